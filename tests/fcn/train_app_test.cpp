// runTraining end to end on the pipe fixture (report, model, heat maps), and the failures that
// must leave the database untouched: no overlap between the query and the database, too few
// references, a model of another architecture to start from; and --heatmaps-only (a saved model
// drawing another database's heat maps).

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "fixture.h"
#include "lookup/database/heat_maps.h"
#include "lookup/database/reference_database.h"
#include "lookup/fcn/train_app.h"
#include "lookup/test/support.h"

using namespace lookup;
using namespace lookup::fcn;
namespace fs = std::filesystem;

namespace {

// Everything in the database folder (name -> content).
std::map<std::string, std::string> snapshot(const fs::path& dir) {
    std::map<std::string, std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (e.is_regular_file())
            out[fs::relative(e.path(), dir).string()] = lookup::test::readText(e.path());
    }
    return out;
}

struct TrainSetup {
    fs::path dir;
    std::string db;
    TrainRequest req;
    TrainOptions options = fixture::smallOptions();
};

TrainSetup makeSetup(const std::string& name) {
    TrainSetup s;
    s.dir = lookup::test::freshDir("lookup_fcn_" + name);
    s.db = (s.dir / "db").string();
    std::vector<double> xs;
    for (double x = -3; x <= 3.01; x += 0.5) xs.push_back(x);
    fixture::writeDatabase(s.db, xs);
    fixture::writeQuery((s.dir / "q.rawlog").string(), fixture::drive(-2.6, 2.6, 0.2, 0.15));
    s.req.db_dir = s.db;
    s.req.train_rawlogs = {(s.dir / "q.rawlog").string()};
    s.req.train_poses = {fixture::posesFile(s.req.train_rawlogs.front())};
    s.req.report_dir = (s.dir / "report").string();
    s.req.progress = false;
    s.options.training.epochs = 4;
    return s;
}

void expectThrowNaming(const TrainSetup& s, const std::string& what1, const std::string& what2) {
    try {
        runTraining(s.req, s.options);
        FAIL() << "training did not fail";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find(what1), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find(what2), std::string::npos) << e.what();
    }
}

}  // namespace

TEST(TrainApp, WritesModelReportAndHeatMaps) {
    TrainSetup s = makeSetup("app");
    const TrainReport r = runTraining(s.req, s.options);
    EXPECT_TRUE(fs::exists(s.db + "/fcn_model.pt"));
    EXPECT_EQ(r.heat_maps.count, 13u);
    const auto db = database::ReferenceDatabase::load(s.db);
    EXPECT_EQ(db.info().heatmaps_dir, r.heat_maps.directory);

    const auto j =
        nlohmann::json::parse(lookup::test::readText(s.dir / "report" / "train_report.json"));
    EXPECT_EQ(j["training"]["epochs"].size(), 4u);
    EXPECT_EQ(j["labels"]["held_out_pairs"].get<std::size_t>(), r.labels.held_out_pairs);
    EXPECT_GT(j["labels"]["inlier_share"].get<double>(), 0.0);
    EXPECT_LT(j["labels"]["inlier_share"].get<double>(), 1.0);
    EXPECT_DOUBLE_EQ(j["best_point_inlier_share"].get<double>(),
                     r.evaluation.best_point_inlier_share);
    EXPECT_TRUE(j.contains("random_point_inlier_share"));
    EXPECT_GT(j["timings_s"]["total"].get<double>(), 0.0);

    // The saved model is the one that drew the heat maps, and can be trained on from.
    const auto model = HeatMapModel::load(s.db + "/fcn_model.pt", &s.options.network);
    (void)model;
    s.req.init_model = s.db + "/fcn_model.pt";
    s.options.training.epochs = 1;
    EXPECT_NO_THROW(runTraining(s.req, s.options));
}

TEST(TrainApp, AQueryWithNoOverlapFailsAndLeavesTheDatabaseUntouched) {
    TrainSetup s = makeSetup("app_nooverlap");
    s.options.training.epochs = 1;
    runTraining(s.req, s.options);  // the database now has heat maps
    const auto before = snapshot(s.db);

    // A query drive 8 m away from every reference.
    fixture::writeQuery((s.dir / "far.rawlog").string(), fixture::drive(-2, 2, 0.2, 8.0));
    s.req.train_rawlogs = {(s.dir / "far.rawlog").string()};
    s.req.train_poses = {fixture::posesFile(s.req.train_rawlogs.front())};
    expectThrowNaming(s, "far.rawlog", "too few usable pairs");
    EXPECT_EQ(snapshot(s.db), before);
}

TEST(TrainApp, TooFewReferencesAndAnotherArchitectureAreRefused) {
    TrainSetup s = makeSetup("app_refs");
    const auto before = snapshot(s.db);
    s.options.labels.min_references = 100;
    expectThrowNaming(s, s.db, "only 13 references");
    EXPECT_EQ(snapshot(s.db), before);

    s.options.labels.min_references = 2;
    TrainOptions other = s.options;
    other.network.base_channels = 4;
    HeatMapModel(other.network).save((s.dir / "other.pt").string());
    s.req.init_model = (s.dir / "other.pt").string();
    expectThrowNaming(s, "other.pt", "another architecture");
    EXPECT_EQ(snapshot(s.db), before);
}

TEST(TrainApp, HeatMapsOnlyDrawsAnotherDatabaseWithASavedModel) {
    TrainSetup s = makeSetup("app_heat_only");
    const fs::path other = s.dir / "other_db";
    fixture::writeDatabase(other.string(), {10.0, 10.5, 11.0, 11.5});
    const HeatMapModel model(s.options.network, 9);
    model.save((s.dir / "model.pt").string());

    const auto w = writeHeatMapsWithModel(other.string(), (s.dir / "model.pt").string());
    EXPECT_EQ(w.count, 4u);
    const auto db = database::ReferenceDatabase::load(other.string());
    EXPECT_EQ(db.info().heatmaps_dir, w.directory);
    for (std::size_t i = 0; i < db.size(); ++i) {
        const cv::Mat stored = database::loadHeatMap(db, i);
        const cv::Mat predicted = model.predict(db.ceilingImage(i));
        ASSERT_EQ(stored.size(), predicted.size());
        EXPECT_LT(cv::norm(stored, predicted, cv::NORM_INF), 1.0 / 65535 + 1e-6);
    }

    // A corrupt model is refused by name and the heat maps just written stay.
    const auto before = snapshot(other);
    std::ofstream((s.dir / "corrupt.pt").string()) << "not a model";
    try {
        writeHeatMapsWithModel(other.string(), (s.dir / "corrupt.pt").string());
        FAIL() << "a corrupt model was accepted";
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("corrupt.pt"), std::string::npos) << e.what();
    }
    EXPECT_EQ(snapshot(other), before);
}

// TrainApp, the lookup-train program as a class.
namespace {

bool initialize(TrainApp& app, std::vector<std::string> args, std::string* err) {
    args.insert(args.begin(), "lookup-train");
    std::vector<const char*> argv;
    for (const auto& a : args) argv.push_back(a.c_str());
    testing::internal::CaptureStderr();
    const bool ok = app.initialize(int(argv.size()), argv.data());
    *err = testing::internal::GetCapturedStderr();
    return ok;
}

std::string writeIni(const fs::path& path, const TrainOptions& options) {
    mrpt::config::CConfigFileMemory ini;
    options.saveToConfigFile(ini, "fcn");
    std::ofstream(path) << ini.getContent();
    return path.string();
}

}  // namespace

TEST(TrainApp, FlagsFillTheRequestAndTheOptionsComeFromTheIni) {
    const auto dir = lookup::test::freshDir("lookup_fcn_app_flags");
    TrainOptions o = fixture::smallOptions();
    o.training.epochs = 3;
    const std::string ini = writeIni(dir / "train.ini", o);
    TrainApp app;
    std::string err;
    ASSERT_TRUE(initialize(app,
                           {"--db", "D", "--train", "a.rawlog,,b.rawlog", "--train-poses",
                            "a.tum,b.tum", "--out-model", "M.pt", "--out", "R", "--init-model",
                            "I.pt", "--no-heatmaps", "--quiet", "--ini", ini},
                           &err))
        << err;
    EXPECT_EQ(app.request().db_dir, "D");
    EXPECT_EQ(app.request().train_rawlogs, (std::vector<std::string>{"a.rawlog", "b.rawlog"}));
    EXPECT_EQ(app.request().train_poses, (std::vector<std::string>{"a.tum", "b.tum"}));
    EXPECT_EQ(app.request().out_model, "M.pt");
    EXPECT_EQ(app.request().report_dir, "R");
    EXPECT_EQ(app.request().init_model, "I.pt");
    EXPECT_FALSE(app.request().write_heat_maps);
    EXPECT_FALSE(app.request().progress);
    EXPECT_EQ(app.options().training.epochs, 3);

    // An empty pose file keeps its place: that rawlog trains on the survey's own poses.
    TrainApp mixed;
    ASSERT_TRUE(initialize(
        mixed,
        {"--db", "D", "--train", "a.rawlog,b.rawlog", "--train-poses", ",b.tum", "--ini", ini},
        &err))
        << err;
    EXPECT_EQ(mixed.request().train_poses, (std::vector<std::string>{"", "b.tum"}));
}

TEST(TrainApp, BadFlagsAndIniTyposAreRefusedNamingThem) {
    const auto dir = lookup::test::freshDir("lookup_fcn_app_typos");
    const std::string ini = writeIni(dir / "train.ini", fixture::smallOptions());
    const std::string text = lookup::test::readText(ini);
    struct Case {
        std::string ini_text;
        std::vector<std::string> args;
        std::string names;
    };
    for (const Case& c : std::vector<Case>{
             {text + "\n[fcn.trainng]\nepochs = 2\n", {"--train", "q"}, ini + " [fcn.trainng]"},
             {text + "\n[fcn.training]\nepochz = 2\n",
              {"--train", "q"},
              ini + " [fcn.training] epochz: unknown key"},
             {text, {}, "--train FILES is required (or --heatmaps-only MODEL)"},
             {text, {"--train", "q", "--figure-ref", "x"}, "--figure-ref"}}) {
        std::ofstream(ini) << c.ini_text;
        std::vector<std::string> args{"--db", "D", "--ini", ini};
        args.insert(args.end(), c.args.begin(), c.args.end());
        TrainApp app;
        std::string err;
        EXPECT_FALSE(initialize(app, args, &err)) << c.names;
        EXPECT_EQ(app.exitCode(), 1) << c.names;
        EXPECT_NE(err.find(c.names), std::string::npos) << err;
        EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    }
}

TEST(TrainApp, RunTrainsThenDrawsTheFigureOfAReference) {
    TrainSetup s = makeSetup("app_run");
    s.options.training.epochs = 1;
    const std::string ini = writeIni(s.dir / "train.ini", s.options);
    TrainApp train;
    const auto r = lookup::test::runApp(
        "lookup-train", train,
        {"--db", s.db, "--train", s.req.train_rawlogs[0], "--train-poses", s.req.train_poses[0],
         "--out", s.req.report_dir, "--ini", ini, "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("model: " + s.db + "/fcn_model.pt\n"), std::string::npos) << r.out;
    EXPECT_TRUE(fs::is_regular_file(s.dir / "report" / "train_report.json"));

    const std::string png = (s.dir / "figure.png").string();
    TrainApp figure;
    const auto f = lookup::test::runApp("lookup-train", figure,
                                        {"--db", s.db, "--figure", png, "--figure-ref", "2"});
    ASSERT_EQ(f.code, 0) << f.err;
    EXPECT_EQ(f.out, png + ": reference 2 of " + s.db + "\n");
    EXPECT_GT(fs::file_size(png), 1000u);
}

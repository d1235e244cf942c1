// runTraining end to end on the pipe fixture (report, model, heat maps), and the failures that
// must leave the database untouched: no overlap between the query and the database, too few
// references, a model of another architecture to start from.

#include <gtest/gtest.h>

#include <fstream>
#include <nlohmann/json.hpp>

#include "fixture.h"
#include "lookup/database/reference_database.h"
#include "lookup/fcn/train_app.h"

using namespace lookup;
using namespace lookup::fcn;
namespace fs = std::filesystem;

namespace {

std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
}

// Everything in the database folder (name -> content).
std::map<std::string, std::string> snapshot(const fs::path& dir) {
    std::map<std::string, std::string> out;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (e.is_regular_file()) out[fs::relative(e.path(), dir).string()] = slurp(e.path());
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
    s.dir = fixture::freshDir(name);
    s.db = (s.dir / "db").string();
    std::vector<double> xs;
    for (double x = -3; x <= 3.01; x += 0.5) xs.push_back(x);
    fixture::writeDatabase(s.db, xs);
    fixture::writeQuery((s.dir / "q.rawlog").string(), fixture::drive(-2.6, 2.6, 0.2, 0.15));
    s.req.db_dir = s.db;
    s.req.train_rawlogs = {(s.dir / "q.rawlog").string()};
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

    const auto j = nlohmann::json::parse(slurp(s.dir / "report" / "train_report.json"));
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

#include <mrpt/3rdparty/tclap/CmdLine.h>

#include <cstdio>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"
#include "lookup/common/share_dirs.h"
#include "lookup/database/heat_maps.h"
#include "lookup/database/reference_database.h"
#include "lookup/fcn/heat_maps.h"
#include "lookup/fcn/train_app.h"
#include "lookup/refine/sampler.h"

namespace lookup::fcn {
namespace {

// `keep_empty`: an empty item keeps its place (in --train-poses, "the survey's poses" for the
// rawlog at that place, so survey traverses and other drives can train together).
std::vector<std::string> splitList(const std::string& s, bool keep_empty = false) {
    std::vector<std::string> out;
    std::stringstream in(s);
    for (std::string item; std::getline(in, item, ',');) {
        if (keep_empty || !item.empty()) out.push_back(item);
    }
    return out;
}

// --ini, else share/lookup/train.ini (beside the binary, source tree, install prefix), else
// built-in defaults.
std::string defaultIni() {
    const std::string f = common::findShareFile("train.ini");
    return std::filesystem::is_regular_file(f) ? f : "";
}

void loadOptions(const std::string& ini_file, TrainOptions& options) {
    if (!ini_file.empty()) {
        if (!std::filesystem::is_regular_file(ini_file)) {
            throw common::ConfigError(ini_file + ": no such file");
        }
        const auto cfg = common::loadIniFile(ini_file);
        common::rejectUnknownSections(*cfg, TrainOptions::sectionNames("fcn"));
        common::loadAndCheck(options, *cfg, "fcn");
    }
    options.check();
}

}  // namespace

bool TrainApp::initialize(int argc, const char* const* argv) {
    using TCLAP::SwitchArg;
    using TCLAP::ValueArg;
    TCLAP::CmdLine cmd(std::string("lookup-train: FCN sample-point selector (LibTorch) and "
                                   "heat maps. ") +
                           common::kExitCodesHelp,
                       ' ', "0.1");
    ValueArg<std::string> db("", "db", "reference database folder", true, "", "DB", cmd);
    ValueArg<std::string> train("", "train",
                                "training rawlogs, comma separated; the last held_out_share "
                                "of each is held out for evaluation (required unless "
                                "--heatmaps-only)",
                                false, "", "FILES", cmd);
    ValueArg<std::string> train_poses(
        "", "train-poses",
        "vehicle poses of the training rawlogs (TUM or MRPT pose files, comma separated, one "
        "per rawlog, e.g. lookup-localize runs' poses.tum; an empty item, as in ',,run/poses.tum', "
        "takes the survey's); default: the survey's poses of the database's traverse recorded "
        "during each rawlog",
        false, "", "FILES", cmd);
    ValueArg<std::string> heat_only(
        "", "heatmaps-only",
        "no training: write the heat maps of DB's references with this trained model "
        "(e.g. one trained on another survey of the same mine)",
        false, "", "MODEL.pt", cmd);
    ValueArg<std::string> ini("", "ini",
                              "options [fcn.network] [fcn.labels] [fcn.training] "
                              "(default: share/lookup/train.ini)",
                              false, "", "FILE", cmd);
    ValueArg<std::string> out_model("", "out-model", "model file (default DB/fcn_model.pt)", false,
                                    "", "FILE", cmd);
    ValueArg<std::string> out("", "out",
                              "folder for train_report.json and train_curve.png "
                              "(default DB)",
                              false, "", "DIR", cmd);
    ValueArg<std::string> init("", "init-model", "start from this model", false, "", "FILE", cmd);
    SwitchArg no_heat("", "no-heatmaps", "do not write heat maps into the database", cmd);
    SwitchArg quiet("", "quiet", "no progress bars", cmd);
    SwitchArg verbose("v", "verbose", "full error texts (MRPT call stacks)", cmd);
    ValueArg<std::string> figure("", "figure",
                                 "only draw reference --figure-ref beside its stored "
                                 "heat map and the 12 points the localiser samples "
                                 "into this PNG (no training)",
                                 false, "", "FILE.png", cmd);
    ValueArg<int> figure_ref("", "figure-ref", "reference index for --figure", false, -1, "N", cmd);
    if (!parseCommandLine(cmd, argc, argv)) return false;

    request_.db_dir = db.getValue();
    request_.train_rawlogs = splitList(train.getValue());
    request_.train_poses = splitList(train_poses.getValue(), true);
    request_.out_model = out_model.getValue();
    request_.report_dir = out.getValue();
    request_.init_model = init.getValue();
    request_.write_heat_maps = !no_heat.getValue();
    request_.progress = !quiet.getValue();
    heat_maps_model_ = heat_only.getValue();
    figure_png_ = figure.getValue();
    figure_ref_ = figure_ref.getValue();
    if (!figure_png_.empty()) return true;  // draws what is stored: no options
    try {
        loadOptions(ini.getValue().empty() ? defaultIni() : ini.getValue(), options_);
        if (heat_maps_model_.empty() && train.getValue().empty()) {
            throw common::ConfigError("--train FILES is required (or --heatmaps-only MODEL)");
        }
    } catch (const std::exception& e) {
        return refuse("lookup-train", e, verbose.getValue());
    }
    return true;
}

// The reference's stored heat map (as the localiser loads it) and the points it would sample
// (refiner.ini defaults: 12 points, rho 0.5, l_n 10 px, 20 px margin).
int TrainApp::drawFigure() const {
    const auto db = database::ReferenceDatabase::load(request_.db_dir);
    if (db.size() == 0) throw std::runtime_error(request_.db_dir + ": no references");
    const std::size_t i = figure_ref_ < 0 ? db.size() / 2 : std::size_t(figure_ref_);
    if (i >= db.size()) {
        throw std::runtime_error(request_.db_dir + ": no reference " + std::to_string(i));
    }
    const cv::Mat heat = database::loadHeatMap(db, i);
    if (heat.empty()) {
        throw std::runtime_error(request_.db_dir + "/db.ini: no heat maps (train first)");
    }
    const refine::SamplerOptions s;
    const auto points = refine::heatMapPoints(heat, s.heat_map_points, s.damping_ratio,
                                              s.damping_side_px, s.heatMapMargin());
    if (!cv::imwrite(figure_png_, heatMapFigure(db.ceilingImage(i), heat, points))) {
        throw common::WriteError(figure_png_, "cannot write the figure");
    }
    std::printf("%s: reference %zu of %s\n", figure_png_.c_str(), i, request_.db_dir.c_str());
    return common::kExitOk;
}

int TrainApp::writeHeatMapsOnly() const {
    const auto w = writeHeatMapsWithModel(request_.db_dir, heat_maps_model_);
    std::printf("heat maps: %s/%s (%zu references, %.1f s) from %s\n", request_.db_dir.c_str(),
                w.directory.c_str(), w.count, w.seconds, heat_maps_model_.c_str());
    return common::kExitOk;
}

int TrainApp::run() {
    if (!figure_png_.empty()) return exit_code_ = drawFigure();
    if (!heat_maps_model_.empty()) return exit_code_ = writeHeatMapsOnly();
    const auto r = runTraining(request_, options_);
    std::printf(
        "labels: %zu pairs (%zu training, %zu held out), inlier share %.3f, %.1f s\n"
        "training: %zu images, %d epochs, val loss %.4f -> %.4f, %.1f s\n"
        "held out: best_point_inlier_share %.3f, random_point_inlier_share %.3f "
        "(%zu pairs)\n"
        "model: %s\nheat maps: %s (%zu)\nreport: %s\n",
        r.labels.usable_pairs, r.labels.training_pairs, r.labels.held_out_pairs,
        r.labels.inlierShare(), r.labels.seconds, r.training_samples, int(r.training.epochs.size()),
        r.training.initial_val_loss,
        r.training.epochs.empty() ? 0.0 : r.training.epochs.back().val_loss, r.training.seconds,
        r.evaluation.best_point_inlier_share, r.evaluation.random_point_inlier_share,
        r.evaluation.pairs, r.model_file.c_str(), r.heat_maps.directory.c_str(), r.heat_maps.count,
        r.report_file.c_str());
    for (const auto& w : r.warnings) std::fprintf(stderr, "warning: %s\n", w.c_str());
    if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
        throw common::WriteError("stdout", "cannot write the summary");
    }
    return exit_code_ = common::kExitOk;
}

}  // namespace lookup::fcn

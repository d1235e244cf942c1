#include "lookup/fcn/train_app.h"

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/system/progress.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iostream>
#include <nlohmann/json.hpp>

#include "lookup/common/errors.h"
#include "lookup/database/reference_database.h"

namespace fs = std::filesystem;

namespace lookup::fcn {
namespace {

void bar(const std::string& what, std::size_t done, std::size_t total, const std::string& tail) {
    const double r = total ? double(done) / total : 1.0;
    std::fprintf(stderr, "\r%-9s %s %3d%% %zu/%zu %s   ", what.c_str(),
                 mrpt::system::progress(r, 30).c_str(), int(r * 100), done, total, tail.c_str());
    if (done >= total) std::fprintf(stderr, "\n");
}

// Train and validation loss per epoch, drawn by gnuplot (as libs/eval/src/report.cpp does).
bool plotCurve(const TrainResult& r, const std::string& dir, std::string& png,
               std::string& warning) {
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) {
        warning = "gnuplot not installed: train_curve.png not drawn";
        return false;
    }
    const std::string dat = dir + "/train_curve.dat", gp = dir + "/train_curve.gp";
    png = dir + "/train_curve.png";
    {
        std::ofstream d(dat);
        d << "# epoch train_loss val_loss\n0 NaN " << r.initial_val_loss << "\n";
        for (const auto& e : r.epochs)
            d << e.epoch << " " << e.train_loss << " " << e.val_loss << "\n";
    }
    for (const char* terminal : {"pngcairo", "png"}) {
        {
            std::ofstream g(gp);
            g << "set terminal " << terminal << " size 800,480 noenhanced\n"
              << "set output '" << png << "'\n"
              << "set xlabel 'epoch'\nset ylabel 'class-balanced BCE'\nset grid\n"
              << "set title 'FCN sample-point selector: training and validation loss'\n"
              << "plot '" << dat << "' using 1:2 with linespoints title 'train', '" << dat
              << "' using 1:3 with linespoints title 'validation (held-out frames)'\n";
        }
        if (std::system(("gnuplot '" + gp + "' 2>>'" + dir + "/gnuplot.log'").c_str()) == 0) {
            return true;
        }
    }
    warning = "gnuplot failed, see " + dir + "/gnuplot.log";
    png.clear();
    return false;
}

using ImageOf = std::function<cv::Mat(std::size_t)>;

double secondsSince(std::chrono::steady_clock::time_point start) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

std::string joined(const std::vector<std::string>& rawlogs) {
    std::string list;
    for (const auto& r : rawlogs) list += (list.empty() ? "" : ",") + r;
    return list;
}

// The database to train on, refused when it has fewer references than labelling needs.
database::ReferenceDatabase loadDatabase(const std::string& db_dir, const LabelOptions& o) {
    auto db = database::ReferenceDatabase::load(db_dir);
    if (db.size() < std::size_t(o.min_references)) {
        throw std::runtime_error(
            db_dir + ": only " + std::to_string(db.size()) +
            " references (fcn.labels min_references = " + std::to_string(o.min_references) + ")");
    }
    return db;
}

// Refuses labels too few to train and validate on, saying why pairs were lost.
void checkEnoughPairs(const LabelStats& st, const LabelOptions& o, const std::string& rawlog_list,
                      const std::string& db_dir) {
    if (st.training_pairs >= std::size_t(o.min_training_pairs) &&
        st.held_out_pairs >= std::size_t(o.min_held_out_pairs)) {
        return;
    }
    throw std::runtime_error(
        rawlog_list + ": too few usable pairs with " + db_dir + " (training " +
        std::to_string(st.training_pairs) + ", held out " + std::to_string(st.held_out_pairs) +
        "; need " + std::to_string(o.min_training_pairs) + " and " +
        std::to_string(o.min_held_out_pairs) + "): " + std::to_string(st.frames_without_reference) +
        " of " + std::to_string(st.query_frames) + " frames have no reference within " +
        std::to_string(o.max_reference_distance_m) + " m, " +
        std::to_string(st.pairs - st.usable_pairs) + " of " + std::to_string(st.pairs) +
        " pairs did not match (no overlap?)");
}

// A new model (or --init's) trained on the labels; the sample counts, parameter count and
// training curve go into `report`.
HeatMapModel trainModel(const TrainRequest& req, const TrainOptions& options,
                        const LabelSet& labels, const ImageOf& image_of,
                        const std::string& rawlog_list, TrainReport& report) {
    const auto train_samples = samplesFromPairs(labels.pairs, false, image_of);
    const auto val_samples = samplesFromPairs(labels.pairs, true, image_of);
    report.training_samples = train_samples.size();
    report.validation_samples = val_samples.size();
    HeatMapModel model = req.init_model.empty()
                             ? HeatMapModel(options.network, options.training.seed)
                             : HeatMapModel::load(req.init_model, &options.network);
    report.parameters = model.parameterCount();
    try {
        report.training = train(model, train_samples, val_samples, options.training,
                                [&](int epoch, int step, int steps, double loss) {
                                    if (!req.progress) return;
                                    char tail[64];
                                    std::snprintf(tail, sizeof tail, "loss %.4f", loss);
                                    bar("epoch " + std::to_string(epoch), step, steps, tail);
                                });
    } catch (const std::invalid_argument& e) {
        throw std::runtime_error(rawlog_list + ": cannot train: " + e.what());
    }
    return model;
}

}  // namespace

TrainReport runTraining(const TrainRequest& req, const TrainOptions& options) {
    const auto t0 = std::chrono::steady_clock::now();
    options.check();
    if (req.train_rawlogs.empty()) throw std::runtime_error("no training rawlog given (--train)");
    TrainReport report;
    const auto db = loadDatabase(req.db_dir, options.labels);
    const ImageOf image_of = [&db](std::size_t i) { return db.ceilingImage(i).clone(); };

    // 1. Labels (paper Sec. III-B), split by time into training and held-out frames.
    const LabelSet labels = generateLabels(db, req.train_rawlogs, req.train_poses, options.labels,
                                           [&](std::size_t d, std::size_t n) {
                                               if (req.progress) bar("labels", d, n, "");
                                           });
    report.labels = labels.stats;
    const std::string rawlog_list = joined(req.train_rawlogs);
    checkEnoughPairs(labels.stats, options.labels, rawlog_list, req.db_dir);

    // 2. Training.
    HeatMapModel model = trainModel(req, options, labels, image_of, rawlog_list, report);

    // 3. The paper's metric on the held-out frames.
    const auto e0 = std::chrono::steady_clock::now();
    report.evaluation = evaluatePoints(model, labels.pairs, image_of);
    report.evaluation_seconds = secondsSince(e0);

    // 4. Model, then heat maps (the database changes only once they are all written).
    report.model_file = req.out_model.empty() ? req.db_dir + "/fcn_model.pt" : req.out_model;
    model.save(report.model_file);
    if (req.write_heat_maps) {
        report.heat_maps = writeHeatMaps(db, model, [&](std::size_t d, std::size_t n) {
            if (req.progress) bar("heat maps", d, n, "");
        });
    }

    // 5. Report and validation curve.
    const std::string dir = req.report_dir.empty() ? req.db_dir : req.report_dir;
    fs::create_directories(dir);
    std::string warning;
    if (!plotCurve(report.training, dir, report.curve_file, warning)) {
        report.warnings.push_back(warning);
    }
    report.report_file = dir + "/train_report.json";
    report.total_seconds = secondsSince(t0);
    writeTrainReport(report, req, options, report.report_file);
    return report;
}

void writeTrainReport(const TrainReport& r, const TrainRequest& req, const TrainOptions& options,
                      const std::string& path) {
    using nlohmann::json;
    mrpt::config::CConfigFileMemory ini;
    options.saveToConfigFile(ini, "fcn");
    json epochs = json::array();
    for (const auto& e : r.training.epochs) {
        epochs.push_back({{"epoch", e.epoch},
                          {"train_loss", e.train_loss},
                          {"val_loss", e.val_loss},
                          {"seconds", e.seconds}});
    }
    const auto& l = r.labels;
    json j = {
        {"db", req.db_dir},
        {"train_rawlogs", req.train_rawlogs},
        {"train_poses", req.train_poses},
        {"split",
         "by time: the last held_out_share of each training rawlog is held out "
         "(validation loss and evaluation); the rest is trained on"},
        {"model_file", r.model_file},
        {"parameters", r.parameters},
        {"best_point_inlier_share", r.evaluation.best_point_inlier_share},
        {"random_point_inlier_share", r.evaluation.random_point_inlier_share},
        {"evaluation",
         {{"held_out_pairs", r.evaluation.pairs},
          {"best_point_inlier_share", r.evaluation.best_point_inlier_share},
          {"random_point_inlier_share", r.evaluation.random_point_inlier_share},
          {"top12_inlier_share", r.evaluation.top12_inlier_share},
          {"heat_inlier_mean", r.evaluation.heat_inlier_mean},
          {"heat_outlier_mean", r.evaluation.heat_outlier_mean}}},
        {"labels",
         {{"query_frames", l.query_frames},
          {"frames_without_reference", l.frames_without_reference},
          {"pairs", l.pairs},
          {"usable_pairs", l.usable_pairs},
          {"training_pairs", l.training_pairs},
          {"held_out_pairs", l.held_out_pairs},
          {"points", l.points},
          {"inlier_points", l.inlier_points},
          {"target_points", l.target_points},
          {"inlier_share", l.inlierShare()}}},
        {"training",
         {{"samples", r.training_samples},
          {"validation_samples", r.validation_samples},
          {"steps", r.training.steps},
          {"initial_val_loss", r.training.initial_val_loss},
          {"positive_weight", r.training.positive_weight},
          {"negative_weight", r.training.negative_weight},
          {"epochs", epochs}}},
        {"heat_maps", {{"directory", r.heat_maps.directory}, {"count", r.heat_maps.count}}},
        {"timings_s",
         {{"labels", l.seconds},
          {"training", r.training.seconds},
          {"evaluation", r.evaluation_seconds},
          {"heat_maps", r.heat_maps.seconds},
          {"total", r.total_seconds}}},
        {"curve_file", r.curve_file},
        {"warnings", r.warnings},
        {"options_ini", ini.getContent()},
    };
    std::ofstream out(path);
    out << j.dump(2) << "\n";
    out.close();
    if (!out) throw common::WriteError(path, "write failed");
}

HeatMapsWritten writeHeatMapsWithModel(const std::string& db_dir, const std::string& model_file) {
    const auto model = HeatMapModel::load(model_file);  // before anything in the database changes
    const auto db = database::ReferenceDatabase::load(db_dir);
    return writeHeatMaps(db, model);
}

}  // namespace lookup::fcn

#pragma once
// lookup-train as a library call (the app is a thin main): labels -> training -> held-out
// evaluation -> model file -> heat maps in the database -> train_report.json and
// train_curve.png.

#include <string>
#include <vector>

#include "lookup/fcn/heat_maps.h"
#include "lookup/fcn/labels.h"
#include "lookup/fcn/options.h"
#include "lookup/fcn/trainer.h"

namespace lookup::fcn {

struct TrainRequest {
    std::string db_dir;                      ///< reference database folder (lookup-survey)
    std::vector<std::string> train_rawlogs;  ///< training query rawlogs (with .GT.txt beside)
    std::string out_model;                   ///< "" = <db_dir>/fcn_model.pt
    std::string report_dir;                  ///< "" = db_dir: train_report.json, train_curve.png
    std::string init_model;                  ///< optional model to start from (same architecture)
    bool write_heat_maps = true;
    bool progress = true;  ///< progress bars on stderr
};

struct TrainReport {
    LabelStats labels;
    std::size_t training_samples = 0;  ///< reference images trained on
    std::size_t validation_samples = 0;
    std::size_t parameters = 0;
    TrainResult training;
    PointEvaluation evaluation;
    HeatMapsWritten heat_maps;
    std::string model_file;
    std::string report_file;
    std::string curve_file;  ///< "" when gnuplot could not draw it
    std::vector<std::string> warnings;
    double evaluation_seconds = 0;
    double total_seconds = 0;
};

/// Runs the whole training. Throws std::runtime_error naming the file and the reason for bad
/// input: a database with fewer than min_references references, training rawlogs with too few
/// usable pairs (no overlap with the database), a bad --init model. Nothing in the database is
/// changed unless the heat maps are written completely.
TrainReport runTraining(const TrainRequest& request, const TrainOptions& options);

/// lookup-train --heatmaps-only: no training, the heat maps of the database in `db_dir` drawn by
/// the model in `model_file` (e.g. one trained on another survey of the same mine). Throws
/// std::runtime_error naming the file for a missing, corrupt or foreign model; the database's
/// existing heat maps stay as they were unless the new ones are written completely.
HeatMapsWritten writeHeatMapsWithModel(const std::string& db_dir, const std::string& model_file);

/// Writes `report` (and the options) as JSON to `path`.
void writeTrainReport(const TrainReport& report, const TrainRequest& request,
                      const TrainOptions& options, const std::string& path);

}  // namespace lookup::fcn

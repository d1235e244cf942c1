#pragma once
// lookup-train as a library call and its App (the program is a thin main): labels -> training ->
// held-out evaluation -> model file -> heat maps in the database -> train_report.json and
// train_curve.png.

#include <string>
#include <vector>

#include "lookup/common/app.h"
#include "lookup/fcn/heat_maps.h"
#include "lookup/fcn/labels.h"
#include "lookup/fcn/options.h"
#include "lookup/fcn/trainer.h"

namespace lookup::fcn {

struct TrainRequest {
    std::string db_dir;                      ///< reference database folder (lookup-survey)
    std::vector<std::string> train_rawlogs;  ///< training rawlogs
    /// One pose file per training rawlog; empty = the survey's poses of the database's traverse
    /// recorded during each (generateLabels).
    std::vector<std::string> train_poses;
    std::string out_model;   ///< "" = <db_dir>/fcn_model.pt
    std::string report_dir;  ///< "" = db_dir: train_report.json, train_curve.png
    std::string init_model;  ///< optional model to start from (same architecture)
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

/// lookup-train, the program:
///   lookup-train --db DB --train QUERY.rawlog[,...] [--ini FILE] [--out-model FILE]
///                [--out DIR] [--init-model FILE] [--no-heatmaps] [--quiet]
///   lookup-train --db DB --heatmaps-only MODEL.pt
///   lookup-train --db DB --figure FILE.png [--figure-ref N]
/// Options from --ini, else share/lookup/train.ini, else the built-in defaults. Errors of the
/// run (the database, the rawlogs, the model) escape run() for common::runApp to report.
class TrainApp : public common::App {
  public:
    bool initialize(int argc, const char* const* argv) override;
    int run() override;

    const TrainRequest& request() const { return request_; }
    const TrainOptions& options() const { return options_; }

  private:
    int drawFigure() const;
    int writeHeatMapsOnly() const;

    TrainRequest request_;
    TrainOptions options_;
    std::string heat_maps_model_;  ///< --heatmaps-only
    std::string figure_png_;       ///< --figure
    int figure_ref_ = -1;          ///< --figure-ref; -1: the middle reference
};

}  // namespace lookup::fcn

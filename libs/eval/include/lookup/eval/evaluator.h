#pragma once
// Errors of localisation runs against ground truth, per traverse and method, with the paper's
// exclusion of frames whose coarse error exceeds 10 m (Sec. IV).

#include <mrpt/config/CLoadableOptions.h>

#include <string>
#include <vector>

#include "lookup/common/pose_files.h"
#include "lookup/eval/run_io.h"

namespace lookup::eval {

struct EvalOptions : public mrpt::config::CLoadableOptions {
    double coarse_exclusion_m = 10.0;  ///< frames whose coarse error exceeds this are excluded
    double max_gt_gap_s = 0.5;         ///< no ground truth is interpolated across longer gaps
    /// A pose counts as a confident wrong fix when its error exceeds this AND it lies outside
    /// its reported 99.7 % ellipse.
    double confident_wrong_min_error_m = 0.5;

    void loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                            const std::string& section) override;
    void saveToConfigFile(mrpt::config::CConfigFileBase& target,
                          const std::string& section) const override;
    void check() const;
};

/// A ground-truth trajectory; `traverse` is the file name up to the first '.'.
struct GroundTruth {
    std::string traverse;
    common::PoseTrack track;
};
GroundTruth loadGroundTruth(const std::string& path);

struct ErrorStats {
    size_t count = 0;
    double mean_m = 0, median_m = 0, p95_m = 0, max_m = 0;
};
/// Statistics of position errors (empty input gives count 0 and zeros).
ErrorStats summarize(std::vector<double> errors_m);

/// One (traverse, method) row of the report.
struct MethodResult {
    std::string traverse;
    std::string method;  ///< "coarse" for the coarse stage alone
    std::string run_directory;
    size_t frames = 0;            ///< frames in the run that fall inside the ground truth
    size_t excluded = 0;          ///< of those, excluded by the coarse-error rule
    size_t without_pose = 0;      ///< lost or dropped (no pose emitted)
    ErrorStats error;             ///< over evaluated frames that emitted a pose
    double acceptance_share = 0;  ///< refined / evaluated frames
    double inside_95_share = 0;   ///< refined frames whose error lies in the reported 95 % ellipse
    double yaw_error_mean_deg = 0;
    double frames_per_s = 0;
    double match_ms_per_frame = 0;  ///< the SAD matcher's time per frame (0: not recorded)
    int frames_dropped = 0;
    /// First refined frame: its index in the run (-1: none), seconds and metres driven (along
    /// the ground truth) since the run's first frame with ground truth.
    long first_fix_frame = -1;
    double first_fix_s = 0, first_fix_distance_m = 0;
    /// Refined share of the evaluated frames from the first fix on (the tracking share).
    double refined_after_first_fix_share = 0;
    /// Poses more than confident_wrong_min_error_m off and outside their reported 99.7 %
    /// ellipse, over every frame with ground truth (coarse-excluded ones too).
    size_t confident_wrong = 0;
    double frame_ms_p99 = 0;  ///< 99th percentile of frames.csv `ms` (dropped frames left out)
    std::string flagged;      ///< Run::flagged: why this row scores an incomplete run ("" if not)
};

struct Report {
    std::vector<MethodResult> rows;
    EvalOptions options;
    std::vector<std::string> warnings;  ///< e.g. a run that matches no ground truth
};

/// Scores one run against its traverse's truth; `coarse` (optional) receives the coarse
/// stage's row for the same frames (frames = 0 when the run carries no coarse poses).
MethodResult scoreRun(const Run& run, const GroundTruth& truth, const EvalOptions& options,
                      MethodResult* coarse = nullptr);

/// Matches each run to the ground truth covering its time stamps, interpolates the truth at
/// every frame and computes the statistics. Adds one "coarse" row per traverse (from the first
/// run of that traverse that carries coarse poses).
Report evaluate(const std::vector<GroundTruth>& truths, const std::vector<Run>& runs,
                const EvalOptions& options);

/// report.md (tables), report.json, and errors.png (mean error per traverse and method, drawn
/// with gnuplot; skipped with a warning in the report if gnuplot is not installed). Each file
/// is written atomically; a failed write throws common::WriteError naming it.
void writeReport(const Report& report, const std::string& out_dir);

}  // namespace lookup::eval

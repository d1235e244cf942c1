#pragma once
// Errors of localisation runs against ground truth, per traverse and method, with the paper's
// exclusion of frames whose coarse error exceeds 10 m (Sec. IV).

#include <mrpt/config/CLoadableOptions.h>

#include <array>
#include <string>
#include <utility>
#include <vector>

#include "lookup/common/options_table.h"
#include "lookup/common/pose_files.h"
#include "lookup/eval/run_io.h"

namespace lookup::eval {

struct EvalOptions : public common::TableOptions<EvalOptions> {
    double coarse_exclusion_m = 10.0;  ///< frames whose coarse error exceeds this are excluded
    double max_gt_gap_s = 0.5;         ///< no ground truth is interpolated across longer gaps
    /// A pose counts as a confident wrong fix when its error exceeds this AND it lies outside
    /// its reported 99.7 % ellipse.
    double confident_wrong_min_error_m = 0.5;

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
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
    size_t frames = 0;        ///< frames in the run that fall inside the ground truth
    size_t excluded = 0;      ///< of those, excluded by the coarse-error rule
    size_t without_pose = 0;  ///< lost or dropped (no pose emitted)
    ErrorStats error;         ///< over evaluated frames that emitted a pose
    /// |z - the truth's z| over the evaluated frames whose pose has a height (frames.csv `z`,
    /// references with 3-D poses); count 0 without heights.
    ErrorStats height;
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

/// One frame of a run beside its truth (what the per-traverse pictures draw).
struct FrameTrace {
    double distance_m = 0;            ///< driven along the truth since the run's first frame
    double truth_x = 0, truth_y = 0;  ///< true vehicle position [m]
    std::string status;               ///< refined | fallback | lost | dropped
    bool has_pose = false;
    double x = 0, y = 0;         ///< emitted position (has_pose) [m]
    double error_m = 0;          ///< its position error (has_pose) [m]
    double coarse_error_m = -1;  ///< the coarse pose's error, -1 = none [m]
    bool excluded = false;       ///< by the coarse-error rule
};

/// The frames with ground truth of one scored run.
struct RunTrace {
    std::string traverse, method;
    std::vector<FrameTrace> frames;
};

struct Report {
    std::vector<MethodResult> rows;
    EvalOptions options;
    std::vector<std::string> warnings;  ///< e.g. a run that matches no ground truth
    std::vector<RunTrace> traces;       ///< one per scored run, in the runs' order
    /// Wall cells of the map (plan positions [m]) drawn under the trajectories; empty = none.
    std::vector<std::array<double, 2>> map_walls;
};

/// Method names the evaluator knows (lookup-localize's defaults, the demo's and the FCN
/// oracles' names, and "coarse"), each with its fixed chart colour "#rrggbb".
const std::vector<std::pair<std::string, std::string>>& methodColourTable();
/// The colour of `method` in every chart: its table entry, else a spare colour chosen by its
/// rank among the unknown names of `methods` (distinct for up to 8 unknown names).
std::string methodColour(const std::string& method, const std::vector<std::string>& methods);

/// Wall cells (occupied cells beside free space) of an MRPT occupancy grid (.gridmap.gz, as
/// lookup-sim and lookup-survey write it). Throws common::ConfigError naming the file.
std::vector<std::array<double, 2>> loadMapWalls(const std::string& gridmap_path);

/// Scores one run against its traverse's truth; `coarse` (optional) receives the coarse
/// stage's row for the same frames (frames = 0 when the run carries no coarse poses).
MethodResult scoreRun(const Run& run, const GroundTruth& truth, const EvalOptions& options,
                      MethodResult* coarse = nullptr, RunTrace* trace = nullptr);

/// Matches each run to the ground truth covering its time stamps, interpolates the truth at
/// every frame and computes the statistics. Adds one "coarse" row per traverse (from the first
/// run of that traverse that carries coarse poses).
Report evaluate(const std::vector<GroundTruth>& truths, const std::vector<Run>& runs,
                const EvalOptions& options);

/// report.md (tables), report.json, and with gnuplot (skipped with a warning in the report if
/// it is not installed): errors.png (mean error per traverse and method) and, per run and
/// traverse, trajectory_<traverse>_<method>.png (truth line, estimates coloured by error,
/// fallback and lost frames marked, over the map walls when given) and
/// error_along_<traverse>.png (error against the distance driven, one line per method);
/// every method in its methodColour(). Each file is written atomically; a failed write throws
/// common::WriteError naming it.
void writeReport(const Report& report, const std::string& out_dir);

}  // namespace lookup::eval

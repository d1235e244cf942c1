#pragma once
// Reading the per-frame output of a localisation run (docs/run-format.md).

#include <stdexcept>
#include <string>
#include <vector>

namespace lookup::eval {

/// A run folder whose files cannot be read: the message names the file, line and reason.
class RunError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// One row of a run's frames.csv.
struct FrameRow {
    double time_s = 0;
    std::string status;  ///< refined | fallback | lost | dropped
    std::string reason;
    bool has_pose = false;
    double x = 0, y = 0, yaw = 0;                           ///< emitted vehicle pose (m, m, rad)
    double cov_xx = 0, cov_xy = 0, cov_yy = 0, cov_tt = 0;  ///< its covariance (m², rad²)
    bool has_coarse = false;
    double coarse_x = 0, coarse_y = 0, coarse_yaw = 0;
    double inlier_share = 0;
    int references = 0;
    double ms = 0;
    /// The floor's height under the pose (m, column `z`), where the database's references carry
    /// heights; runs written before the column have none.
    bool has_z = false;
    double z = 0;
};

/// A run folder: its method name (from run.ini), frames and throughput (from timing.json).
struct Run {
    std::string directory;
    std::string method;
    std::vector<FrameRow> frames;
    double frames_per_s = 0;  ///< 0 when timing.json is absent
    /// timing.json refine_ms_per_frame.match: the point matcher's time per frame, the cost
    /// that the sample points decide (0 when absent)
    double match_ms_per_frame = 0;
    int frames_dropped = 0;
    bool has_timing = false;  ///< timing.json exists: lookup-localize finished the run
    long timing_frames = -1;  ///< timing.json "frames" (-1: absent)
    /// Rows whose pose or coarse pose held a non-finite number (loaded without that pose).
    std::size_t non_finite_rows = 0;
    /// Why the run must not be scored as it is (runProblem), when scored anyway: the report's
    /// `flagged` column. Empty: a complete run.
    std::string flagged;
};

/// Loads RUN/frames.csv (+ run.ini and timing.json when present). Throws RunError naming
/// the file and line for a missing file, a missing column or a malformed value. A pose with a
/// non-finite number is dropped (the frame counts as without pose) and counted.
Run loadRun(const std::string& directory);

/// Why `run` is not a complete, finite run, or "" when it is: no timing.json (aborted, killed,
/// still running, or a `.partial` folder), a frame count that differs from timing.json's, no
/// frames at all, or rows with non-finite values.
std::string runProblem(const Run& run);

/// The header line of frames.csv (docs/run-format.md), without a newline.
std::string framesCsvHeader();
/// One frames.csv row, without a newline (commas in the reason become ';').
std::string formatFramesCsvRow(const FrameRow& row);

/// Writes frames.csv with the header of docs/run-format.md.
void writeFramesCsv(const std::string& path, const std::vector<FrameRow>& frames);

}  // namespace lookup::eval

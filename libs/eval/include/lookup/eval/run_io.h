#pragma once
// Reading the per-frame output of a localisation run (docs/run-format.md).

#include <string>
#include <vector>

namespace lookup::eval {

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
};

/// Loads RUN/frames.csv (+ run.ini and timing.json when present). Throws ConfigError naming
/// the file and line for a missing file, a missing column or a malformed value.
Run loadRun(const std::string& directory);

/// The header line of frames.csv (docs/run-format.md), without a newline.
std::string framesCsvHeader();
/// One frames.csv row, without a newline (commas in the reason become ';').
std::string formatFramesCsvRow(const FrameRow& row);

/// Writes frames.csv with the header of docs/run-format.md.
void writeFramesCsv(const std::string& path, const std::vector<FrameRow>& frames);

}  // namespace lookup::eval

#pragma once
// The `lookup-coarse` program as a class (thin main, testable logic): runs the online coarse
// localiser over a query rawlog against a reference rawlog (or saved descriptors) and writes
// one CSV row per query image. Works on any two rawlogs with camera images and no poses;
// poses, when given, add odometry-narrowed search and an error evaluation.

#include <iosfwd>
#include <string>
#include <vector>

#include "lookup/common/app.h"

namespace lookup::coarse {

/// Figures of one run (what the program prints at the end).
struct CoarseRunSummary {
    std::size_t frames = 0;
    std::size_t usable = 0;           ///< tracking, odometry or global
    std::size_t odometry = 0;         ///< held by odometry (window match not confident)
    std::size_t lost = 0;             ///< lost or invalid
    std::size_t unconfirmed = 0;      ///< global match waiting for its confirmation
    std::size_t not_enough = 0;       ///< not_enough_frames
    std::size_t global_searches = 0;  ///< frames with status global
    std::size_t references = 0;
    double mean_frame_ms = 0;  ///< descriptor + search, per query frame [ms]
    double median_frame_ms = 0;
    double mean_search_ms = 0;  ///< sequence search only [ms]
    double median_search_ms = 0;
    /// Search time split by what the frame needed [ms]: a window around the track (tracking,
    /// odometry; includes their periodic audits) or a search over the whole reference (every
    /// other searched frame: start-up, lost, unconfirmed).
    std::size_t tracking_frames = 0, global_frames = 0;
    double mean_tracking_search_ms = 0, mean_global_search_ms = 0;
    bool indexed = false;  ///< global searches went through a DescriptorIndex
    double setup_ms = 0;   ///< building the localiser (and its index) [ms]
    /// With --ref-poses and --query-poses: planar distance between the matched reference
    /// pose and the query's true pose, over every frame with a match [m].
    std::size_t evaluated = 0;
    double mean_error_m = 0;
    double median_error_m = 0;
    double share_over_10m = 0;  ///< fraction of evaluated frames with error > 10 m
};

class CoarseTool : public common::App {
  public:
    /// Parses the command line (TCLAP). Returns false when the program should stop at once
    /// (--help, --version, or a command-line error, reported to stderr); see exitCode().
    bool initialize(int argc, const char* const* argv) override;
    bool initialize(const std::vector<std::string>& args);

    /// Runs; returns the exit code (common::kExit*: 1 options, 2 bad input data, 3 write
    /// error). Errors (bad rawlogs, options, ...) are printed to `err` on one line naming the
    /// file and record (MRPT's dump only with --verbose), never thrown.
    int run(std::ostream& out, std::ostream& err);
    /// run(std::cout, std::cerr).
    int run() override;

    const CoarseRunSummary& summary() const { return summary_; }

  private:
    int runOrThrow(std::ostream& out, std::ostream& err);

    std::string ref_rawlog_, ref_descriptors_, query_rawlog_, out_csv_, camera_, ini_,
        section_ = "coarse", ref_poses_, query_poses_, save_descriptors_, confusion_png_,
        odometry_label_ = "ODOMETRY";
    int replicate_ = 1;
    bool quiet_ = false;
    bool verbose_ = false;
    CoarseRunSummary summary_;
};

}  // namespace lookup::coarse

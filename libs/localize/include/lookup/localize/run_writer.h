#pragma once
// Writes a localisation run folder (docs/run-format.md) as frames arrive, flushing each frame,
// so a run that is interrupted keeps every frame written so far.

#include <cstdio>
#include <map>
#include <memory>
#include <string>

#include "lookup/common/rawlog_io.h"
#include "lookup/localize/localizer.h"

namespace lookup::localize {

/// Per-stage totals, written as timing.json.
struct RunTiming {
    std::size_t frames = 0;
    std::size_t frames_dropped = 0;
    /// Loading the database and the coarse stage's references, before the first observation.
    double startup_s = 0;
    /// From the first observation to the last (start-up excluded): frames_per_s divides by it.
    double wall_s = 0;
    double coarse_ms = 0, select_ms = 0, refine_ms = 0, total_ms = 0;
    /// Refiner stage totals by name (e.g. "match" -> ms), summed over frames.
    std::map<std::string, double> refine_stage_ms;
    /// Observations refused at the localiser's edge, by reason (Rejection::kind).
    std::map<std::string, std::size_t> skipped;

    /// Frames the localiser processed (not dropped): per-frame times divide by this.
    std::size_t processed() const { return frames > frames_dropped ? frames - frames_dropped : 0; }
};

class RunWriter {
  public:
    /// Creates `out_dir` and opens its files. `run_ini_text` is copied to run.ini (the method
    /// name and the options used). Throws std::runtime_error naming the path on failure.
    RunWriter(const std::string& out_dir, const std::string& run_ini_text, bool write_debug_images,
              int debug_image_every);
    ~RunWriter();

    /// Appends one frame to frames.csv, poses.tum, coarse.tum and results.rawlog. `query` is
    /// the ceiling frame (for debug overlays; may be null).
    void write(const FrameResult& frame, const mrpt::obs::CObservationImage* query);

    /// Writes timing.json and closes results.rawlog.
    void finish(const RunTiming& timing);

    const std::string& directory() const { return dir_; }

  private:
    std::string dir_;
    std::FILE* frames_csv_ = nullptr;
    std::FILE* poses_tum_ = nullptr;
    std::FILE* coarse_tum_ = nullptr;
    std::unique_ptr<common::RawlogWriter> results_;
    bool debug_images_;
    int debug_every_;
    std::size_t frame_count_ = 0;
};

/// A flow overlay of one refinement on the query image: inliers green, outliers grey, points
/// the matcher rejected blue (the paper's Fig. 2 colours).
cv::Mat drawFlowOverlay(const cv::Mat& query_grey, const refine::RefineResult& result);

}  // namespace lookup::localize

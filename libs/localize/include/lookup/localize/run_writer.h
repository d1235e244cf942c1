#pragma once
// Writes a localisation run folder (docs/run-format.md) as frames arrive, flushing each frame,
// so a run that is interrupted keeps every frame written so far.

#include <map>
#include <memory>
#include <string>
#include <vector>

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
    double coarse_ms = 0, select_ms = 0, refine_ms = 0, place_ms = 0, total_ms = 0;
    /// Refiner stage totals by name (e.g. "match" -> ms), summed over frames.
    std::map<std::string, double> refine_stage_ms;
    /// --kidnap-every: ceiling frames from each restart to its first refined frame (-1: none
    /// before the next restart or the end).
    std::vector<int> cold_start_frames;
    /// Observations refused at the localiser's edge, by reason (Rejection::kind).
    std::map<std::string, std::size_t> skipped;
    /// The online refresh's counts by name (Localizer::OnlineRefreshCounts); empty when off.
    std::map<std::string, std::size_t> online_refresh;
    /// The ceiling camera's time offset against the odometry (estimate_s, sigma_s, pairs,
    /// applied_s); empty when nothing was estimated.
    std::map<std::string, double> camera_time_offset;
    /// The ceiling cameras' rolling-shutter readouts (query_s, query_sigma_s, survey_s,
    /// survey_sigma_s, frames, query_applied_s, survey_applied_s); empty when nothing was
    /// estimated.
    std::map<std::string, double> readout;
    /// The ceiling camera's lens once judged (images, dirty_share, least_transmission,
    /// corrected 0/1); empty before.
    std::map<std::string, double> lens;

    /// Frames the localiser processed (not dropped): per-frame times divide by this.
    std::size_t processed() const { return frames > frames_dropped ? frames - frames_dropped : 0; }
};

/// A run folder is written as `<out_dir>.partial` and renamed to `out_dir` only when it is
/// complete (timing.json, written last, names its frame count): readers never see a half
/// run under the final name, and a run that fails or is killed leaves the previous run at
/// `out_dir` as it was. Every write is checked: a failure throws common::WriteError naming
/// the file.
class RunWriter {
  public:
    /// Cleans what an interrupted run left beside `out_dir` (a `.partial` folder is removed, a
    /// `.old` one restored when `out_dir` is missing, both said on stderr), then creates the
    /// staging folder and opens its files. `run_ini_text` is copied to run.ini (the method
    /// name and the options used). Throws common::ConfigError when `out_dir` exists and is not
    /// a run folder (it would be replaced), common::WriteError when a file cannot be written.
    RunWriter(const std::string& out_dir, const std::string& run_ini_text, bool write_debug_images,
              int debug_image_every);
    /// What an interrupted run left beside `out_dir` (see the constructor), handled before a
    /// run reads its inputs, so a run refused at the start still restores `out_dir`.
    static void cleanLeftovers(const std::string& out_dir);

    /// Without finish(): closes the files and leaves the staging folder as it is.
    ~RunWriter();

    /// Appends one frame to frames.csv, poses.tum, coarse.tum and results.rawlog, flushed so
    /// that a killed run keeps it. `query` is the ceiling frame (for debug overlays; may be
    /// null).
    void write(const FrameResult& frame, const mrpt::obs::CObservationImage* query);

    /// Closes and syncs every file, writes timing.json last and replaces `out_dir` with the
    /// staging folder (`out_dir` -> `.old`, staging -> `out_dir`, `.old` removed).
    void finish(const RunTiming& timing);

    /// The run folder (`out_dir`).
    const std::string& directory() const { return final_dir_; }
    /// Where the frames are written until finish(): `<out_dir>.partial`.
    const std::string& stagingDirectory() const { return dir_; }
    std::size_t framesWritten() const { return frame_count_; }

  private:
    void publish();

    std::string final_dir_;
    std::string dir_;
    std::unique_ptr<common::OutputFile> frames_csv_, poses_tum_, coarse_tum_;
    std::unique_ptr<common::RawlogWriter> results_;
    bool debug_images_;
    int debug_every_;
    std::size_t frame_count_ = 0;
};

/// A flow overlay of one refinement on the query image: inliers green, outliers grey, points
/// the matcher rejected blue (the paper's Fig. 2 colours).
cv::Mat drawFlowOverlay(const cv::Mat& query_grey, const refine::RefineResult& result);

}  // namespace lookup::localize

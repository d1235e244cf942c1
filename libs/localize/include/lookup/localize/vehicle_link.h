#pragma once
// What a run gives the vehicle besides its run folder: the pose stream (--publish), the health
// messages and log lines, and the persisted fix for restarts (--persist-fix). One object per
// run, fed by the frame loop (lookup::localize::runLocalization / runLiveLocalization).

#include <mrpt/obs/CObservation.h>

#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "lookup/localize/fix_store.h"
#include "lookup/localize/health.h"
#include "lookup/localize/localizer.h"
#include "lookup/localize/pose_stream.h"

namespace lookup::localize {

/// The pose message of one frame (type "pose"; the stream adds t_sent and latency_ms).
nlohmann::json poseMessage(const FrameResult& frame, std::size_t index);

class VehicleLink {
  public:
    /// Opens the pose stream (`publish_url`, may be empty) at once, so that a bad address
    /// fails before anything is loaded. `persist_path` (may be empty): the fix file.
    /// `realtime`: times are wall time (live, --realtime), otherwise the recorded time.
    VehicleLink(const LocalizerOptions& options, const std::string& publish_url,
                std::string persist_path, bool realtime);
    ~VehicleLink();

    /// Offers a valid persisted fix of `db` to `localizer` as a start-up hypothesis, or logs
    /// why not; starts persisting. tcp: waits up to `wait_for_client_s` for a first client.
    void start(Localizer& localizer, const database::ReferenceDatabase& db,
               double wait_for_client_s);

    /// An observation arrived (any sensor); `wall_s`: the run's wall clock.
    void observation(const mrpt::obs::CObservation& obs, double wall_s);
    /// Frame `index` was computed; `arrival_unix_s`: when it reached the localiser.
    void frame(const FrameResult& frame, std::size_t index, double arrival_unix_s, double wall_s);
    /// Health messages and camera checks; call often (also while no observation arrives).
    void tick(double wall_s, bool force = false);

    /// Sends the last health message, persists the fix, closes the stream and adds "publish",
    /// "health" and "persist_fix" to `run_dir`/timing.json.
    void finish(const std::string& run_dir, double wall_s);

  private:
    double runTime(double wall_s) const { return realtime_ ? wall_s : data_time_s_; }

    bool realtime_;
    std::unique_ptr<PoseStream> stream_;
    HealthMonitor health_;
    std::string persist_path_;
    double persist_interval_s_;
    std::unique_ptr<FixPersister> persister_;
    nlohmann::json persist_report_ = nlohmann::json::object();
    double first_stamp_s_ = NAN, data_time_s_ = 0;
};

}  // namespace lookup::localize

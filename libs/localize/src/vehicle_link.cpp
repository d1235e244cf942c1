#include "lookup/localize/vehicle_link.h"

#include <cstdio>
#include <fstream>

#include "lookup/database/reference_database.h"

namespace lookup::localize {

nlohmann::json poseMessage(const FrameResult& f, std::size_t index) {
    nlohmann::json m;
    m["type"] = "pose";
    m["frame"] = index;
    m["t_image"] = f.time_s;
    m["status"] = toString(f.status);
    m["reason"] = f.reason;
    if (f.has_pose) {
        m["x"] = f.pose.mean.x();
        m["y"] = f.pose.mean.y();
        m["yaw"] = f.pose.mean.phi();
        if (f.height_m) m["z"] = *f.height_m;
        const auto& c = f.pose.cov;
        m["cov"] = {c(0, 0), c(0, 1), c(0, 2), c(1, 0), c(1, 1),
                    c(1, 2), c(2, 0), c(2, 1), c(2, 2)};
    } else {
        m["x"] = m["y"] = m["yaw"] = m["cov"] = nullptr;
    }
    m["source"] = f.pose_source;
    m["inlier_share"] = f.inlier_share;
    m["processing_ms"] = f.times.total_ms;
    return m;
}

VehicleLink::VehicleLink(const LocalizerOptions& options, const std::string& publish_url,
                         std::string persist_path, bool realtime)
    : realtime_(realtime),
      health_(options.ceiling_camera_label, options.health_interval_s,
              realtime ? options.camera_timeout_s : 0.0),
      persist_path_(std::move(persist_path)),
      persist_interval_s_(options.persist_interval_s) {
    if (!publish_url.empty()) {
        stream_ = std::make_unique<PoseStream>(publish_url);
        std::fprintf(stderr, "lookup-localize: publishing on %s (port %d)\n", publish_url.c_str(),
                     stream_->port());
    }
}

// A run that ends by an exception still keeps its last fix: FixPersister flushes.
VehicleLink::~VehicleLink() = default;

void VehicleLink::start(Localizer& localizer, const database::ReferenceDatabase& db,
                        double wait_for_client_s) {
    if (!persist_path_.empty()) {
        const std::string identity = databaseIdentity(db);
        std::string why_not;
        persist_report_["file"] = persist_path_;
        if (const auto fix = readFixFile(persist_path_, identity, why_not)) {
            localizer.offerHypothesis(fix->pose);
            std::fprintf(stderr,
                         "lookup-localize: %s: offering the fix of t = %.3f (x %.3f, y %.3f, "
                         "yaw %.3f) as a start-up hypothesis\n",
                         persist_path_.c_str(), fix->time_s, fix->pose.mean.x(), fix->pose.mean.y(),
                         fix->pose.mean.phi());
            persist_report_["offered"] = true;
        } else {
            std::fprintf(stderr, "lookup-localize: %s; starting without it\n", why_not.c_str());
            persist_report_["offered"] = false;
            persist_report_["not_offered_because"] = why_not;
        }
        persister_ = std::make_unique<FixPersister>(persist_path_, persist_interval_s_,
                                                    db.directory(), identity);
    }
    if (stream_ && wait_for_client_s > 0 && !stream_->waitForClient(wait_for_client_s)) {
        std::fprintf(stderr, "lookup-localize: %s: no client after %.1f s; going on\n",
                     stream_->url().c_str(), wait_for_client_s);
    }
}

void VehicleLink::observation(const mrpt::obs::CObservation& obs, double wall_s) {
    const double stamp = mrpt::Clock::toDouble(obs.timestamp);
    if (std::isnan(first_stamp_s_)) first_stamp_s_ = stamp;
    data_time_s_ = std::max(data_time_s_, stamp - first_stamp_s_);
    health_.observe(obs.sensorLabel, stamp, runTime(wall_s));
}

void VehicleLink::frame(const FrameResult& f, std::size_t index, double arrival_unix_s,
                        double wall_s) {
    health_.frame(f, runTime(wall_s));
    if (persister_) persister_->update(f);
    if (stream_) stream_->push(poseMessage(f, index), arrival_unix_s);
}

void VehicleLink::tick(double wall_s, bool force) {
    auto health = health_.tick(runTime(wall_s), force);
    if (!health) return;
    if (stream_) {
        const auto s = stream_->stats();
        (*health)["messages_dropped"] = s.dropped_queue_full + s.dropped_slow_client;
        (*health)["clients"] = s.clients_now;
    }
    std::fprintf(stderr, "lookup-localize: health: %s\n", HealthMonitor::logLine(*health).c_str());
    if (stream_) stream_->push(std::move(*health));
}

void VehicleLink::finish(const std::string& run_dir, double wall_s) {
    tick(wall_s, /*force=*/true);  // the run's totals, also for a run shorter than the interval
    nlohmann::json extra;
    if (persister_) {
        persister_->flush();
        persist_report_["writes"] = persister_->writes();
        extra["persist_fix"] = persist_report_;
    }
    extra["health"] = health_.summary();
    if (stream_) {
        stream_->close();
        const auto s = stream_->stats();
        extra["publish"] = {{"url", stream_->url()},
                            {"queued", s.queued},
                            {"sent", s.sent},
                            {"dropped_queue_full", s.dropped_queue_full},
                            {"dropped_slow_client", s.dropped_slow_client},
                            {"send_errors", s.send_errors},
                            {"clients_connected", s.clients_connected},
                            {"clients_disconnected", s.clients_disconnected}};
        if (s.dropped_queue_full + s.dropped_slow_client > 0) {
            std::fprintf(stderr,
                         "lookup-localize: %s: %zu messages dropped (%zu queue full, %zu for "
                         "clients not reading)\n",
                         stream_->url().c_str(), s.dropped_queue_full + s.dropped_slow_client,
                         s.dropped_queue_full, s.dropped_slow_client);
        }
    }
    // timing.json is the run writer's; these sections are added to it.
    const std::string path = run_dir + "/timing.json";
    nlohmann::json timing = nlohmann::json::object();
    {
        std::ifstream in(path);
        if (in) timing = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
        if (timing.is_discarded()) timing = nlohmann::json::object();
    }
    timing.update(extra);
    std::ofstream(path) << timing.dump(2) << "\n";
}

}  // namespace lookup::localize

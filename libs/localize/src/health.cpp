#include "lookup/localize/health.h"

#include <cstdio>

namespace lookup::localize {

HealthMonitor::HealthMonitor(std::string ceiling_label, double interval_s, double camera_timeout_s)
    : ceiling_label_(std::move(ceiling_label)),
      interval_s_(interval_s),
      camera_timeout_s_(camera_timeout_s),
      next_message_s_(interval_s) {}

void HealthMonitor::observe(const std::string& label, double stamp_s, double now_s) {
    Sensor& s = sensors_[label];
    if (stamp_s < s.last_stamp_s) {
        const double jump = s.last_stamp_s - stamp_s;
        ++s.clock_jumps;
        s.largest_jump_s = std::max(s.largest_jump_s, jump);
        char text[160];
        std::snprintf(text, sizeof text, "%s clock jumped back %.3f s (stamp %.6f after %.6f)",
                      label.c_str(), jump, stamp_s, s.last_stamp_s);
        event(text);
    }
    s.last_stamp_s = stamp_s;
    ++s.frames;
    if (label != ceiling_label_) return;
    checkCamera(now_s);  // a gap seen only now (recorded time) is still reported
    if (camera_stopped_) {
        char text[120];
        std::snprintf(text, sizeof text, "%s resumed after %.2f s without a frame", label.c_str(),
                      now_s - last_ceiling_s_);
        event(text);
        camera_stopped_ = false;
    }
    last_ceiling_s_ = now_s;
    have_ceiling_ = true;
}

void HealthMonitor::frame(const FrameResult& result, double now_s) {
    status_ = toString(result.status);
    if (result.status == FrameStatus::Dropped) {
        ++frames_dropped_;
        return;
    }
    ++frames_processed_;
    if (result.status == FrameStatus::Refined) last_fix_s_ = now_s;
}

void HealthMonitor::checkCamera(double now_s) {
    if (camera_timeout_s_ <= 0 || camera_stopped_) return;
    const double silent_s = now_s - last_ceiling_s_;
    if (silent_s <= camera_timeout_s_) return;
    camera_stopped_ = true;
    ++camera_stops_;
    char text[160];
    if (have_ceiling_) {
        std::snprintf(text, sizeof text, "%s stopped: no frame for %.2f s", ceiling_label_.c_str(),
                      silent_s);
    } else {
        std::snprintf(text, sizeof text, "%s: no frame in the first %.2f s", ceiling_label_.c_str(),
                      silent_s);
    }
    event(text);
}

void HealthMonitor::event(const std::string& text) {
    std::fprintf(stderr, "lookup-localize: health: %s\n", text.c_str());
    events_.push_back(text);
}

std::optional<nlohmann::json> HealthMonitor::tick(double now_s, bool force) {
    checkCamera(now_s);
    const bool periodic = interval_s_ > 0 && now_s >= next_message_s_;
    if (!periodic && events_.empty() && !force) return std::nullopt;
    if (periodic) {
        // Catch up without a burst when the clock leapt (recorded time, a long frame).
        next_message_s_ = std::max(next_message_s_ + interval_s_, now_s);
    }
    auto m = message(now_s);
    events_.clear();
    return m;
}

nlohmann::json HealthMonitor::message(double now_s) const {
    nlohmann::json m;
    m["type"] = "health";
    m["t_run"] = now_s;
    nlohmann::json frames = nlohmann::json::object(), jumps = nlohmann::json::object();
    for (const auto& [label, s] : sensors_) {
        frames[label] = s.frames;
        if (s.clock_jumps > 0) jumps[label] = s.clock_jumps;
    }
    m["frames_received"] = frames;
    m["frames_processed"] = frames_processed_;
    m["frames_dropped"] = frames_dropped_;
    m["last_fix_age_s"] = last_fix_s_ ? nlohmann::json(now_s - *last_fix_s_) : nlohmann::json();
    m["status"] = status_;
    m["camera"] = camera_stopped_ ? "stopped" : have_ceiling_ ? "ok" : "waiting";
    m["camera_frame_age_s"] = now_s - last_ceiling_s_;
    m["clock_jumps"] = jumps;
    m["events"] = events_;
    return m;
}

std::string HealthMonitor::logLine(const nlohmann::json& h) {
    std::string frames;
    for (const auto& [label, n] : h.at("frames_received").items()) {
        frames += (frames.empty() ? "" : ", ") + label + " " + n.dump();
    }
    char buf[256], age_text[32] = "never";
    const auto& age = h.at("last_fix_age_s");
    if (!age.is_null()) std::snprintf(age_text, sizeof age_text, "%.2f s ago", age.get<double>());
    std::snprintf(buf, sizeof buf,
                  "%.1f s: frames received %s; %zu processed, %zu dropped; last fix %s; status %s; "
                  "camera %s",
                  h.at("t_run").get<double>(), frames.empty() ? "none" : frames.c_str(),
                  h.at("frames_processed").get<std::size_t>(),
                  h.at("frames_dropped").get<std::size_t>(), age_text,
                  h.at("status").get<std::string>().c_str(),
                  h.at("camera").get<std::string>().c_str());
    std::string line = buf;
    if (h.contains("messages_dropped")) {
        line += "; stream dropped " + h.at("messages_dropped").dump();
    }
    return line;
}

nlohmann::json HealthMonitor::summary() const {
    nlohmann::json jumps = nlohmann::json::object();
    for (const auto& [label, s] : sensors_) {
        if (s.clock_jumps == 0) continue;
        jumps[label] = {{"count", s.clock_jumps}, {"largest_s", s.largest_jump_s}};
    }
    return {{"clock_jumps", jumps}, {"camera_stops", camera_stops_}};
}

}  // namespace lookup::localize

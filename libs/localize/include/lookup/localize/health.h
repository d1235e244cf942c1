#pragma once
// Health of a run for the vehicle (docs/run-format.md, "Health messages"): frames received
// per sensor, frames dropped, the last fix's age and the current status, every interval; and
// at once, events: the ceiling camera stopped or resumed, a sensor's clock jumped backwards.
//
// Times are on the run's clock, given by the caller: wall time in live and real-time runs
// (a camera that stops is noticed while nothing arrives), the recorded time otherwise.

#include <nlohmann/json.hpp>

#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "lookup/localize/localizer.h"

namespace lookup::localize {

class HealthMonitor {
  public:
    /// `interval_s`: periodic messages (0 = none; events are still reported).
    /// `camera_timeout_s`: no `ceiling_label` frame for this long reports the camera stopped
    /// (0 = never).
    HealthMonitor(std::string ceiling_label, double interval_s, double camera_timeout_s);

    /// An observation of `label`, stamped `stamp_s`, arrived at run time `now_s`. A stamp
    /// earlier than the previous one of the same sensor is a clock jump (an event).
    void observe(const std::string& label, double stamp_s, double now_s);

    /// A ceiling frame's result (processed or dropped), at run time `now_s`.
    void frame(const FrameResult& result, double now_s);

    /// A health message (type "health") when one is due: every interval_s, and at once after
    /// an event; always with `force` (the run's last). Events are also written to stderr as
    /// they happen.
    std::optional<nlohmann::json> tick(double now_s, bool force = false);

    /// One log line for a health message.
    static std::string logLine(const nlohmann::json& health);

    /// Totals for timing.json: clock jumps per sensor, camera stops.
    nlohmann::json summary() const;

  private:
    struct Sensor {
        std::size_t frames = 0;
        double last_stamp_s = NAN;
        std::size_t clock_jumps = 0;
        double largest_jump_s = 0;
    };
    void event(const std::string& text);
    void checkCamera(double now_s);
    nlohmann::json message(double now_s) const;

    std::string ceiling_label_;
    double interval_s_, camera_timeout_s_;
    std::map<std::string, Sensor> sensors_;
    double last_ceiling_s_ = 0;  ///< run time of the last ceiling frame (0: the start)
    bool have_ceiling_ = false;
    bool camera_stopped_ = false;
    std::size_t camera_stops_ = 0;
    std::size_t frames_processed_ = 0, frames_dropped_ = 0;
    std::string status_ = "starting";
    std::optional<double> last_fix_s_;
    double next_message_s_;
    std::vector<std::string> events_;  ///< since the last message
};

}  // namespace lookup::localize

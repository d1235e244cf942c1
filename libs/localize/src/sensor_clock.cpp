#include "lookup/localize/sensor_clock.h"

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdlib>

#include "lookup/common/config.h"

namespace lookup::localize {

namespace {
constexpr const char* kSection = "time_offsets";
constexpr double kMaxOffset_s = 1.0;  // more is a broken clock, not an offset
}  // namespace

SensorClock SensorClock::fromConfig(const mrpt::config::CConfigFileBase& ini,
                                    const std::string& file) {
    SensorClock clock;
    if (!ini.sectionExists(kSection)) return clock;
    std::vector<std::string> keys;
    ini.getAllKeys(kSection, keys);
    for (const auto& label : keys) {
        const std::string text = ini.read_string(kSection, label, "");
        char* end = nullptr;
        const double v = std::strtod(text.c_str(), &end);
        const char* stop = text.c_str() + text.size();
        const bool rest_blank =
            end != text.c_str() && std::all_of<const char*>(end, stop, [](char c) {
                return std::isspace(static_cast<unsigned char>(c)) != 0;
            });
        if (!rest_blank || !std::isfinite(v) || std::abs(v) > kMaxOffset_s) {
            throw common::ConfigError(file + " [" + kSection + "] " + label + ": '" + text +
                                      "' is not a time offset in seconds in [-1, 1]");
        }
        clock.offsets_[label] = v;
        clock.min_offset_ = std::min(clock.min_offset_, v);
    }
    return clock;
}

double SensorClock::offsetOf(const std::string& label) const {
    const auto it = offsets_.find(label);
    return it == offsets_.end() ? 0.0 : it->second;
}

void SensorClock::saveTo(mrpt::config::CConfigFileBase& target) const {
    for (const auto& [label, v] : offsets_) target.write(kSection, label, v);
}

std::vector<SensorClock::Item> SensorClock::push(Item item) {
    const double raw = mrpt::Clock::toDouble(item.obs->timestamp);
    const double corrected = raw + offsetOf(item.obs->sensorLabel);
    item.obs->timestamp = mrpt::Clock::fromDouble(corrected);
    latest_raw_s_ = std::max(latest_raw_s_, raw);
    pending_.emplace(corrected, std::move(item));
    // Any later observation has a raw stamp after latest_raw_s_, so a corrected one after
    // latest_raw_s_ + min_offset_.
    std::vector<Item> ready;
    while (!pending_.empty() && pending_.begin()->first <= latest_raw_s_ + min_offset_) {
        ready.push_back(std::move(pending_.begin()->second));
        pending_.erase(pending_.begin());
    }
    return ready;
}

std::vector<SensorClock::Item> SensorClock::flush() {
    std::vector<Item> out;
    for (auto& [t, item] : pending_) out.push_back(std::move(item));
    pending_.clear();
    return out;
}

}  // namespace lookup::localize

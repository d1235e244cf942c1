#pragma once
// The localiser's own sensors' time offsets ([time_offsets] of the --ini: `<sensor label> =
// <seconds>`), applied where observations come in, before the localiser sees them. Each offset
// is added to that sensor's stamps so that all sensors share one clock, the vehicle's (a camera
// stamped 40 ms after its exposure: `CEILING_CAM = -0.040`); every frame's pose is then the
// pose at the image's exposure time. Observations whose corrected stamps change their order are
// held back until nothing later can come before them (at most the spread of the offsets), so
// the localiser still gets them in time order; the hold counts in each frame's latency.

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/obs/CObservation.h>

#include <map>
#include <string>
#include <vector>

namespace lookup::localize {

class SensorClock {
  public:
    /// An observation on its way, with what the replay / live loop knows of it.
    struct Item {
        mrpt::obs::CObservation::Ptr obs;
        double arrival_s = 0;    ///< when it arrived (the loop's clock) [s]
        std::size_t record = 0;  ///< rawlog record (npos: live)
    };

    /// No offsets: observations pass unchanged.
    SensorClock() = default;
    /// Reads [time_offsets] of `ini` (absent: no offsets). Throws common::ConfigError naming
    /// `file`, the section and the key for a value that is not a number in [-1, 1] s.
    static SensorClock fromConfig(const mrpt::config::CConfigFileBase& ini,
                                  const std::string& file);

    bool empty() const { return offsets_.empty(); }
    /// Whether `label`'s offset is configured (measured), zero or not.
    bool configures(const std::string& label) const { return offsets_.count(label) > 0; }
    /// The offset of `label` (0 when not configured) [s].
    double offsetOf(const std::string& label) const;
    /// Writes the offsets as read ([time_offsets]) into a run's run.ini.
    void saveTo(mrpt::config::CConfigFileBase& target) const;

    /// Shifts the stamp of `item.obs` by its sensor's offset and queues it; returns the queued
    /// observations that no later one can precede, in corrected time order.
    std::vector<Item> push(Item item);
    /// Everything still queued, in corrected time order (end of a pass or of the run).
    std::vector<Item> flush();

  private:
    std::map<std::string, double> offsets_;
    double min_offset_ = 0;  ///< smallest offset, 0 included (sensors not listed)
    double latest_raw_s_ = -1e300;
    std::multimap<double, Item> pending_;  ///< by corrected stamp
};

}  // namespace lookup::localize

#include "lookup/survey/levelling.h"

#include <mrpt/core/bits_math.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/datetime.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <utility>
#include <vector>

#include "lookup/survey/scan_deskew.h"
#include "lookup/survey/traverse.h"

namespace lookup::survey {

bool AttitudeTrack::add(double time_s, const Attitude& a) {
    if (!time_.empty() && !(time_s > time_.back())) return false;
    time_.push_back(time_s);
    attitude_.push_back(a);
    return true;
}

std::optional<Attitude> AttitudeTrack::at(double time_s, double max_gap_s) const {
    const auto it = std::lower_bound(time_.begin(), time_.end(), time_s);
    if (it == time_.end()) return std::nullopt;
    const std::size_t j = std::size_t(it - time_.begin());
    if (*it == time_s) return attitude_[j];
    if (j == 0 || time_[j] - time_[j - 1] > max_gap_s) return std::nullopt;
    const double w = (time_s - time_[j - 1]) / (time_[j] - time_[j - 1]);
    const Attitude &a = attitude_[j - 1], &b = attitude_[j];
    return Attitude{a.pitch + w * (b.pitch - a.pitch), a.roll + w * (b.roll - a.roll)};
}

double AttitudeTrack::maxAbsPitch() const {
    double m = 0;
    for (const Attitude& a : attitude_) m = std::max(m, std::abs(a.pitch));
    return m;
}

namespace {

/// A step of the vehicle on a grade as its plan motion: forward travel shortened by the pitch,
/// sideways travel by the roll.
mrpt::poses::CPose2D planStep(const mrpt::poses::CPose2D& step, const Attitude& a) {
    return {step.x() * std::cos(a.pitch), step.y() * std::cos(a.roll), step.phi()};
}

/// The floor's height along the drive, by signed plan travel (the vehicle's own ground heights
/// from the odometry steps and the pitch), in bins of kBinM.
class FloorProfile {
  public:
    static constexpr double kBinM = 0.5;
    void add(double s, double z) {
        auto& [sum, n] = bins_[std::lround(s / kBinM)];
        sum += z;
        ++n;
    }
    std::optional<double> at(double s) const {
        const auto it = bins_.find(std::lround(s / kBinM));
        if (it == bins_.end()) return std::nullopt;
        return it->second.first / it->second.second;
    }

  private:
    std::map<long, std::pair<double, int>> bins_;
};

/// Where the vehicle was at an odometry record: signed plan travel and ground height.
struct Station {
    double time_s, s, z;
};

/// Travel and ground height at `time_s`, interpolated between stations.
std::optional<Station> stationAt(const std::vector<Station>& st, double time_s) {
    const auto it = std::lower_bound(st.begin(), st.end(), time_s,
                                     [](const Station& a, double t) { return a.time_s < t; });
    if (it == st.end() || (it == st.begin() && it->time_s != time_s)) return std::nullopt;
    if (it->time_s == time_s) return *it;
    const Station &a = *(it - 1), &b = *it;
    const double w = (time_s - a.time_s) / (b.time_s - a.time_s);
    return Station{time_s, a.s + w * (b.s - a.s), a.z + w * (b.z - a.z)};
}

/// Odometry steps to plan motion; the stations and floor heights they pass.
void levelOdometry(TraverseData& traverse, const AttitudeTrack& attitude, double max_gap_s,
                   LevellingReport& rep, std::vector<Station>& stations, FloorProfile& floor) {
    bool first = true;
    mrpt::poses::CPose2D last_raw, last_plan;
    double last_time = 0, s = 0, z = 0;
    for (auto& o : traverse.laser_sequence) {
        auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o);
        if (!odo) continue;
        const double time = mrpt::Clock::toDouble(odo->timestamp);
        const mrpt::poses::CPose2D raw = odo->odometry;
        if (first) {
            last_plan = raw;
            first = false;
        } else {
            const mrpt::poses::CPose2D step = raw - last_raw;
            const auto a = attitude.at(0.5 * (time + last_time), max_gap_s);
            const mrpt::poses::CPose2D plan = a ? planStep(step, *a) : step;
            rep.odometry_levelled += a ? 1 : 0;
            rep.odometry_m += std::hypot(step.x(), step.y());
            rep.levelled_m += std::hypot(plan.x(), plan.y());
            last_plan = last_plan + plan;
            s += plan.x();
            if (a) z -= step.x() * std::sin(a->pitch);  // positive pitch: nose down
        }
        last_raw = raw;
        last_time = time;
        odo->odometry = last_plan;
        if (const auto a = attitude.at(time, max_gap_s); a && odo->hasVelocities) {
            odo->velocityLocal.vx *= std::cos(a->pitch);
            odo->velocityLocal.vy *= std::cos(a->roll);
        }
        if (stations.empty() || time > stations.back().time_s) stations.push_back({time, s, z});
        floor.add(s, z);
    }
}

/// Makes invalid the returns of `scan` less than `floor_margin_m` above the floor where they
/// lie, or more than `roof_margin_m` above the scanner's own height over the floor: where the
/// grade changes, the tilted scan plane meets the floor or the roof ahead, walls that are not
/// there.
void dropOffSliceReturns(mrpt::obs::CObservation2DRangeScan& scan, const Attitude& a,
                         const Station& at, const FloorProfile& floor, double floor_margin_m,
                         double roof_margin_m, LevellingReport& rep) {
    const mrpt::poses::CPose3D levelled =
        mrpt::poses::CPose3D(0, 0, 0, 0, a.pitch, a.roll) + scan.sensorPose;
    for (std::size_t i = 0; i < scan.getScanSize(); ++i) {
        if (!scan.getScanRangeValidity(i)) continue;
        const double r = scan.getScanRange(i), b = scan.getScanAngle(i);
        double x, y, z;
        levelled.composePoint(r * std::cos(b), r * std::sin(b), 0, x, y, z);
        const auto floor_z = floor.at(at.s + x);
        if (!floor_z) continue;
        const double above_floor = z - (*floor_z - at.z);
        const bool on_floor = above_floor < floor_margin_m;
        const bool on_roof = roof_margin_m > 0 && above_floor > levelled.z() + roof_margin_m;
        if (!on_floor && !on_roof) continue;
        scan.setScanRangeValidity(i, false);
        ++(on_floor ? rep.floor_returns : rep.roof_returns);
    }
}

}  // namespace

LevellingReport levelTraverse(TraverseData& traverse, const AttitudeTrack& attitude,
                              double max_gap_s, double floor_margin_m, double roof_margin_m) {
    LevellingReport rep;
    rep.imu_records = attitude.size();
    if (attitude.empty()) return rep;
    rep.max_pitch_deg = mrpt::RAD2DEG(attitude.maxAbsPitch());
    std::vector<Station> stations;
    FloorProfile floor;
    levelOdometry(traverse, attitude, max_gap_s, rep, stations, floor);
    for (auto& o : traverse.laser_sequence) {
        auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o);
        if (!scan) continue;
        const double time = mrpt::Clock::toDouble(scan->timestamp);
        const auto a = attitude.at(time, max_gap_s);
        if (!a) continue;
        if (const auto at = stationAt(stations, time); at) {
            dropOffSliceReturns(*scan, *a, *at, floor, floor_margin_m, roof_margin_m, rep);
        }
        deskewScan(*scan, mrpt::poses::CPose2D(), *a);
        ++rep.scans_levelled;
    }
    return rep;
}

}  // namespace lookup::survey

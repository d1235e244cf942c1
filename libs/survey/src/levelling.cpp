#include "lookup/survey/levelling.h"

#include <mrpt/core/bits_math.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/datetime.h>

#include <algorithm>
#include <cmath>

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

}  // namespace

LevellingReport levelTraverse(TraverseData& traverse, const AttitudeTrack& attitude,
                              double max_gap_s) {
    LevellingReport rep;
    rep.imu_records = attitude.size();
    if (attitude.empty()) return rep;
    rep.max_pitch_deg = mrpt::RAD2DEG(attitude.maxAbsPitch());
    bool first = true;
    mrpt::poses::CPose2D last_raw, last_plan;
    double last_time = 0;
    for (auto& o : traverse.laser_sequence) {
        const double time = mrpt::Clock::toDouble(o->timestamp);
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
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
            }
            last_raw = raw;
            last_time = time;
            odo->odometry = last_plan;
            if (const auto a = attitude.at(time, max_gap_s); a && odo->hasVelocities) {
                odo->velocityLocal.vx *= std::cos(a->pitch);
                odo->velocityLocal.vy *= std::cos(a->roll);
            }
        } else if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            const auto a = attitude.at(time, max_gap_s);
            if (!a) continue;
            deskewScan(*scan, mrpt::poses::CPose2D(), *a);
            ++rep.scans_levelled;
        }
    }
    return rep;
}

}  // namespace lookup::survey

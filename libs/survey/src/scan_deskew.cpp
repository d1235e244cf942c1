#include "lookup/survey/scan_deskew.h"

#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/datetime.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <utility>
#include <vector>

#include "lookup/common/odometry_track.h"

namespace lookup::survey {
namespace {

// Neighbouring returns farther apart than this (plus a few rays' spacing at their range) lie
// on different surfaces and are not joined [m].
constexpr double kMaxJoinM = 0.2;

mrpt::poses::CPose2D interpolate(const mrpt::poses::CPose2D& motion, double a) {
    return mrpt::poses::CPose2D(a * motion.x(), a * motion.y(), a * motion.phi());
}

common::OdometryTrack odometryOf(const TraverseData& traverse) {
    common::OdometryTrack track;
    for (const auto& o : traverse.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            track.add(mrpt::Clock::toDouble(odo->timestamp), odo->odometry);
        }
    }
    return track;
}

/// Scan points in the first ray's sensor frame, each with its bearing measured from the first
/// bin (bin b lies at b * step); invalid rays are flagged.
struct Redrawn {
    std::vector<double> x, y, bearing;
    std::vector<bool> valid;
};

Redrawn redraw(const mrpt::obs::CObservation2DRangeScan& scan, const mrpt::poses::CPose2D& motion,
               const Attitude& attitude) {
    const std::size_t n = scan.getScanSize();
    const mrpt::poses::CPose2D sensor(scan.sensorPose);
    const bool tilted = attitude.pitch != 0 || attitude.roll != 0;
    // The scanner in a frame of the vehicle's heading whose x-y plane is horizontal.
    const mrpt::poses::CPose3D levelled =
        mrpt::poses::CPose3D(0, 0, 0, 0, attitude.pitch, attitude.roll) + scan.sensorPose;
    const mrpt::poses::CPose2D sensor_inv = mrpt::poses::CPose2D() - sensor;
    Redrawn out{std::vector<double>(n), std::vector<double>(n), std::vector<double>(n),
                std::vector<bool>(n, false)};
    for (std::size_t i = 0; i < n; ++i) {
        if (!scan.getScanRangeValidity(i)) continue;
        const double r = scan.getScanRange(i), bearing = scan.getScanAngle(i);
        double x = r * std::cos(bearing), y = r * std::sin(bearing);
        if (tilted) {
            double vx, vy, vz;
            levelled.composePoint(x, y, 0, vx, vy, vz);
            sensor.inverseComposePoint(vx, vy, x, y);
        }
        // The sensor at this ray's time, seen from the sensor at the first ray.
        const mrpt::poses::CPose2D at_ray =
            sensor_inv + interpolate(motion, i / double(n - 1)) + sensor;
        at_ray.composePoint(x, y, out.x[i], out.y[i]);
        const double a = std::atan2(out.y[i], out.x[i]);
        out.bearing[i] = scan.rightToLeft ? a + scan.aperture / 2 : scan.aperture / 2 - a;
        out.valid[i] = true;
    }
    return out;
}

}  // namespace

void deskewScan(mrpt::obs::CObservation2DRangeScan& scan, const mrpt::poses::CPose2D& motion,
                const Attitude& attitude) {
    const std::size_t n = scan.getScanSize();
    if (n < 2) return;
    const double step = scan.aperture / double(n - 1);
    const Redrawn p = redraw(scan, motion, attitude);
    std::vector<float> range(n, 0.0f);
    std::vector<bool> valid(n, false);
    const auto keep = [&](long bin, double rho) {
        if (bin < 0 || bin >= long(n) || !(rho > 0)) return;
        if (!valid[bin] || rho < range[bin]) range[bin] = float(rho), valid[bin] = true;
    };
    const auto joined = [&](std::size_t i) {
        return i + 1 < n && p.valid[i] && p.valid[i + 1] &&
               std::hypot(p.x[i + 1] - p.x[i], p.y[i + 1] - p.y[i]) <
                   kMaxJoinM + 4 * step * std::hypot(p.x[i], p.y[i]);
    };
    for (std::size_t i = 0; i < n; ++i) {
        if (!p.valid[i]) continue;
        if (!joined(i)) {
            // A return joined to neither neighbour goes to its nearest bin (half a bin off).
            if (i == 0 || !joined(i - 1)) {
                keep(std::lround(p.bearing[i] / step), std::hypot(p.x[i], p.y[i]));
            }
            continue;
        }
        // Neighbouring returns on one surface: each bin between their bearings takes the range
        // where its ray crosses the segment joining them, so bearings are not quantised.
        const double lo = std::min(p.bearing[i], p.bearing[i + 1]);
        const double hi = std::max(p.bearing[i], p.bearing[i + 1]);
        for (long b = std::max(0L, long(std::ceil(lo / step))); b < long(n) && b * step <= hi;
             ++b) {
            const double a = scan.getScanAngle(std::size_t(b));
            const double dx = std::cos(a), dy = std::sin(a);
            const double c0 = dx * p.y[i] - dy * p.x[i], c1 = dx * p.y[i + 1] - dy * p.x[i + 1];
            if (c0 == c1) continue;
            const double s = c0 / (c0 - c1);
            keep(b, dx * (p.x[i] + s * (p.x[i + 1] - p.x[i])) +
                        dy * (p.y[i] + s * (p.y[i + 1] - p.y[i])));
        }
    }
    for (std::size_t i = 0; i < n; ++i) {
        scan.setScanRange(i, range[i]);
        scan.setScanRangeValidity(i, valid[i]);
    }
}

std::size_t deskewTraverse(TraverseData& traverse, double sweep_s) {
    if (!(sweep_s > 0)) return 0;
    const common::OdometryTrack odometry = odometryOf(traverse);
    std::size_t corrected = 0;
    for (auto& o : traverse.laser_sequence) {
        auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o);
        if (!scan) continue;
        const double t = mrpt::Clock::toDouble(scan->timestamp);
        // Only where odometry covers the whole sweep: no extrapolation.
        const auto first = odometry.at(t), last = odometry.at(t + sweep_s);
        if (!first || !last) continue;
        deskewScan(*scan, last->pose - first->pose);
        ++corrected;
    }
    return corrected;
}

}  // namespace lookup::survey

#pragma once
// Lidar and odometry drives through a bent, rough-walled lookup-sim tunnel, for the tests of
// the survey's laser stage.

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <cmath>
#include <memory>
#include <string>

#include "../sim/test_worlds.h"
#include "lookup/common/pose_files.h"
#include "lookup/sim/simulator.h"
#include "lookup/sim/world.h"
#include "lookup/survey/traverse.h"

namespace lookup::test {

/// A `length_m` tunnel with 8 deg bends, rough walls and niches as in the presets, no furniture.
inline lookup::sim::WorldOptions bentTunnel(double length_m = 160) {
    lookup::sim::WorldOptions w = lookup::sim::testing::straightTunnel(false);
    const lookup::sim::WorldOptions preset;
    w.length_m = length_m;
    w.segment_length_m = 40;
    w.bend_max_deg = 8;
    w.wall_roughness_m = preset.wall_roughness_m;
    w.niche_spacing_m = preset.niche_spacing_m;
    return w;
}

struct Drive {
    survey::TraverseData data;
    common::PoseTrack truth;     ///< vehicle pose at each scan
    common::PoseTrack odometry;  ///< dead reckoning at each scan, from the true start
};

/// The vehicle `lateral_m` from the centre line at fractional route index `at`, heading along it.
inline mrpt::poses::CPose2D routePose(const lookup::sim::TunnelWorld& world, double at,
                                      double lateral_m) {
    const auto& route = world.route();
    const auto i = std::size_t(at);
    const double f = at - double(i);
    const Eigen::Vector2d dir = (route[i + 1] - route[i - 1]).normalized();
    const Eigen::Vector2d p =
        (1 - f) * route[i] + f * route[i + 1] + lateral_m * Eigen::Vector2d(-dir.y(), dir.x());
    return mrpt::poses::CPose2D(p.x(), p.y(), std::atan2(dir.y(), dir.x()));
}

/// A drive along the route at `lateral_m` from the centre line at 5 m/s, a scan and an odometry
/// reading every 0.1 s, with wheel odometry that is 1 % long and turns 0.05 deg per metre too
/// far. Each scan's rays are taken over `sweep_s` from its stamp on (scan skew; 0: at once).
inline Drive drive(const lookup::sim::TunnelWorld& world, double lateral_m, double t0,
                   uint32_t seed, double sweep_s = 0) {
    Drive d;
    d.data.rawlog = "synthetic-" + std::to_string(seed);
    const auto& route = world.route();
    const double step_m = 0.5, period_s = 0.1;
    const std::size_t stride = std::size_t(step_m / 0.25);
    lookup::sim::LidarOptions lidar;
    mrpt::poses::CPose2D odometry, previous_truth;
    for (std::size_t i = 8, n = 0; i + 8 < route.size(); i += stride, ++n) {
        const mrpt::poses::CPose2D truth = routePose(world, double(i), lateral_m);
        if (n == 0) {
            odometry = truth;
        } else {
            mrpt::poses::CPose2D inc = truth - previous_truth;
            inc = mrpt::poses::CPose2D(inc.x() * 1.01, inc.y() * 1.01,
                                       inc.phi() + mrpt::DEG2RAD(0.05) * step_m);
            odometry = odometry + inc;
        }
        previous_truth = truth;
        const double t = t0 + period_s * double(n);
        auto odo = std::make_shared<mrpt::obs::CObservationOdometry>();
        odo->odometry = odometry;
        odo->timestamp = mrpt::Clock::fromDouble(t);
        odo->sensorLabel = "ODOMETRY";
        const mrpt::poses::CPose2D at_end =
            routePose(world, double(i) + double(stride) * sweep_s / period_s, lateral_m);
        auto scan = std::make_shared<mrpt::obs::CObservation2DRangeScan>(lookup::sim::simulateLidar(
            world, truth, lidar, seed * 100000 + uint32_t(n), sweep_s > 0 ? &at_end : nullptr));
        scan->timestamp = mrpt::Clock::fromDouble(t);
        d.data.laser_sequence.push_back(odo);
        d.data.laser_sequence.push_back(scan);
        d.truth.push_back({t, mrpt::poses::CPose3D(truth)});
        d.odometry.push_back({t, mrpt::poses::CPose3D(odometry)});
    }
    d.data.scan_count = d.data.odometry_count = d.truth.size();
    return d;
}

}  // namespace lookup::test

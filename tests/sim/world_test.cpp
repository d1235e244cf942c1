// Tunnel geometry and the lidar simulated against its occupancy grid.

#include "test_worlds.h"

#include <gtest/gtest.h>
#include <lookup/sim/simulator.h>
#include <lookup/sim/world.h>
#include <mrpt/core/bits_math.h>

#include <cmath>

namespace {

using lookup::sim::TunnelWorld;
using lookup::sim::testing::straightTunnel;

TEST(World, SignedDistanceAndRoofOfAStraightTunnel) {
    const auto opt = straightTunnel(true);
    const TunnelWorld world(opt, 1);
    const double hw = opt.width_m / 2;
    EXPECT_NEAR(world.query(20, 0).sdf, -hw, 1e-9);
    EXPECT_NEAR(world.query(20, 1.0).sdf, -(hw - 1.0), 1e-9);
    EXPECT_NEAR(world.query(20, -hw - 0.5).sdf, 0.5, 1e-9);
    EXPECT_NEAR(world.query(20, 1.0).d, 1.0, 1e-9);
    // Flat ceiling in the middle, arch spring at the wall.
    EXPECT_NEAR(world.roofHeight(20, 0, hw), opt.ceiling_height_m, 1e-9);
    EXPECT_NEAR(world.roofHeight(20, hw, 0.0), opt.ceiling_height_m - opt.arch_radius_m, 1e-9);
    EXPECT_NEAR(world.routeLength(), opt.length_m, 0.5);
}

TEST(World, ShorterWorldIsTheSameWorldCutShort) {
    auto opt = straightTunnel(false);
    opt.bend_max_deg = 10;
    opt.segment_length_m = 20;
    opt.length_m = 200;
    const TunnelWorld full(opt, 7);
    opt.length_m = 60;
    const TunnelWorld mini(opt, 7);
    for (std::size_t i = 0; i + 40 < mini.route().size(); i += 10) {  // away from the cut end
        EXPECT_NEAR((mini.route()[i] - full.route()[i]).norm(), 0.0, 1e-6) << i;
    }
}

TEST(World, LidarRangesAgreeWithTheAnalyticWalls) {
    const auto opt = straightTunnel(true);
    const TunnelWorld world(opt, 1);
    mrpt::maps::COccupancyGridMap2D grid;
    world.fillGridMap(grid);
    lookup::sim::LidarOptions lidar;
    lidar.noise_std_m = 0;
    const double hw = opt.width_m / 2;
    for (const double yaw : {0.0, 0.3, -0.25}) {
        const mrpt::poses::CPose2D vehicle(18.0, 0.6, yaw);
        const auto scan = lookup::sim::simulateLidar(grid, vehicle, lidar, 1);
        ASSERT_EQ(scan.getScanSize(), 541u);
        const mrpt::poses::CPose2D sensor = vehicle + mrpt::poses::CPose2D(lidar.mount.pose());
        int checked = 0;
        for (std::size_t i = 0; i < scan.getScanSize(); ++i) {
            const double a =
                sensor.phi() - scan.aperture / 2 + i * scan.aperture / (scan.getScanSize() - 1);
            const double s = std::sin(a);
            if (std::abs(s) < 0.3) continue;  // rays along the tunnel end far away
            const double expected = s > 0 ? (hw - sensor.y()) / s : (hw + sensor.y()) / -s;
            if (expected > 12) continue;
            ASSERT_TRUE(scan.getScanRangeValidity(i)) << "ray " << i;
            EXPECT_NEAR(scan.getScanRange(i), expected, 0.08) << "yaw " << yaw << " ray " << i;
            ++checked;
        }
        EXPECT_GT(checked, 200);
    }
}

TEST(World, LidarDegeneratesAlongAStraightTunnel) {
    // Two scans 1 m apart along the tunnel are the same away from the tunnel ends: the
    // along-tunnel position is unobservable, as for real lidar in a long drive.
    const auto opt = straightTunnel(true);
    const TunnelWorld world(opt, 1);
    mrpt::maps::COccupancyGridMap2D grid;
    world.fillGridMap(grid);
    lookup::sim::LidarOptions lidar;
    lidar.noise_std_m = 0;
    lidar.max_range_m = 8;
    const auto a = lookup::sim::simulateLidar(grid, mrpt::poses::CPose2D(17, 0.2, 0), lidar, 1);
    const auto b = lookup::sim::simulateLidar(grid, mrpt::poses::CPose2D(18, 0.2, 0), lidar, 1);
    int same = 0, valid = 0;
    for (std::size_t i = 0; i < a.getScanSize(); ++i) {
        if (!a.getScanRangeValidity(i) || !b.getScanRangeValidity(i)) continue;
        ++valid;
        same += std::abs(a.getScanRange(i) - b.getScanRange(i)) < 0.06;
    }
    EXPECT_GT(valid, 100);
    EXPECT_GT(same, 0.95 * valid);
}

}  // namespace

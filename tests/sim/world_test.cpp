// Tunnel geometry and the lidar traced against its rock surface.

#include "test_worlds.h"

#include <gtest/gtest.h>
#include <lookup/sim/simulator.h>
#include <lookup/sim/world.h>
#include <mrpt/core/bits_math.h>

#include <cmath>
#include <utility>

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
    lookup::sim::LidarOptions lidar;
    lidar.noise_std_m = 0;
    const double hw = opt.width_m / 2;
    for (const double yaw : {0.0, 0.3, -0.25}) {
        const mrpt::poses::CPose2D vehicle(18.0, 0.6, yaw);
        const auto scan = lookup::sim::simulateLidar(world, vehicle, lidar, 1);
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
            EXPECT_NEAR(scan.getScanRange(i), expected, 0.005) << "yaw " << yaw << " ray " << i;
            ++checked;
        }
        EXPECT_GT(checked, 200);
    }
}

// Noise-free scans at x = 17 m and 18 m, 0.2 m off the centre line: {valid rays, rays whose
// range changed by less than 6 cm}.
std::pair<int, int> rangesUnchangedOneMetreOn(const TunnelWorld& world) {
    lookup::sim::LidarOptions lidar;
    lidar.noise_std_m = 0;
    lidar.max_range_m = 8;
    const auto a = lookup::sim::simulateLidar(world, mrpt::poses::CPose2D(17, 0.2, 0), lidar, 1);
    const auto b = lookup::sim::simulateLidar(world, mrpt::poses::CPose2D(18, 0.2, 0), lidar, 1);
    int same = 0, valid = 0;
    for (std::size_t i = 0; i < a.getScanSize(); ++i) {
        if (!a.getScanRangeValidity(i) || !b.getScanRangeValidity(i)) continue;
        ++valid;
        same += std::abs(a.getScanRange(i) - b.getScanRange(i)) < 0.06;
    }
    return {valid, same};
}

TEST(World, LidarDegeneratesAlongAStraightTunnel) {
    // Two scans 1 m apart along the tunnel are the same away from the tunnel ends: the
    // along-tunnel position is unobservable, as for real lidar in a long drive.
    const auto opt = straightTunnel(true);
    const TunnelWorld world(opt, 1);
    const auto [valid, same] = rangesUnchangedOneMetreOn(world);
    EXPECT_GT(valid, 100);
    EXPECT_GT(same, 0.95 * valid);
}

}  // namespace

namespace {

// Ranges of the rays perpendicular-ish to the left wall, as the vehicle drives along the tunnel:
// the wall's lateral position seen by the lidar at each step.
std::vector<double> leftWallOffsets(const TunnelWorld& world) {
    lookup::sim::LidarOptions lidar;
    lidar.noise_std_m = 0;
    lidar.max_range_m = 8;
    std::vector<double> out;
    for (double x = 8; x <= 32; x += 0.25) {
        const auto scan =
            lookup::sim::simulateLidar(world, mrpt::poses::CPose2D(x, 0, 0), lidar, 1);
        const std::size_t mid = scan.getScanSize() / 2 + 180;  // +90 deg: straight to the left
        EXPECT_TRUE(scan.getScanRangeValidity(mid));
        out.push_back(scan.getScanRange(mid) + lidar.mount.y_m);
    }
    return out;
}

}  // namespace

TEST(World, ZeroRoughnessGivesStraightWalls) {
    const auto opt = straightTunnel(true);  // wall_roughness_m = 0
    const TunnelWorld world(opt, 1);
    for (const double y : leftWallOffsets(world)) EXPECT_NEAR(y, opt.width_m / 2, 0.005);
}

TEST(World, RoughWallsVaryByAboutTheConfiguredRoughness) {
    auto opt = straightTunnel(true);
    opt.wall_roughness_m = 0.2;
    const TunnelWorld world(opt, 1);
    const auto wall = leftWallOffsets(world);
    double lo = 1e9, hi = -1e9, mean = 0, var = 0;
    for (const double y : wall) {
        lo = std::min(lo, y);
        hi = std::max(hi, y);
        mean += y / wall.size();
    }
    for (const double y : wall) var += (y - mean) * (y - mean) / wall.size();
    // Within +-roughness of the nominal wall (plus a grid cell), and really rough: the relief
    // spans a good part of that band with a standard deviation of several centimetres.
    EXPECT_GT(lo, opt.width_m / 2 - opt.wall_roughness_m - 0.06);
    EXPECT_LT(hi, opt.width_m / 2 + opt.wall_roughness_m + 0.06);
    EXPECT_GT(hi - lo, opt.wall_roughness_m);
    EXPECT_GT(std::sqrt(var), 0.25 * opt.wall_roughness_m);
    // A pure function of the seed: the same rock again, other rock with another seed.
    EXPECT_EQ(wall, leftWallOffsets(TunnelWorld(opt, 1)));
    EXPECT_NE(wall, leftWallOffsets(TunnelWorld(opt, 2)));
}

TEST(World, RoughWallsMakeTheLidarObservableAlongTheTunnel) {
    // The converse of LidarDegeneratesAlongAStraightTunnel: with the default relief two scans
    // 1 m apart differ along the walls, so scan matching can tell where along the drive it is.
    auto opt = straightTunnel(true);
    opt.wall_roughness_m = lookup::sim::WorldOptions().wall_roughness_m;
    const TunnelWorld world(opt, 1);
    const auto [valid, same] = rangesUnchangedOneMetreOn(world);
    EXPECT_GT(valid, 100);
    EXPECT_LT(same, 0.6 * valid);
}

TEST(World, NichesAreCutIntoTheWalls) {
    auto opt = straightTunnel(true);
    opt.length_m = 120;
    opt.niche_spacing_m = 20;
    const TunnelWorld world(opt, 3);
    // Every piece beyond the main line is a niche: its mouth on a wall, its back
    // niche_depth_m behind it.
    int niches = 0;
    for (const auto& s : world.segments()) {
        if (s.on_route) continue;
        ++niches;
        const double back = std::abs(s.b.y()) + s.half_width;
        EXPECT_NEAR(back, opt.width_m / 2 + opt.niche_depth_m, 1e-9);
        EXPECT_NEAR(s.half_width, opt.niche_width_m / 2, 1e-9);
        // Free rock-side space at the back of the niche, rock beyond it.
        const double side = s.b.y() > 0 ? 1 : -1;
        EXPECT_LT(world.query(s.b.x(), side * (opt.width_m / 2 + opt.niche_depth_m - 0.2)).sdf, 0);
        EXPECT_GT(world.query(s.b.x(), side * (opt.width_m / 2 + opt.niche_depth_m + 0.2)).sdf, 0);
    }
    EXPECT_GE(niches, 3);
    EXPECT_LE(niches, 8);
}

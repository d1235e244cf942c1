// The ceiling camera's time offset against the odometry, estimated from how the fixes' heading
// follows the odometry's through a weave: found and (on request) applied when the camera is
// late, left at zero when it is on time or the drive is straight.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lookup/localize/camera_clock.h"

using lookup::common::OdometryTrack;
using lookup::localize::CameraClock;

namespace {

constexpr double kT0 = 1000.0;
constexpr double kOdometryHz = 50, kCameraHz = 14, kDuration_s = 25;

/// A vehicle weaving at `weave_rad` heading amplitude with a 5 s period (a 40 m zigzag at
/// 28 km/h), its odometry heading drifting slowly; fixes of the camera stamped `late_s` after
/// their exposure, their heading off by a constant and by noise.
CameraClock drive(double weave_rad, double late_s, unsigned seed = 7, bool apply = true) {
    const auto yaw = [weave_rad](double t) {
        return weave_rad * std::sin(2 * M_PI * (t - kT0) / 5.0);
    };
    std::mt19937 rng(seed);
    std::normal_distribution<double> fix_noise(0, 0.0015), odo_noise(0, 0.0003);
    OdometryTrack odometry;
    lookup::localize::CameraClockOptions options;
    options.apply = apply;
    CameraClock clock(options);
    double odo_walk = 0, next_frame = kT0 + 0.5;
    for (double t = kT0; t < kT0 + kDuration_s; t += 1 / kOdometryHz) {
        odo_walk += odo_noise(rng);
        odometry.add(t, mrpt::poses::CPose2D(0, 0, yaw(t) + 0.0004 * (t - kT0) + odo_walk));
        if (t < next_frame) continue;
        clock.update(odometry);
        const double exposure = next_frame - late_s;
        clock.addFix(next_frame, 0.3 + yaw(exposure) + fix_noise(rng));
        next_frame += 1 / kCameraHz;
    }
    clock.update(odometry);
    return clock;
}

}  // namespace

TEST(CameraClock, ALateCameraIsFoundFromAWeaveAndApplied) {
    const CameraClock clock = drive(0.19, 0.020);
    ASSERT_TRUE(clock.estimate());
    EXPECT_GT(clock.estimate()->pairs, 200u);
    EXPECT_NEAR(clock.estimate()->offset_s, -0.020, 3 * clock.estimate()->sigma_s);
    EXPECT_LT(clock.estimate()->sigma_s, 0.003);
    EXPECT_TRUE(clock.isApplied());
    EXPECT_NEAR(clock.applied(), -0.020, 0.006);
    // Without `apply` the same drive is estimated and reported, the stamps left as they are.
    const CameraClock reported = drive(0.19, 0.020, 7, false);
    ASSERT_TRUE(reported.estimate());
    EXPECT_DOUBLE_EQ(reported.estimate()->offset_s, clock.estimate()->offset_s);
    EXPECT_FALSE(reported.isApplied());
    EXPECT_EQ(reported.applied(), 0.0);
}

TEST(CameraClock, ACameraOnTimeIsLeftAlone) {
    for (unsigned seed : {1u, 2u, 3u}) {
        const CameraClock clock = drive(0.19, 0.0, seed);
        ASSERT_TRUE(clock.estimate());
        EXPECT_NEAR(clock.estimate()->offset_s, 0.0, 0.006);
        EXPECT_FALSE(clock.isApplied()) << "seed " << seed;
        EXPECT_EQ(clock.applied(), 0.0);
    }
}

TEST(CameraClock, AStraightDriveShowsNothing) {
    // No change of yaw rate: the offset is not observable, whatever the camera's lateness.
    const CameraClock clock = drive(0.0, 0.040);
    EXPECT_FALSE(clock.isApplied());
    EXPECT_EQ(clock.applied(), 0.0);
}

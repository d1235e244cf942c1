// A survey on a grade: with the inclinometer's pitch and roll, odometry steps and lidar scans
// must come out as plan motion and plan distances to the (vertical) walls.
#include <gtest/gtest.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/datetime.h>

#include <cmath>
#include <limits>
#include <memory>

#include "lookup/survey/levelling.h"
#include "lookup/survey/traverse.h"
#include "room_scans.h"

namespace {

using lookup::survey::Attitude;
using lookup::survey::AttitudeTrack;
using lookup::test::meanWallDistance;
using mrpt::obs::CObservation2DRangeScan;
using mrpt::obs::CObservationOdometry;
using mrpt::poses::CPose2D;
using mrpt::poses::CPose3D;

const double kPitch = std::atan(1.0 / 7);  // a 1:7 decline, nose down
const double kT0 = 1700000000.0;

// A room of vertical walls at x = +-15 m, y = +-4 m: the distance along a 3-D ray from
// (x, y) with direction d to them.
double rangeToWalls(double x, double y, const mrpt::math::TPoint3D& d) {
    double t = std::numeric_limits<double>::infinity();
    if (d.x > 1e-9) t = std::min(t, (15 - x) / d.x);
    if (d.x < -1e-9) t = std::min(t, (-15 - x) / d.x);
    if (d.y > 1e-9) t = std::min(t, (4 - y) / d.y);
    if (d.y < -1e-9) t = std::min(t, (-4 - y) / d.y);
    return t;
}

// A 270° scan from a scanner 1.2 m up on a vehicle at the origin tilted by `a`.
CObservation2DRangeScan tiltedScan(const Attitude& a) {
    CObservation2DRangeScan scan;
    scan.aperture = float(M_PI * 1.5);
    scan.rightToLeft = true;
    scan.maxRange = 40.0f;
    scan.sensorPose = CPose3D(1.9, 0.1, 1.2, 0.05, 0, 0);
    scan.resizeScan(541);
    const CPose3D sensor = CPose3D(0, 0, 0, 0, a.pitch, a.roll) + scan.sensorPose;
    for (std::size_t i = 0; i < scan.getScanSize(); ++i) {
        const double b = scan.getScanAngle(i);
        mrpt::math::TPoint3D tip;
        sensor.composePoint(std::cos(b), std::sin(b), 0, tip.x, tip.y, tip.z);
        const mrpt::math::TPoint3D d(tip.x - sensor.x(), tip.y - sensor.y(), tip.z - sensor.z());
        scan.setScanRange(i, float(rangeToWalls(sensor.x(), sensor.y(), d)));
        scan.setScanRangeValidity(i, true);
    }
    return scan;
}

AttitudeTrack constantAttitude(const Attitude& a, double from_s, double to_s) {
    AttitudeTrack track;
    for (double t = from_s; t <= to_s + 1e-9; t += 0.02) track.add(t, a);
    return track;
}

TEST(Levelling, AttitudeIsInterpolatedAndNotBridgedAcrossGaps) {
    AttitudeTrack track;
    EXPECT_TRUE(track.add(10.0, {0.0, 0.1}));
    EXPECT_TRUE(track.add(10.1, {0.2, 0.3}));
    EXPECT_FALSE(track.add(10.1, {0.5, 0.5}));  // not later
    EXPECT_TRUE(track.add(15.0, {0.4, 0.4}));
    const auto mid = track.at(10.05, 1.0);
    ASSERT_TRUE(mid);
    EXPECT_NEAR(mid->pitch, 0.1, 1e-9);
    EXPECT_NEAR(mid->roll, 0.2, 1e-9);
    EXPECT_FALSE(track.at(12.0, 1.0));  // 4.9 s between readings
    EXPECT_FALSE(track.at(9.9, 1.0));
    EXPECT_FALSE(track.at(15.1, 1.0));
    EXPECT_NEAR(track.maxAbsPitch(), 0.4, 1e-12);
}

TEST(Levelling, ATiltedScanShowsThePlanDistancesToTheWalls) {
    const Attitude a{kPitch, 0.03};
    auto scan = CObservation2DRangeScan::Create(tiltedScan(a));
    scan->timestamp = mrpt::Clock::fromDouble(kT0 + 0.5);
    const double tilted = meanWallDistance(*scan);
    EXPECT_GT(tilted, 0.02);  // the end walls look farther in the tilted plane
    lookup::survey::TraverseData traverse;
    traverse.laser_sequence.push_back(scan);
    const auto rep =
        lookup::survey::levelTraverse(traverse, constantAttitude(a, kT0, kT0 + 1), 1.0, 0.3, 1.0);
    EXPECT_EQ(rep.scans_levelled, 1u);
    EXPECT_LT(meanWallDistance(*scan), 0.01) << "before " << tilted;
}

TEST(Levelling, OdometryOnTheRampBecomesPlanMotion) {
    lookup::survey::TraverseData traverse;
    for (int k = 0; k <= 100; ++k) {  // 5 m/s along the slope, 50 Hz, turning slowly
        auto odo = CObservationOdometry::Create();
        odo->timestamp = mrpt::Clock::fromDouble(kT0 + 0.02 * k);
        odo->odometry = CPose2D(0.1 * k, 0, 0);
        odo->hasVelocities = true;
        odo->velocityLocal.vx = 5;
        traverse.laser_sequence.push_back(odo);
    }
    // The inclinometer covers the first second only: the rest stays as recorded.
    const auto rep = lookup::survey::levelTraverse(
        traverse, constantAttitude({kPitch, 0}, kT0, kT0 + 1.0), 1.0, 0.3, 1.0);
    EXPECT_EQ(rep.odometry_levelled, 50u);
    EXPECT_NEAR(rep.max_pitch_deg, mrpt::RAD2DEG(kPitch), 1e-9);
    EXPECT_NEAR(rep.odometry_m, 10.0, 1e-9);
    EXPECT_NEAR(rep.levelled_m, 5.0 * std::cos(kPitch) + 5.0, 1e-6);
    const auto at = [&](int k) {
        return std::dynamic_pointer_cast<CObservationOdometry>(traverse.laser_sequence[k]);
    };
    EXPECT_NEAR(at(50)->odometry.x(), 5.0 * std::cos(kPitch), 1e-6);
    EXPECT_NEAR(at(100)->odometry.x(), 5.0 * std::cos(kPitch) + 5.0, 1e-6);
    EXPECT_NEAR(at(10)->velocityLocal.vx, 5 * std::cos(kPitch), 1e-9);
    EXPECT_NEAR(at(90)->velocityLocal.vx, 5, 1e-9);
}

// A drive over a ramp of `pitch` (positive: descending) that ends at plan s = 10 m, in a
// tunnel 8 m wide with its roof 3 m above the floor; one scan at s = 8 m, still on the ramp.
struct GradeChange {
    lookup::survey::TraverseData traverse;
    AttitudeTrack attitude;
    std::shared_ptr<CObservation2DRangeScan> scan;
};

GradeChange driveOverGradeChange(double pitch) {
    const double tan_g = std::tan(pitch), step = 0.1;  // slope distance per record [m]
    const auto floorAt = [&](double s) { return -std::min(s, 10.0) * tan_g; };  // plan s
    GradeChange g;
    double s = 0;
    for (int k = 0; k <= 400; ++k) {  // to s = 40 m: the floor beyond every return is known
        const double t = kT0 + 0.02 * k;
        const bool on_ramp = s < 10;
        g.attitude.add(t, {on_ramp ? pitch : 0.0, 0.0});
        auto odo = CObservationOdometry::Create();
        odo->timestamp = mrpt::Clock::fromDouble(t);
        odo->odometry = CPose2D(step * k, 0, 0);
        g.traverse.laser_sequence.push_back(odo);
        if (k == 81) {  // plan s = 8.0 m
            g.scan = CObservation2DRangeScan::Create();
            g.scan->aperture = float(M_PI * 1.5);
            g.scan->rightToLeft = true;
            g.scan->maxRange = 40.0f;
            g.scan->sensorPose = CPose3D(1.9, 0, 1.2, 0, 0, 0);
            g.scan->resizeScan(541);
            g.scan->timestamp = mrpt::Clock::fromDouble(t);
            const CPose3D sensor = CPose3D(s, 0, floorAt(s), 0, pitch, 0) + g.scan->sensorPose;
            for (std::size_t i = 0; i < g.scan->getScanSize(); ++i) {
                const double b = g.scan->getScanAngle(i);
                double x, y, z;
                float range = 0;
                for (double r = 0.05; r < 39.9 && range == 0; r += 0.01) {
                    sensor.composePoint(r * std::cos(b), r * std::sin(b), 0, x, y, z);
                    const bool outside = z < floorAt(x) || z > floorAt(x) + 3;
                    if (std::abs(y) > 4 || outside || std::abs(x) > 60) range = float(r);
                }
                g.scan->setScanRange(i, range);
                g.scan->setScanRangeValidity(i, range > 0);
            }
            g.traverse.laser_sequence.push_back(g.scan);
        }
        s += step * std::cos(on_ramp ? pitch : 0.0);
    }
    return g;
}

constexpr std::size_t kAhead = 270, kLeft = 450;  // rays at 0 and +90 deg

// 2 m before the foot of a 1:7 decline, still nose down: the scan ahead meets the level floor
// beyond the foot; the returns from the side walls stay.
TEST(Levelling, ReturnsFromTheFloorAtTheFootOfADeclineAreDropped) {
    GradeChange g = driveOverGradeChange(kPitch);
    ASSERT_GT(g.scan->getScanRange(kAhead), 5.0f);  // the floor, beyond the foot
    ASSERT_LT(g.scan->getScanRange(kAhead), 12.0f);
    const auto rep = lookup::survey::levelTraverse(g.traverse, g.attitude, 1.0, 0.3, 1.0);
    EXPECT_GT(rep.floor_returns, 5u);
    EXPECT_LT(rep.floor_returns, 200u);  // the side walls stay
    EXPECT_EQ(rep.roof_returns, 0u);
    EXPECT_FALSE(g.scan->getScanRangeValidity(kAhead));
    EXPECT_TRUE(g.scan->getScanRangeValidity(kLeft));
    // Margins 0: nothing dropped, the floor drawn as a wall ahead.
    GradeChange kept = driveOverGradeChange(kPitch);
    const auto none = lookup::survey::levelTraverse(kept.traverse, kept.attitude, 1.0, 0.0, 0.0);
    EXPECT_EQ(none.floor_returns + none.roof_returns, 0u);
    EXPECT_TRUE(kept.scan->getScanRangeValidity(kAhead));
}

// 2 m before the top of a 1:7 incline, still nose up: the scan ahead meets the level roof past
// the crest.
TEST(Levelling, ReturnsFromTheRoofPastTheCrestOfAnInclineAreDropped) {
    GradeChange g = driveOverGradeChange(-kPitch);
    ASSERT_GT(g.scan->getScanRange(kAhead), 8.0f);  // the roof, past the crest
    ASSERT_LT(g.scan->getScanRange(kAhead), 25.0f);
    const auto rep = lookup::survey::levelTraverse(g.traverse, g.attitude, 1.0, 0.3, 1.0);
    EXPECT_GT(rep.roof_returns, 5u);
    EXPECT_LT(rep.roof_returns, 200u);
    EXPECT_FALSE(g.scan->getScanRangeValidity(kAhead));
    EXPECT_TRUE(g.scan->getScanRangeValidity(kLeft));
}

TEST(Levelling, WithoutAnInclinometerNothingChanges) {
    lookup::survey::TraverseData traverse;
    auto scan = CObservation2DRangeScan::Create(tiltedScan({kPitch, 0}));
    scan->timestamp = mrpt::Clock::fromDouble(kT0);
    traverse.laser_sequence.push_back(scan);
    const float before = scan->getScanRange(270);
    const auto rep = lookup::survey::levelTraverse(traverse, AttitudeTrack(), 1.0, 0.3, 1.0);
    EXPECT_EQ(rep.imu_records, 0u);
    EXPECT_EQ(rep.scans_levelled, 0u);
    EXPECT_EQ(scan->getScanRange(270), before);
}

}  // namespace

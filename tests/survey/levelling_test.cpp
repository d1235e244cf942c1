// A survey on a grade: with the inclinometer's pitch and roll, odometry steps and lidar scans
// must come out as plan motion and plan distances to the (vertical) walls.
#include <gtest/gtest.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/datetime.h>

#include <cmath>
#include <limits>

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
        lookup::survey::levelTraverse(traverse, constantAttitude(a, kT0, kT0 + 1), 1.0, 0.3);
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
        traverse, constantAttitude({kPitch, 0}, kT0, kT0 + 1.0), 1.0, 0.3);
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

// A vehicle 2 m before the foot of a 1:7 decline, still nose down: its scan ahead meets the
// level floor beyond the foot; the returns from the side walls stay.
TEST(Levelling, ReturnsFromTheFloorAtTheFootOfADeclineAreDropped) {
    const double tan_g = std::tan(kPitch), step = 0.1;  // slope distance per record [m]
    const auto floorAt = [&](double s) { return -std::min(s, 10.0) * tan_g; };  // plan s
    lookup::survey::TraverseData traverse;
    AttitudeTrack attitude;
    double s = 0;
    std::size_t scan_record = 0;
    for (int k = 0; k <= 200; ++k) {
        const double t = kT0 + 0.02 * k;
        const bool on_ramp = s < 10;
        attitude.add(t, {on_ramp ? kPitch : 0.0, 0.0});
        auto odo = CObservationOdometry::Create();
        odo->timestamp = mrpt::Clock::fromDouble(t);
        odo->odometry = CPose2D(step * k, 0, 0);
        traverse.laser_sequence.push_back(odo);
        if (k == 81) {  // plan s = 8.0 m
            auto scan = CObservation2DRangeScan::Create();
            scan->aperture = float(M_PI * 1.5);
            scan->rightToLeft = true;
            scan->maxRange = 40.0f;
            scan->sensorPose = CPose3D(1.9, 0, 1.2, 0, 0, 0);
            scan->resizeScan(541);
            scan->timestamp = mrpt::Clock::fromDouble(t);
            const CPose3D sensor = CPose3D(s, 0, floorAt(s), 0, kPitch, 0) + scan->sensorPose;
            for (std::size_t i = 0; i < scan->getScanSize(); ++i) {
                const double b = scan->getScanAngle(i);
                double x, y, z;
                float range = 0;
                for (double r = 0.05; r < 39.9 && range == 0; r += 0.01) {
                    sensor.composePoint(r * std::cos(b), r * std::sin(b), 0, x, y, z);
                    if (std::abs(y) > 4 || z < floorAt(x) || std::abs(x) > 60) range = float(r);
                }
                scan->setScanRange(i, range);
                scan->setScanRangeValidity(i, range > 0);
            }
            traverse.laser_sequence.push_back(scan);
            scan_record = traverse.laser_sequence.size() - 1;
        }
        s += step * std::cos(on_ramp ? kPitch : 0.0);
    }
    auto copy = traverse;  // its own odometry records: levelling rewrites them in place
    for (auto& o : copy.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<CObservationOdometry>(o)) {
            o = CObservationOdometry::Create(*odo);
        }
    }
    auto scan =
        std::dynamic_pointer_cast<CObservation2DRangeScan>(traverse.laser_sequence[scan_record]);
    copy.laser_sequence[scan_record] = CObservation2DRangeScan::Create(*scan);
    const std::size_t ahead = 270, left = 450;
    ASSERT_GT(scan->getScanRange(ahead), 5.0f);  // the floor, beyond the foot
    ASSERT_LT(scan->getScanRange(ahead), 12.0f);
    const auto rep = lookup::survey::levelTraverse(traverse, attitude, 1.0, 0.3);
    EXPECT_GT(rep.floor_returns, 5u);
    EXPECT_LT(rep.floor_returns, 200u);  // the side walls stay
    EXPECT_FALSE(scan->getScanRangeValidity(ahead));
    EXPECT_TRUE(scan->getScanRangeValidity(left));
    // Margin 0: nothing dropped, the floor drawn as a wall ahead.
    const auto kept = lookup::survey::levelTraverse(copy, attitude, 1.0, 0.0);
    EXPECT_EQ(kept.floor_returns, 0u);
    EXPECT_TRUE(std::dynamic_pointer_cast<CObservation2DRangeScan>(copy.laser_sequence[scan_record])
                    ->getScanRangeValidity(ahead));
}

TEST(Levelling, WithoutAnInclinometerNothingChanges) {
    lookup::survey::TraverseData traverse;
    auto scan = CObservation2DRangeScan::Create(tiltedScan({kPitch, 0}));
    scan->timestamp = mrpt::Clock::fromDouble(kT0);
    traverse.laser_sequence.push_back(scan);
    const float before = scan->getScanRange(270);
    const auto rep = lookup::survey::levelTraverse(traverse, AttitudeTrack(), 1.0, 0.3);
    EXPECT_EQ(rep.imu_records, 0u);
    EXPECT_EQ(rep.scans_levelled, 0u);
    EXPECT_EQ(scan->getScanRange(270), before);
}

}  // namespace

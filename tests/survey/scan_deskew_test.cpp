// De-skewing a scan taken while the vehicle moves: the redrawn scan must match the scan an
// instantaneous sweep would have taken from the first ray's pose.
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/datetime.h>

#include <cmath>
#include <limits>

#include "lookup/survey/scan_deskew.h"
#include "room_scans.h"

namespace {

using lookup::test::meanWallDistance;

using lookup::survey::deskewScan;
using mrpt::obs::CObservation2DRangeScan;
using mrpt::poses::CPose2D;

// A closed room 30 m x 8 m around the origin: the distance along a ray to its walls.
double rangeToWalls(double x, double y, double angle) {
    const double dx = std::cos(angle), dy = std::sin(angle);
    double t = std::numeric_limits<double>::infinity();
    if (dx > 1e-9) t = std::min(t, (15 - x) / dx);
    if (dx < -1e-9) t = std::min(t, (-15 - x) / dx);
    if (dy > 1e-9) t = std::min(t, (4 - y) / dy);
    if (dy < -1e-9) t = std::min(t, (-4 - y) / dy);
    return t;
}

// A 270° right-to-left scan whose ray i is taken at vehicle pose start ⊕ (i/(n-1))·motion.
CObservation2DRangeScan sweep(const CPose2D& start, const CPose2D& motion) {
    CObservation2DRangeScan scan;
    scan.aperture = float(M_PI * 1.5);
    scan.rightToLeft = true;
    scan.maxRange = 40.0f;
    scan.sensorPose = mrpt::poses::CPose3D(0.5, 0.1, 1.0, 0.05, 0, 0);
    scan.resizeScan(541);
    const std::size_t n = scan.getScanSize();
    for (std::size_t i = 0; i < n; ++i) {
        const double a = i / double(n - 1);
        const CPose2D vehicle = start + CPose2D(a * motion.x(), a * motion.y(), a * motion.phi());
        const CPose2D sensor = vehicle + CPose2D(scan.sensorPose);
        const double angle = sensor.phi() + scan.getScanAngle(i);
        scan.setScanRange(i, float(rangeToWalls(sensor.x(), sensor.y(), angle)));
        scan.setScanRangeValidity(i, true);
    }
    return scan;
}

TEST(ScanDeskew, RedrawsAMovingSweepAsSeenFromItsFirstRay) {
    const CPose2D start(-3.0, 0.5, 0.2);
    const CPose2D motion(0.4, 0.02, mrpt::DEG2RAD(4.0));  // 5 m/s and a bend over 75 ms
    CObservation2DRangeScan scan = sweep(start, motion);
    const double skewed = meanWallDistance(scan, start);
    deskewScan(scan, motion);
    const double deskewed = meanWallDistance(scan, start);
    EXPECT_GT(skewed, 0.08);
    EXPECT_LT(deskewed, 0.002) << "skewed " << skewed;
    std::size_t valid = 0;
    for (std::size_t i = 0; i < scan.getScanSize(); ++i) valid += scan.getScanRangeValidity(i);
    EXPECT_GT(valid, scan.getScanSize() * 9 / 10);
}

TEST(ScanDeskew, AStillVehicleLeavesTheScanAsItWas) {
    const CPose2D start(1.0, -1.0, -0.3);
    CObservation2DRangeScan scan = sweep(start, CPose2D());
    const CObservation2DRangeScan before = scan;
    deskewScan(scan, CPose2D());
    for (std::size_t i = 0; i < scan.getScanSize(); ++i) {
        ASSERT_EQ(scan.getScanRangeValidity(i), before.getScanRangeValidity(i)) << i;
        EXPECT_NEAR(scan.getScanRange(i), before.getScanRange(i), 1e-4) << i;
    }
}

TEST(ScanDeskew, TraverseTakesTheMotionFromOdometryAndSkipsUnbracketedScans) {
    using mrpt::obs::CObservationOdometry;
    lookup::survey::TraverseData traverse;
    const double t0 = 1700000000.0;
    for (int k = 0; k <= 10; ++k) {  // 5 m/s straight ahead, 50 Hz
        auto odo = CObservationOdometry::Create();
        odo->timestamp = mrpt::Clock::fromDouble(t0 + 0.02 * k);
        odo->odometry = CPose2D(0.1 * k, 0, 0);
        traverse.laser_sequence.push_back(odo);
    }
    const CPose2D start(0, 0, 0), motion(0.375, 0, 0);
    auto inside = CObservation2DRangeScan::Create(sweep(start, motion));
    inside->timestamp = mrpt::Clock::fromDouble(t0 + 0.05);
    auto late = CObservation2DRangeScan::Create(sweep(start, motion));
    late->timestamp = mrpt::Clock::fromDouble(t0 + 0.15);  // sweep ends after the odometry
    traverse.laser_sequence.push_back(inside);
    traverse.laser_sequence.push_back(late);
    EXPECT_EQ(lookup::survey::deskewTraverse(traverse, 0.075), 1u);
    EXPECT_LT(meanWallDistance(*inside, start), 0.002);
    EXPECT_GT(meanWallDistance(*late, start), 0.015);  // left skewed
    EXPECT_EQ(lookup::survey::deskewTraverse(traverse, 0.0), 0u);
}

}  // namespace

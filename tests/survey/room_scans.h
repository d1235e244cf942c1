#pragma once
// A closed room of vertical walls at x = +-15 m, y = +-4 m around the origin, for scans redrawn
// by the survey (de-skewed, levelled).

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/poses/CPose2D.h>

#include <algorithm>
#include <cmath>
#include <limits>

namespace lookup::test {

/// Mean plan distance from the scan's points, the vehicle at `at`, to the room's walls.
inline double meanWallDistance(const mrpt::obs::CObservation2DRangeScan& scan,
                               const mrpt::poses::CPose2D& at = {}) {
    const mrpt::poses::CPose2D sensor = at + mrpt::poses::CPose2D(scan.sensorPose);
    double sum = 0;
    int count = 0;
    for (std::size_t i = 0; i < scan.getScanSize(); ++i) {
        if (!scan.getScanRangeValidity(i)) continue;
        double x = 0, y = 0;
        const double r = scan.getScanRange(i), b = scan.getScanAngle(i);
        sensor.composePoint(r * std::cos(b), r * std::sin(b), x, y);
        sum += std::min({std::abs(15 - std::abs(x)), std::abs(4 - std::abs(y))});
        ++count;
    }
    return count ? sum / count : std::numeric_limits<double>::infinity();
}

}  // namespace lookup::test

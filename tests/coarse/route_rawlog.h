#pragma once
// Writes a synthetic route traverse as a rawlog (external PNG images via common::RawlogWriter),
// with wheel odometry and a ground-truth pose file, like lookup-sim's datasets.

#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <string>
#include <vector>

#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "synthetic_route.h"

namespace lookup::coarse::testing {

/// Frame t at route position positions[t] [tiles = metres here], time t0 + t.
inline void writeRouteRawlog(const std::string& path, SyntheticRoute& route,
                             const std::vector<double>& positions, double t0,
                             const std::string& label = "FORWARD_CAM", double noise = 6.0,
                             const std::string& gt_path = "") {
    common::RawlogWriter w(path);
    common::PoseTrack gt;
    for (std::size_t t = 0; t < positions.size(); ++t) {
        const double time = t0 + static_cast<double>(t);
        mrpt::obs::CObservationOdometry odo;
        odo.sensorLabel = "ODOMETRY";
        odo.timestamp = mrpt::Clock::fromDouble(time - 0.01);
        odo.odometry = mrpt::poses::CPose2D(positions[t], 0, 0);
        w.write(odo);
        mrpt::obs::CObservationImage img;
        img.sensorLabel = label;
        img.timestamp = mrpt::Clock::fromDouble(time);
        img.image = route.image(positions[t], noise);
        w.writeWithExternalImage(img, label + "_" + std::to_string(t) + ".png");
        gt.push_back({time, mrpt::poses::CPose3D(positions[t], 0, 0, 0, 0, 0)});
    }
    w.close();
    if (!gt_path.empty()) common::writeMrptPoseFile(gt_path, gt);
}

inline std::vector<double> positionsFrom(double x0, double speed, int frames) {
    std::vector<double> p;
    for (int t = 0; t < frames; ++t) p.push_back(x0 + speed * t);
    return p;
}

}  // namespace lookup::coarse::testing

#pragma once
// A tiny synthetic survey made by the tests themselves: a 24 m corridor (COccupancyGridMap2D
// with irregular walls), a vehicle driving along it at 1 m/s, 10 Hz odometry (2 % scale drift),
// MRPT's laserScanSimulator scans, textured ceiling images (every 4th one blurred) and forward
// images, plus the ground-truth file. Fast: ~200 frames of 80x60 px.

#include <mrpt/config/CConfigFile.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/random/RandomGenerators.h>

#include <cmath>
#include <filesystem>
#include <string>

#include <opencv2/imgproc.hpp>

#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/survey/survey_options.h"
#include "lookup/test/support.h"

namespace lookup::test {

/// share/lookup/survey.ini of the source tree, read once.
inline const mrpt::config::CConfigFile& shareSurveyIni() {
    static mrpt::config::CConfigFile cfg(std::string(LOOKUP_SOURCE_SHARE_DIR) + "/survey.ini");
    return cfg;
}

/// Its [survey] options; `operator_start_at_truth` gives the fixture's true start
/// (truePoseAt(0): x 0, y 0, heading atan(0.1)) as the operator's start pose, so the map frame
/// is the truth's and errors compare directly.
inline survey::SurveyOptions shareSurveyOptions(bool operator_start_at_truth) {
    survey::SurveyOptions o;
    o.loadFromConfigFile(shareSurveyIni(), "survey");
    if (operator_start_at_truth) o.start_pose = "0 0 5.7106";
    return o;
}

inline mrpt::maps::COccupancyGridMap2D corridorMap() {
    mrpt::maps::COccupancyGridMap2D grid(-3, 27, -4, 4, 0.05f);
    grid.fill(0.5f);
    for (double x = -2; x < 26; x += 0.025) {
        // Walls at y = +-1.6 with bumps of varying size, so scans are not degenerate.
        const double bump = 0.3 * (std::fmod(std::floor(x / 1.7) * 0.37, 1.0));
        for (double y = -1.6 - bump; y <= 1.6 + bump; y += 0.025) {
            grid.setPos(x, y, 1.0f);  // free
        }
        grid.setPos(x, 1.65 + bump, 0.0f);
        grid.setPos(x, -1.65 - bump, 0.0f);
    }
    for (double y = -1.9; y <= 1.9; y += 0.025) grid.setPos(-2, y, 0.0f);  // dead end
    return grid;
}

inline mrpt::poses::CPose2D truePoseAt(double t) {
    const double x = t;  // 1 m/s
    const double y = 0.3 * std::sin(x / 3.0);
    const double yaw = std::atan(0.1 * std::cos(x / 3.0));
    return {x, y, yaw};
}

/// A world-fixed ceiling texture seen by a camera at `camera_in_map` (5 cm cells, 40 px/m).
inline cv::Mat ceilingTexture(const mrpt::poses::CPose3D& camera_in_map, int w, int h) {
    cv::Mat img(h, w, CV_8UC1);
    const double s = 40.0;  // px per m
    for (int v = 0; v < h; ++v) {
        for (int u = 0; u < w; ++u) {
            const double cx = (u - w / 2) / s, cy = (v - h / 2) / s;
            const double c = std::cos(camera_in_map.yaw()), sn = std::sin(camera_in_map.yaw());
            const double wx = camera_in_map.x() + c * cx - sn * cy;
            const double wy = camera_in_map.y() + sn * cx + c * cy;
            const auto ix = static_cast<long>(std::floor(wx * 20)),
                       iy = static_cast<long>(std::floor(wy * 20));
            const unsigned long hsh = (ix * 73856093UL) ^ (iy * 19349663UL);
            img.at<uint8_t>(v, u) = static_cast<uint8_t>(40 + (hsh * 2654435761UL >> 7) % 170);
        }
    }
    return img;
}

/// The fixture's ceiling camera: 80x60 px, f = 40 px.
inline mrpt::img::TCamera fixtureCeilingCamera() { return pinholeCamera(80, 60, 40); }

struct Fixture {
    std::string rawlog;
    std::string ground_truth;
    mrpt::poses::CPose3D ceiling_mount{0.5, 0.1, 2.0, 0.3, 0, 0};
    mrpt::poses::CPose3D forward_mount{1.0, 0, 1.5, 0, 0, 0};
    int frames = 0;
};

/// Writes `<dir>/<name>.rawlog` (+ _Images, + .GT.txt). `duration_s` of driving from x = 0.
inline Fixture makeSurveyRawlog(const std::string& dir, const std::string& name,
                                double duration_s = 20.0, bool with_lidar = true) {
    namespace fs = std::filesystem;
    fs::create_directories(dir);
    Fixture f;
    f.rawlog = (fs::path(dir) / (name + ".rawlog")).string();
    f.ground_truth = f.rawlog + ".GT.txt";
    const auto grid = corridorMap();
    common::RawlogWriter w(f.rawlog);
    common::PoseTrack gt;
    // laserScanSimulator draws its range noise from MRPT's global generator: seeded, so a test
    // sees the same scans on every run (unseeded, 1 run in 30 drifted past the 0.5 m bound).
    mrpt::random::getRandomGenerator().randomize(1);
    mrpt::poses::CPose2D odometry;
    mrpt::poses::CPose2D previous = truePoseAt(0);
    const double t0 = 1.7e9;  // realistic UNIX time
    const mrpt::img::TCamera cam = fixtureCeilingCamera();
    mrpt::img::TCamera forward_cam = cam;  // the survey refuses images of another size
    forward_cam.scaleToResolution(32, 24);
    for (int k = 0; k <= static_cast<int>(duration_s * 10); ++k) {
        const double t = k * 0.1;
        const auto pose = truePoseAt(t);
        const auto stamp = mrpt::Clock::fromDouble(t0 + t);
        gt.push_back({t0 + t, mrpt::poses::CPose3D(pose)});
        // Odometry: true increments with a 2 % scale error.
        auto inc = pose - previous;
        inc.x(inc.x() * 1.02);
        odometry = odometry + inc;
        previous = pose;
        mrpt::obs::CObservationOdometry odo;
        odo.sensorLabel = "ODOMETRY";
        odo.timestamp = stamp;
        odo.odometry = odometry;
        w.write(odo);
        if (with_lidar) {
            mrpt::obs::CObservation2DRangeScan scan;
            scan.sensorLabel = "LIDAR";
            scan.timestamp = stamp;
            scan.aperture = mrpt::DEG2RAD(270.0);
            scan.maxRange = 30;
            grid.laserScanSimulator(scan, pose, 0.5f, 271, 0.01f);
            w.write(scan);
        }
        mrpt::obs::CObservationImage ceiling;
        ceiling.sensorLabel = "CEILING_CAM";
        ceiling.timestamp = stamp;
        ceiling.cameraPose = f.ceiling_mount;
        ceiling.cameraParams = cam;
        cv::Mat tex = ceilingTexture(mrpt::poses::CPose3D(pose) + f.ceiling_mount, 80, 60);
        if (k % 4 == 3) cv::GaussianBlur(tex, tex, cv::Size(0, 0), 3.0);  // motion blur stand-in
        ceiling.image = mrpt::img::CImage(tex, mrpt::img::DEEP_COPY);
        w.writeWithExternalImage(ceiling, "CEILING_CAM_" + std::to_string(k) + ".png");
        mrpt::obs::CObservationImage forward;
        forward.sensorLabel = "FORWARD_CAM";
        forward.timestamp = mrpt::Clock::fromDouble(t0 + t + 0.02);
        forward.cameraPose = f.forward_mount;
        forward.cameraParams = forward_cam;
        forward.image = mrpt::img::CImage(ceilingTexture(mrpt::poses::CPose3D(pose), 32, 24),
                                          mrpt::img::DEEP_COPY);
        w.writeWithExternalImage(forward, "FORWARD_CAM_" + std::to_string(k) + ".png");
        ++f.frames;
    }
    w.close();
    common::writeMrptPoseFile(f.ground_truth, gt);
    return f;
}

}  // namespace lookup::test

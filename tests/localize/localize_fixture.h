#pragma once
// Shared by the localisation tests: a synthetic planar ceiling, a database along a straight
// drive, a query over it (optionally damaged), and running the built programs.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <functional>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "lookup/common/config.h"
#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"
#include "lookup/localize/localize_app.h"
#include "lookup/refine/testing/synthetic_ceiling.h"
#include "lookup/test/support.h"

namespace lookup::localize_testing {
namespace fs = std::filesystem;
using test::readText;
using test::runProgram;

constexpr double kCeilingHeight = 5.0;
constexpr double kT0 = 1.7e9;

struct Scene {
    refine::synthetic::SyntheticCeiling ceiling =
        refine::synthetic::SyntheticCeiling::make(kCeilingHeight, 40.0, 0.01, 7);
    mrpt::img::TCamera camera = refine::synthetic::makeCamera(320, 240, 160);
    mrpt::poses::CPose3D mount = refine::synthetic::ceilingCameraOnVehicle();

    mrpt::obs::CObservationImage::Ptr image(const mrpt::poses::CPose3D& vehicle, double t) const {
        auto obs = mrpt::obs::CObservationImage::Create();
        obs->sensorLabel = "CEILING_CAM";
        obs->timestamp = mrpt::Clock::fromDouble(t);
        obs->cameraParams = camera;
        obs->cameraPose = mount;
        obs->image =
            mrpt::img::CImage(ceiling.render(camera, vehicle + mount), mrpt::img::DEEP_COPY);
        return obs;
    }
};

// A forward view for frame k of a traverse: smooth random texture, distinct per frame and
// per traverse (seed), as a tunnel seen from a different lateral position would be.
inline mrpt::obs::CObservationImage::Ptr forwardView(int traverse_seed, int k, double t) {
    cv::Mat img(96, 128, CV_8UC1);
    cv::RNG rng(traverse_seed * 1000 + k);
    rng.fill(img, cv::RNG::UNIFORM, 0, 255);
    cv::GaussianBlur(img, img, cv::Size(0, 0), 3.0);
    auto obs = mrpt::obs::CObservationImage::Create();
    obs->sensorLabel = "FORWARD_CAM";
    obs->timestamp = mrpt::Clock::fromDouble(t);
    obs->image = mrpt::img::CImage(img, mrpt::img::DEEP_COPY);
    return obs;
}

// One survey traverse: `references` every 0.25 m along y = 0 from x = -8, 0.1 s apart from
// t0; with forward views when forward_seed > 0.
struct SurveyTraverse {
    const char* name;
    int references;
    double t0;
    int forward_seed = 0;
    double y_m = 0;  ///< lateral position of the traverse
};

// `survey_camera`: the survey's ceiling camera as a rolling shutter (readout_s > 0) with its
// timing and velocity, recorded in db.ini as `recorded_readout_ms`.
struct SurveyCamera {
    refine::RowTiming timing;
    double recorded_readout_ms = 0;
    std::optional<double> time_offset_sigma_s;  ///< db.ini's ceiling_time_offset_sigma_s
};

// `grade`: every reference stored as if the scene lay on it (3-D survey poses down a decline,
// the ceiling following the floor); the images as the scene's.
inline void writeDatabase(const Scene& scene, const std::string& dir,
                          const std::vector<SurveyTraverse>& traverses,
                          const SurveyCamera& survey_camera = {},
                          const mrpt::poses::CPose3D& grade = {}) {
    database::DatabaseWriter writer(dir);
    for (const auto& tr : traverses) {
        for (int k = 0; k < tr.references; ++k) {
            database::ReferenceInput in;
            in.traverse = tr.name;
            in.vehicle_pose = mrpt::poses::CPose3D(-8 + 0.25 * k, tr.y_m, 0, 0, 0, 0);
            in.vehicle_cov.setIdentity();
            in.vehicle_cov *= 1e-4;
            in.ceiling = scene.image(in.vehicle_pose, tr.t0 + 0.1 * k);
            if (survey_camera.timing.readout_s > 0) {
                in.ceiling->image = mrpt::img::CImage(
                    scene.ceiling.renderRollingShutter(scene.camera, scene.mount, in.vehicle_pose,
                                                       survey_camera.timing),
                    mrpt::img::DEEP_COPY);
            }
            in.vehicle_pose = grade + in.vehicle_pose;
            if (tr.forward_seed > 0) {
                in.forward = forwardView(tr.forward_seed, k, tr.t0 + 0.1 * k);
                in.forward_vehicle_pose = in.vehicle_pose;
            }
            in.travelled_m = 0.25 * k;
            writer.add(in);
        }
    }
    database::DatabaseInfo info;
    info.name = "synthetic";
    info.ceiling_camera = scene.camera;
    info.ceiling_height_m = kCeilingHeight;
    info.pose_source = "test";
    info.ceiling_readout_ms = survey_camera.recorded_readout_ms;
    info.ceiling_time_offset_sigma_s = survey_camera.time_offset_sigma_s;
    writer.commit(info);
}

// The planar drive of the first test (20 frames, odometry beside every ceiling frame, coarse
// poses from a file), with `spoil(i, image, odometry)` free to damage frame i's records.
using Spoiler =
    std::function<void(int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&)>;

// The run of `dir`'s db, query.rawlog and coarse.tum into run/, grid sampling, quiet.
inline localize::LocalizeRequest requestIn(const fs::path& dir) {
    localize::LocalizeRequest req;
    req.db_dir = (dir / "db").string();
    req.rawlog = (dir / "query.rawlog").string();
    req.out_dir = (dir / "run").string();
    req.coarse_poses = (dir / "coarse.tum").string();
    req.sampling = "grid";
    req.progress = false;
    return req;
}

// The query drive of planarRun: frame i's vehicle pose, the coarse poses' error, and how far
// ahead of the usual mount the camera sits on the vehicle (the survey's and the query's).
struct PlanarDrive {
    std::function<mrpt::poses::CPose3D(int)> vehicle = [](int i) {
        return mrpt::poses::CPose3D(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0);
    };
    mrpt::poses::CPose3D coarse_error{0.6, -0.4, 0, -0.05, 0, 0};
    mrpt::poses::CPose3D camera_ahead;
    SurveyCamera survey_camera;
    /// The scene on a grade (writeDatabase): the odometry and coarse poses in its plan view.
    mrpt::poses::CPose3D grade;
};

inline localize::LocalizeRequest planarRun(const fs::path& dir, const Spoiler& spoil,
                                           int frames = 20, const PlanarDrive& drive = {}) {
    Scene scene;
    scene.mount = drive.camera_ahead + scene.mount;
    writeDatabase(scene, (dir / "db").string(), {{"survey", 65, 100.0}}, drive.survey_camera,
                  drive.grade);
    common::PoseTrack coarse;
    common::RawlogWriter rawlog((dir / "query.rawlog").string());
    for (int i = 0; i < frames; ++i) {
        const double t = kT0 + 0.1 * i;
        const mrpt::poses::CPose3D vehicle = drive.vehicle(i);
        const mrpt::poses::CPose2D in_plan(drive.grade + vehicle);
        coarse.push_back({t, mrpt::poses::CPose3D(in_plan) + drive.coarse_error});
        auto img = scene.image(vehicle, t);
        mrpt::obs::CObservationOdometry odo;
        odo.sensorLabel = "ODOMETRY";
        odo.timestamp = img->timestamp;
        odo.odometry = in_plan;
        spoil(i, *img, odo);
        rawlog.write(odo);
        if (!img->image.isEmpty()) {
            rawlog.writeWithExternalImage(*img, "ceiling_" + std::to_string(i) + ".png");
        } else {
            rawlog.write(*img);
        }
    }
    rawlog.close();
    common::writeTumPoseFile((dir / "coarse.tum").string(), coarse);
    return requestIn(dir);
}

// Every number in every line of `path` (after `skip_lines`) is finite.
inline std::size_t nonFiniteLines(const fs::path& path, int skip_lines) {
    std::ifstream in(path);
    std::string line;
    std::size_t bad = 0;
    for (int k = 0; std::getline(in, line); ++k) {
        if (k < skip_lines) continue;
        for (char& c : line) c = c == ',' ? ' ' : c;
        std::istringstream cells(line);
        for (std::string cell; cells >> cell;) {
            char* end = nullptr;
            const double v = std::strtod(cell.c_str(), &end);
            if (end != cell.c_str() && !std::isfinite(v)) {
                ++bad;
                break;
            }
        }
    }
    return bad;
}

/// Command-line arguments of lookup-localize for `req`.
inline std::vector<std::string> localizeArgs(const localize::LocalizeRequest& req) {
    std::vector<std::string> a{"--db", req.db_dir, "--rawlog", req.rawlog, "--out", req.out_dir};
    if (!req.coarse_poses.empty()) a.insert(a.end(), {"--coarse-poses", req.coarse_poses});
    if (!req.sampling.empty()) a.insert(a.end(), {"--sampling", req.sampling});
    return a;
}

}  // namespace lookup::localize_testing

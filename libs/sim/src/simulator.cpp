#include "lookup/sim/simulator.h"

#include "lookup/sim/camera_renderer.h"
#include "noise.h"

#include <lookup/common/config.h>
#include <lookup/common/rawlog_io.h>
#include <mrpt/core/Clock.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <limits>
#include <sstream>

namespace lookup::sim {
namespace fs = std::filesystem;
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using namespace detail;

constexpr double kTrackDt = 0.01;  // ground-truth step [s]

enum class Sensor { Odometry = 0, Lidar = 1, Ceiling = 2, Forward = 3 };

struct Event {
    double t;  // seconds since the traverse start
    Sensor sensor;
    std::size_t index;
};

/// Linear interpolation of the dense track at `t` (absolute), angles along the short way.
mrpt::poses::CPose3D poseAt(const common::PoseTrack& track, double t) {
    const double t0 = track.front().time_s;
    const double f = std::clamp((t - t0) / kTrackDt, 0.0, double(track.size() - 1));
    const std::size_t i = std::min(static_cast<std::size_t>(f), track.size() - 2);
    const double a = f - i;
    const auto& p = track[i].pose;
    const auto& q = track[i + 1].pose;
    auto lerpAngle = [a](double x, double y) {
        return mrpt::math::wrapToPi(x + a * mrpt::math::wrapToPi(y - x));
    };
    return mrpt::poses::CPose3D(p.x() + a * (q.x() - p.x()), p.y() + a * (q.y() - p.y()),
                                p.z() + a * (q.z() - p.z()), lerpAngle(p.yaw(), q.yaw()),
                                lerpAngle(p.pitch(), q.pitch()), lerpAngle(p.roll(), q.roll()));
}

uint64_t folderBytes(const fs::path& p) {
    std::error_code ec;
    if (fs::is_regular_file(p, ec)) return fs::file_size(p, ec);
    uint64_t total = 0;
    if (fs::is_directory(p, ec)) {
        for (const auto& e : fs::recursive_directory_iterator(p, ec)) {
            if (e.is_regular_file(ec)) total += e.file_size(ec);
        }
    }
    return total;
}

std::string frameName(const std::string& label, std::size_t index) {
    char buf[32];
    std::snprintf(buf, sizeof(buf), "_%06zu.png", index);
    return label + buf;
}

// Bounds of the error of the start pose lookup-sim hands the survey: a vehicle parked over a
// surveyed mark at the portal, aligned by eye with a painted line (docs/survey.md).
constexpr double kStartErrorMaxM = 0.05;
constexpr double kStartErrorMaxDeg = 0.1;

// The operator's start pose of a traverse, "x y yaw_deg": its true pose at the first lidar
// scan with a seeded error within the bounds above, never the exact truth.
std::string operatorStartPose(const ScenarioOptions& sc, const common::PoseTrack& track,
                              std::size_t index) {
    const mrpt::poses::CPose3D p = poseAt(track, track.front().time_s + sc.lidar.phase_s);
    const uint32_t seed = hash3(static_cast<uint32_t>(sc.seed),
                                static_cast<uint32_t>(sc.seed >> 32), 0x57a27u + uint32_t(index));
    const double r = kStartErrorMaxM * (0.5 + 0.5 * unit(hash3(seed, 1, 0)));
    const double dir = 2 * M_PI * unit(hash3(seed, 2, 0));
    const double sign = unit(hash3(seed, 3, 0)) < 0.5 ? -1.0 : 1.0;
    const double dyaw = sign * kStartErrorMaxDeg * (0.5 + 0.5 * unit(hash3(seed, 4, 0)));
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%.3f %.3f %.3f", p.x() + r * std::cos(dir),
                  p.y() + r * std::sin(dir), mrpt::RAD2DEG(p.yaw()) + dyaw);
    return buf;
}

void writeDatasetIni(const std::string& path, const ScenarioOptions& sc,
                     const std::vector<common::PoseTrack>& tracks) {
    std::ofstream f(path);
    f << "# Written by lookup-sim; see docs/dataset-format.md\n"
      << "[dataset]\n"
      << "name = " << sc.name << "\n"
      << "traverse_count = " << sc.traverses.size() << "\n"
      << "map = map.gridmap.gz\n"
      << "ceiling_camera_label = " << sc.ceiling_camera.label << "\n"
      << "forward_camera_label = " << sc.forward_camera.label << "\n"
      << "lidar_label = " << sc.lidar.label << "\n"
      << "odometry_label = " << sc.odometry.label << "\n";
    // No ceiling height and no exact start: the survey measures the one and is given the
    // other as an operator would give it.
    bool start_written = false;
    for (std::size_t i = 0; i < sc.traverses.size(); ++i) {
        const auto& t = sc.traverses[i];
        f << "\n[traverse_" << i << "]\n"
          << "name = " << t.name << "\n"
          << "rawlog = " << t.name << ".rawlog\n"
          << "ground_truth = " << t.name << ".rawlog.GT.txt\n"
          << "roles = " << t.roles << "\n";
        if (!start_written && t.roles.find("mapping") != std::string::npos) {
            f << "start_pose = " << operatorStartPose(sc, tracks[i], i) << "\n";
            start_written = true;
        }
    }
    if (!f) throw common::ConfigError(path + ": cannot write");
}

}  // namespace

mrpt::obs::CObservation2DRangeScan simulateLidar(const TunnelWorld& world,
                                                 const mrpt::poses::CPose2D& vehicle,
                                                 const LidarOptions& lidar, uint32_t noise_key) {
    mrpt::obs::CObservation2DRangeScan scan;
    scan.sensorLabel = lidar.label;
    scan.aperture = static_cast<float>(mrpt::DEG2RAD(lidar.aperture_deg));
    scan.rightToLeft = true;
    scan.maxRange = static_cast<float>(lidar.max_range_m);
    scan.stdError = static_cast<float>(lidar.noise_std_m);
    scan.sensorPose = lidar.mount.pose();
    const std::size_t rays =
        static_cast<std::size_t>(std::lround(lidar.aperture_deg / lidar.resolution_deg)) + 1;
    scan.resizeScan(rays);
    const mrpt::poses::CPose2D sensor = vehicle + mrpt::poses::CPose2D(scan.sensorPose);
    // A horizontal scan plane at the mount height; only the rock counts (walls, and the floor
    // or roof where the plane meets them), as for a 2-D scanner above the furniture's reach.
    const Eigen::Vector3d origin(sensor.x(), sensor.y(), lidar.mount.z_m);
    const double rad_per_ray = mrpt::DEG2RAD(lidar.resolution_deg);
    for (std::size_t r = 0; r < rays; ++r) {
        const double angle =
            sensor.phi() - scan.aperture / 2 + r * scan.aperture / static_cast<double>(rays - 1);
        const Eigen::Vector3d dir(std::cos(angle), std::sin(angle), 0.0);
        const SurfaceHit hit = world.traceStatic(origin, dir, 0.0, lidar.max_range_m, rad_per_ray);
        if (hit.kind == SurfaceKind::None || !(hit.t < lidar.max_range_m)) {
            scan.setScanRange(r, scan.maxRange);
            scan.setScanRangeValidity(r, false);
            continue;
        }
        const double noise =
            lidar.noise_std_m * gaussian(hash3(noise_key, r, 1), hash3(noise_key, r, 2));
        scan.setScanRange(r, static_cast<float>(std::max(0.0, hit.t + noise)));
        scan.setScanRangeValidity(r, true);
    }
    return scan;
}

common::PoseTrack vehicleTrack(const TunnelWorld& world, const TraverseOptions& tr,
                               const VehicleOptions& vehicle, double start_time_s) {
    const auto& route = world.route();
    const double step = 0.25;
    const double length = world.routeLength();
    const double s_begin = std::min(tr.start_m, length - 5);
    const double s_end = tr.end_m < 0 ? length : std::min(tr.end_m, length);
    auto centre = [&](double s, Vector2d* dir) {
        const double f = std::clamp(s / step, 0.0, double(route.size() - 1));
        const std::size_t i = std::min(static_cast<std::size_t>(f), route.size() - 2);
        const double a = f - i;
        *dir = (route[i + 1] - route[i]).normalized();
        return Vector2d(route[i] + a * (route[i + 1] - route[i]));
    };
    auto path = [&](double s) {
        Vector2d dir;
        const Vector2d c = centre(s, &dir);
        const double off =
            tr.lateral_offset_m +
            tr.zigzag_amplitude_m * std::sin(2 * M_PI * (s - s_begin) / tr.zigzag_period_m);
        return Vector2d(c + off * Vector2d(-dir.y(), dir.x()));
    };
    const uint32_t seed =
        hash3(static_cast<uint32_t>(tr.name.size()), tr.name.empty() ? 0 : tr.name[0],
              static_cast<uint32_t>(tr.speed_kmh * 1000));
    const double v_cruise = tr.speed_kmh / 3.6, v_min = 0.3;
    auto speed = [&](double s) {
        const double wobble = 2 * fbm(s / 60.0, 0.5, seed, 2, 1.0, 0.5, 0).v - 1;
        double v = v_cruise * (1 + tr.speed_variation * std::clamp(2.0 * wobble, -1.0, 1.0));
        v = std::min(v, std::sqrt(v_min * v_min + 2 * tr.accel_mps2 * (s - s_begin)));
        v = std::min(v, std::sqrt(v_min * v_min + 2 * tr.accel_mps2 * std::max(s_end - s, 0.0)));
        return std::max(v, v_min);
    };
    common::PoseTrack track;
    double s = s_begin, t = 0;
    for (;;) {
        const Vector2d p = path(s);
        const Vector2d ahead = path(std::min(s + 0.2, s_end + 0.2)) - path(s - 0.2);
        const double yaw = std::atan2(ahead.y(), ahead.x());
        const Vector2d fwd(std::cos(yaw), std::sin(yaw)), left(-fwd.y(), fwd.x());
        const Vector2d front = p + fwd * vehicle.wheelbase_m / 2,
                       rear = p - fwd * vehicle.wheelbase_m / 2;
        const Vector2d pl = p + left * vehicle.track_m / 2, pr = p - left * vehicle.track_m / 2;
        const double zf = world.floorHeight(front.x(), front.y());
        const double zr = world.floorHeight(rear.x(), rear.y());
        const double zl = world.floorHeight(pl.x(), pl.y());
        const double zri = world.floorHeight(pr.x(), pr.y());
        // MRPT: positive pitch lowers the nose, positive roll raises the left side.
        const double pitch = -std::atan2(zf - zr, vehicle.wheelbase_m);
        const double roll = std::atan2(zl - zri, vehicle.track_m);
        track.push_back(
            {start_time_s + t,
             mrpt::poses::CPose3D(p.x(), p.y(), 0.25 * (zf + zr + zl + zri), yaw, pitch, roll)});
        if (s >= s_end) break;
        const double v = speed(s + 0.5 * speed(s) * kTrackDt);  // midpoint rule
        s = std::min(s + v * kTrackDt, s_end);
        t += kTrackDt;
    }
    return track;
}

Simulator::Simulator(ScenarioOptions scenario) : scenario_(std::move(scenario)) {
    scenario_.check();
    world_ = std::make_unique<TunnelWorld>(scenario_.world, scenario_.seed);
    double next = scenario_.start_time_s;
    for (std::size_t i = 0; i < scenario_.traverses.size(); ++i) {
        const double t0 = std::max(scenario_.start_time_s + i * scenario_.traverse_gap_s, next);
        tracks_.push_back(vehicleTrack(*world_, scenario_.traverses[i], scenario_.vehicle, t0));
        next = std::ceil(tracks_.back().back().time_s + 10.0);
    }
}

Simulator::~Simulator() = default;

SimulationResult Simulator::run(const std::string& out_dir, const Progress& progress) const {
    const auto start = std::chrono::steady_clock::now();
    SimulationResult result;
    result.out_dir = out_dir;
    try {
        std::error_code ec;
        fs::create_directories(out_dir, ec);
        if (!fs::is_directory(out_dir)) {
            result.reason = out_dir + ": cannot create output folder: " + ec.message();
            return result;
        }
        {
            std::ofstream f(out_dir + "/scenario.ini");
            f << scenario_.toIniText();
            if (!f) throw common::ConfigError(out_dir + "/scenario.ini: cannot write");
        }
        writeDatasetIni(out_dir + "/dataset.ini", scenario_, tracks_);

        mrpt::maps::COccupancyGridMap2D grid;
        world_->fillGridMap(grid);
        {
            mrpt::io::CFileGZOutputStream f;
            if (!f.open(out_dir + "/map.gridmap.gz")) {
                throw common::ConfigError(out_dir + "/map.gridmap.gz: cannot write");
            }
            auto arch = mrpt::serialization::archiveFrom(f);
            arch << grid;
        }
        if (!grid.saveAsBitmapFile(out_dir + "/map.png")) {
            throw common::ConfigError(out_dir + "/map.png: cannot write");
        }
        for (std::size_t i = 0; i < scenario_.traverses.size(); ++i) {
            result.traverses.push_back(runTraverse(i, out_dir, grid, progress));
        }
        result.total_bytes = folderBytes(out_dir);
        result.status = SimulationResult::Status::Ok;
    } catch (const std::exception& e) {
        result.reason = e.what();
    }
    result.wall_time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return result;
}

TraverseSummary Simulator::runTraverse(std::size_t index, const std::string& out_dir,
                                       const mrpt::maps::COccupancyGridMap2D& grid,
                                       const Progress& progress) const {
    const auto start = std::chrono::steady_clock::now();
    const TraverseOptions& tr = scenario_.traverses[index];
    const common::PoseTrack& track = tracks_[index];
    const double t0 = track.front().time_s;
    const double duration = track.back().time_s - t0;
    const uint32_t seed =
        hash3(static_cast<uint32_t>(scenario_.seed), static_cast<uint32_t>(scenario_.seed >> 32),
              static_cast<uint32_t>(index) + 1);
    TraverseSummary sum;
    sum.name = tr.name;
    sum.roles = tr.roles;
    sum.duration_s = duration;
    sum.start_time_s = t0;
    sum.ground_truth_rows = track.size();
    for (std::size_t i = 1; i < track.size(); ++i) {
        sum.length_m += std::hypot(track[i].pose.x() - track[i - 1].pose.x(),
                                   track[i].pose.y() - track[i - 1].pose.y());
    }

    const std::string stem = out_dir + "/" + tr.name;
    std::error_code ec;
    fs::remove_all(stem + "_Images", ec);  // no stale frames from an earlier run
    common::writeMrptPoseFile(stem + ".rawlog.GT.txt", track);

    // Every sensor on its own clock; ties are broken by sensor order so the file order is fixed.
    std::vector<Event> events;
    auto schedule = [&](Sensor s, double rate, double phase) {
        for (std::size_t k = 0;; ++k) {
            const double t = phase + k / rate;
            if (t > duration) break;
            events.push_back({t, s, k});
        }
    };
    schedule(Sensor::Odometry, scenario_.odometry.rate_hz, scenario_.odometry.phase_s);
    schedule(Sensor::Lidar, scenario_.lidar.rate_hz, scenario_.lidar.phase_s);
    schedule(Sensor::Ceiling, scenario_.ceiling_camera.rate_hz, scenario_.ceiling_camera.phase_s);
    schedule(Sensor::Forward, scenario_.forward_camera.rate_hz, scenario_.forward_camera.phase_s);
    std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) {
        return a.t < b.t || (a.t == b.t && a.sensor < b.sensor);
    });

    const CameraRenderer ceiling(*world_, scenario_.ceiling_camera, CameraRenderer::Kind::Ceiling,
                                 scenario_.threads);
    const CameraRenderer forward(*world_, scenario_.forward_camera, CameraRenderer::Kind::Forward,
                                 scenario_.threads);
    const mrpt::poses::CPose3D ceiling_on_vehicle = scenario_.ceiling_camera.mount.pose();
    const mrpt::poses::CPose3D forward_on_vehicle = scenario_.forward_camera.mount.pose();

    common::RawlogWriter writer(stem + ".rawlog");
    mrpt::poses::CPose2D odometry;  // accumulated, drifting
    mrpt::poses::CPose2D last_true;
    bool have_last = false;
    auto cameraConditions = [&](const CameraOptions& cam, const CameraRenderer& renderer,
                                const mrpt::poses::CPose3D& on_vehicle, double t, Sensor s,
                                std::size_t k, bool blur) {
        FrameConditions fc;
        const uint32_t key = hash3(seed, static_cast<uint32_t>(s), static_cast<uint32_t>(k));
        // Slow auto-exposure drift plus a small frame-to-frame flicker.
        const double slow = 2 * valueNoise(t / 3.0, 0.5, seed + 17 * uint32_t(s)).v - 1;
        fc.exposure_gain =
            1 + cam.exposure_variation * (0.8 * slow + 0.2 * (2 * unit(mix32(key)) - 1));
        fc.noise_key = key;
        if (blur && cam.exposure_ms > 0) {
            // Image motion of the ceiling point on the optical axis during the exposure.
            const double half = 0.5e-3 * cam.exposure_ms;
            const mrpt::poses::CPose3D c0 = poseAt(track, t0 + t - half) + on_vehicle;
            const mrpt::poses::CPose3D c1 = poseAt(track, t0 + t + half) + on_vehicle;
            const double range = std::max(scenario_.world.ceiling_height_m - c0.z(), 0.5);
            const mrpt::math::TPoint3D X = c0.composePoint(mrpt::math::TPoint3D(0, 0, range));
            const mrpt::math::TPoint3D p1 = c1.inverseComposePoint(X);
            const auto& K = renderer.intrinsics();
            fc.blur_u_px = K.fx() * p1.x / p1.z;
            fc.blur_v_px = K.fy() * p1.y / p1.z;
        }
        return fc;
    };

    std::size_t done = 0, last_report = 0;
    for (const Event& ev : events) {
        const double t_abs = t0 + ev.t;
        const mrpt::poses::CPose3D vehicle = poseAt(track, t_abs);
        const auto stamp = mrpt::Clock::fromDouble(t_abs);
        switch (ev.sensor) {
            case Sensor::Ceiling:
            case Sensor::Forward: {
                const bool is_ceiling = ev.sensor == Sensor::Ceiling;
                const CameraOptions& cam =
                    is_ceiling ? scenario_.ceiling_camera : scenario_.forward_camera;
                const CameraRenderer& renderer = is_ceiling ? ceiling : forward;
                const mrpt::poses::CPose3D& on_vehicle =
                    is_ceiling ? ceiling_on_vehicle : forward_on_vehicle;
                const FrameConditions fc = cameraConditions(cam, renderer, on_vehicle, ev.t,
                                                            ev.sensor, ev.index, is_ceiling);
                mrpt::obs::CObservationImage obs;
                obs.sensorLabel = cam.label;
                obs.timestamp = stamp;
                obs.cameraPose = on_vehicle;
                obs.cameraParams = renderer.intrinsics();
                obs.image = renderer.render(vehicle + on_vehicle, fc);
                writer.writeWithExternalImage(obs, frameName(cam.label, ev.index));
                (is_ceiling ? sum.ceiling_frames : sum.forward_frames)++;
                break;
            }
            case Sensor::Lidar: {
                mrpt::obs::CObservation2DRangeScan scan =
                    simulateLidar(*world_, mrpt::poses::CPose2D(vehicle), scenario_.lidar,
                                  hash3(seed, 1000 + ev.index, 7));
                scan.timestamp = stamp;
                writer.write(scan);
                sum.lidar_scans++;
                break;
            }
            case Sensor::Odometry: {
                const mrpt::poses::CPose2D now(vehicle);
                if (have_last) {
                    const mrpt::poses::CPose2D delta = now - last_true;
                    const double dist = std::hypot(delta.x(), delta.y());
                    const uint32_t key = hash3(seed, 2000 + ev.index, 11);
                    const OdometryOptions& o = scenario_.odometry;
                    const double k = 1 + o.scale_error;
                    const mrpt::poses::CPose2D measured(
                        delta.x() * k +
                            o.noise_std_m * gaussian(hash3(key, 1, 0), hash3(key, 2, 0)),
                        delta.y() * k +
                            o.noise_std_m * gaussian(hash3(key, 3, 0), hash3(key, 4, 0)),
                        delta.phi() + mrpt::DEG2RAD(o.yaw_bias_deg_per_m * dist +
                                                    o.noise_std_deg * gaussian(hash3(key, 5, 0),
                                                                               hash3(key, 6, 0))));
                    odometry = odometry + measured;
                    // Measured local velocities over the last period.
                    last_true = now;
                    mrpt::obs::CObservationOdometry obs;
                    obs.sensorLabel = o.label;
                    obs.timestamp = stamp;
                    obs.odometry = odometry;
                    obs.hasVelocities = true;
                    obs.velocityLocal.vx = measured.x() * o.rate_hz;
                    obs.velocityLocal.vy = measured.y() * o.rate_hz;
                    obs.velocityLocal.omega = measured.phi() * o.rate_hz;
                    writer.write(obs);
                } else {
                    last_true = now;
                    have_last = true;
                    mrpt::obs::CObservationOdometry obs;
                    obs.sensorLabel = scenario_.odometry.label;
                    obs.timestamp = stamp;
                    obs.odometry = odometry;
                    obs.hasVelocities = true;
                    writer.write(obs);
                }
                sum.odometry_records++;
                break;
            }
        }
        ++done;
        if (progress && (done - last_report) * 200 >= events.size()) {
            last_report = done;
            progress(tr.name, double(done) / events.size());
        }
    }
    writer.close();
    if (progress) progress(tr.name, 1.0);
    sum.bytes = folderBytes(stem + ".rawlog") + folderBytes(stem + "_Images") +
                folderBytes(stem + ".rawlog.GT.txt");
    sum.wall_time_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    return sum;
}

std::string formatSummary(const SimulationResult& r) {
    std::ostringstream os;
    os << std::fixed;
    if (r.status != SimulationResult::Status::Ok) {
        os << "FAILED: " << r.reason << "\n";
        return os.str();
    }
    os << std::left << std::setw(12) << "traverse" << std::setw(20) << "roles" << std::right
       << std::setw(8) << "ceiling" << std::setw(8) << "forward" << std::setw(7) << "lidar"
       << std::setw(7) << "odom" << std::setw(10) << "length_m" << std::setw(11) << "duration_s"
       << std::setw(9) << "size_MB" << std::setw(8) << "time_s"
       << "\n";
    for (const auto& t : r.traverses) {
        os << std::left << std::setw(12) << t.name << std::setw(20) << t.roles << std::right
           << std::setw(8) << t.ceiling_frames << std::setw(8) << t.forward_frames << std::setw(7)
           << t.lidar_scans << std::setw(7) << t.odometry_records << std::setw(10)
           << std::setprecision(1) << t.length_m << std::setw(11) << t.duration_s << std::setw(9)
           << t.bytes / 1e6 << std::setw(8) << t.wall_time_s << "\n";
    }
    os << "total: " << std::setprecision(1) << r.total_bytes / 1e6 << " MB in " << r.wall_time_s
       << " s -> " << r.out_dir << "\n";
    return os.str();
}

}  // namespace lookup::sim

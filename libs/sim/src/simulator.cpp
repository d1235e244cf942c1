#include "lookup/sim/simulator.h"

#include "lookup/sim/camera_renderer.h"
#include "noise.h"

#include <lookup/common/config.h>
#include <lookup/common/rawlog_io.h>
#include <mrpt/core/Clock.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
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
    double t;      // capture time, seconds since the traverse start
    double stamp;  // recorded time stamp, seconds since the traverse start
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

/// Capture times of one sensor on its own clock, their stamps (latency, jitter) and the
/// records lost in transmission or in `lost` windows left out.
template <typename Lost>
void scheduleSensor(std::vector<Event>& events, Sensor s, double rate, double phase,
                    const SensorTiming& timing, double duration, uint32_t seed, Lost&& lost) {
    const uint32_t id = static_cast<uint32_t>(s);
    for (std::size_t k = 0;; ++k) {
        const double t = phase + k / rate;
        if (t > duration) break;
        const uint32_t kk = static_cast<uint32_t>(k);
        if (timing.drop_rate > 0 && unit(hash3(seed, 4000 + id, kk)) < timing.drop_rate) continue;
        if (lost(t)) continue;
        double stamp = t;
        if (timing.latency_ms != 0 || timing.jitter_ms != 0) {
            const double jitter = gaussian(hash3(seed, 3000 + id, kk), hash3(seed, 3500 + id, kk));
            stamp = t + 1e-3 * (timing.latency_ms + timing.jitter_ms * jitter);
        }
        events.push_back({t, stamp, s, k});
    }
}

/// Odometry dropouts: windows of `dropout_s` chosen with probability `dropout_fraction`.
bool inDropout(const OdometryOptions& o, double t, uint32_t seed) {
    if (o.dropout_fraction <= 0) return false;
    const double cell = std::floor(t / o.dropout_s);
    return unit(hash3(seed, 5000, static_cast<uint32_t>(static_cast<int64_t>(cell)))) <
           o.dropout_fraction;
}

/// Poses of the camera when each row is exposed (rolling shutter), `t_abs` being the time of the
/// row the stamp refers to.
std::vector<mrpt::poses::CPose3D> rowPoses(const common::PoseTrack& track, const CameraOptions& cam,
                                           const mrpt::poses::CPose3D& on_vehicle, double t_abs) {
    const double readout = 1e-3 * cam.readout_ms;
    const double t_first = t_abs - (cam.stamp_row == common::StampRow::Middle ? readout / 2 : 0.0);
    std::vector<mrpt::poses::CPose3D> poses;
    poses.reserve(cam.height_px);
    for (int v = 0; v < cam.height_px; ++v) {
        poses.push_back(poseAt(track, t_first + readout * v / (cam.height_px - 1)) + on_vehicle);
    }
    return poses;
}

/// Per-camera state carried from frame to frame within a traverse (the auto-exposure loop).
struct CameraState {
    double gain = 1;     ///< exposure gain the auto-exposure has reached
    double last_t = -1;  ///< time of the previous delivered frame [s], -1 = none
};

/// One camera frame: exposure (drift, flicker or auto-exposure), motion blur, rolling-shutter
/// row poses; the time stamp is set by the caller.
mrpt::obs::CObservationImage captureFrame(const common::PoseTrack& track, const CameraOptions& cam,
                                          const CameraRenderer& renderer, const Event& ev,
                                          double t0, uint32_t seed, bool blur,
                                          double ceiling_height_m, CameraState& state) {
    const mrpt::poses::CPose3D on_vehicle = cam.mount.pose();
    const double t = ev.t;
    FrameConditions fc;
    const uint32_t key =
        hash3(seed, static_cast<uint32_t>(ev.sensor), static_cast<uint32_t>(ev.index));
    // Slow exposure drift plus a small frame-to-frame flicker, on top of the auto-exposure.
    const double slow = 2 * valueNoise(t / 3.0, 0.5, seed + 17 * uint32_t(ev.sensor)).v - 1;
    fc.exposure_gain =
        state.gain * (1 + cam.exposure_variation * (0.8 * slow + 0.2 * (2 * unit(mix32(key)) - 1)));
    fc.noise_key = key;
    if (blur && cam.exposure_ms > 0) {
        // Image motion of the ceiling point on the optical axis during the exposure.
        const double half = 0.5e-3 * cam.exposure_ms;
        const mrpt::poses::CPose3D c0 = poseAt(track, t0 + t - half) + on_vehicle;
        const mrpt::poses::CPose3D c1 = poseAt(track, t0 + t + half) + on_vehicle;
        const double range = std::max(ceiling_height_m - c0.z(), 0.5);
        const mrpt::math::TPoint3D X = c0.composePoint(mrpt::math::TPoint3D(0, 0, range));
        const mrpt::math::TPoint3D p1 = c1.inverseComposePoint(X);
        const auto& K = renderer.intrinsics();
        fc.blur_u_px = K.fx() * p1.x / p1.z;
        fc.blur_v_px = K.fy() * p1.y / p1.z;
    }
    mrpt::obs::CObservationImage obs;
    obs.sensorLabel = cam.label;
    obs.cameraPose = on_vehicle;
    obs.cameraParams = renderer.intrinsics();
    FrameStats stats;
    if (cam.readout_ms > 0) {
        obs.image = renderer.render(rowPoses(track, cam, on_vehicle, t0 + t), fc, &stats);
    } else {
        obs.image = renderer.render(poseAt(track, t0 + t) + on_vehicle, fc, &stats);
    }
    if (cam.auto_exposure_target_dn > 0) {
        // First-order loop on the metered mean grey level: after a step in scene brightness
        // the gain closes the gap with time constant tau.
        const double dt = state.last_t < 0 ? 1.0 / cam.rate_hz : t - state.last_t;
        const double ratio = cam.auto_exposure_target_dn / std::max(stats.mean_dn, 1.0);
        state.gain =
            std::clamp(state.gain * std::pow(ratio, std::min(1.0, dt / cam.auto_exposure_tau_s)),
                       1.0 / 64, 64.0);
        state.last_t = t;
    }
    return obs;
}

/// Wheel odometry integrated on the vehicle, carried from record to record.
struct OdometryState {
    mrpt::poses::CPose2D odometry;   ///< accumulated, drifting
    mrpt::poses::CPose2D last_true;  ///< true pose at the previous record
    bool have_last = false;
    double last_t = 0;            ///< capture time of the previous record [s]
    double distance = 0;          ///< true distance so far [m]
    double last_z = 0;            ///< true height at the previous record [m]
    bool slope_distance = false;  ///< wheels measure the 3-D distance (a graded mine)
};

/// One odometry record: true increment with scale error (times slip_factor in a slip episode),
/// heading drift and noise; a vehicle standing still reads exactly zero.
mrpt::obs::CObservationOdometry odometryRecord(const OdometryOptions& o,
                                               const mrpt::poses::CPose3D& now3, const Event& ev,
                                               uint32_t seed, OdometryState& st) {
    const mrpt::poses::CPose2D now(now3);
    const double dz = now3.z() - st.last_z;
    st.last_z = now3.z();
    mrpt::obs::CObservationOdometry obs;
    obs.sensorLabel = o.label;
    obs.hasVelocities = true;
    if (!st.have_last) {
        st.last_true = now;
        st.have_last = true;
        st.last_t = ev.t;
        obs.odometry = st.odometry;
        return obs;
    }
    const mrpt::poses::CPose2D delta = now - st.last_true;
    const double dist = std::hypot(delta.x(), delta.y());
    const uint32_t key = hash3(seed, 2000 + ev.index, 11);
    double k = 1 + o.scale_error;
    if (st.slope_distance && dist > 0) k *= std::hypot(dist, dz) / dist;
    if (o.slip_fraction > 0) {
        const double cell = std::floor((st.distance + 0.5 * dist) / o.slip_episode_m);
        const uint32_t c = static_cast<uint32_t>(static_cast<int64_t>(cell));
        if (unit(hash3(seed, 6000, c)) < o.slip_fraction) k *= o.slip_factor;
    }
    st.distance += dist;
    mrpt::poses::CPose2D measured(0, 0, 0);
    if (dist > 0 || delta.phi() != 0) {
        measured = mrpt::poses::CPose2D(
            delta.x() * k + o.noise_std_m * gaussian(hash3(key, 1, 0), hash3(key, 2, 0)),
            delta.y() * k + o.noise_std_m * gaussian(hash3(key, 3, 0), hash3(key, 4, 0)),
            delta.phi() +
                mrpt::DEG2RAD(o.yaw_bias_deg_per_m * dist +
                              o.noise_std_deg * gaussian(hash3(key, 5, 0), hash3(key, 6, 0))));
    }
    st.odometry = st.odometry + measured;
    st.last_true = now;
    // Measured local velocities over the time since the previous record (one period unless
    // records were lost).
    const double periods = std::max(1.0, std::round((ev.t - st.last_t) * o.rate_hz));
    st.last_t = ev.t;
    obs.odometry = st.odometry;
    obs.velocityLocal.vx = measured.x() * o.rate_hz / periods;
    obs.velocityLocal.vy = measured.y() * o.rate_hz / periods;
    obs.velocityLocal.omega = measured.phi() * o.rate_hz / periods;
    return obs;
}

/// The inclinometer's pitch and roll at `vehicle`: the truth plus the traverse's constant bias
/// and per-record noise.
mrpt::obs::CObservationIMU imuRecord(const ImuOptions& o, const mrpt::poses::CPose3D& vehicle,
                                     const Event& ev, uint32_t seed) {
    const auto draw = [&](uint32_t a, uint32_t b) {
        return gaussian(hash3(seed, a, b), hash3(seed, a, b + 1));
    };
    mrpt::obs::CObservationIMU obs;
    obs.sensorLabel = o.label;
    const double bias_pitch = o.bias_std_deg * draw(7000, 0);
    const double bias_roll = o.bias_std_deg * draw(7000, 2);
    const uint32_t k = 2 * static_cast<uint32_t>(ev.index);
    obs.set(mrpt::obs::IMU_PITCH,
            vehicle.pitch() + mrpt::DEG2RAD(bias_pitch + o.noise_std_deg * draw(7100, k)));
    obs.set(mrpt::obs::IMU_ROLL,
            vehicle.roll() + mrpt::DEG2RAD(bias_roll + o.noise_std_deg * draw(7200, k)));
    return obs;
}

/// Every sensor on its own clock, in stamp order; ties are broken by sensor order so the file
/// order is fixed.
std::vector<Event> scheduleEvents(const CameraOptions& ceiling, const CameraOptions& forward,
                                  const LidarOptions& lidar, const OdometryOptions& odo,
                                  double duration, uint32_t seed) {
    std::vector<Event> events;
    auto never = [](double) { return false; };
    scheduleSensor(events, Sensor::Odometry, odo.rate_hz, odo.phase_s, odo.timing, duration, seed,
                   [&](double t) { return inDropout(odo, t, seed); });
    scheduleSensor(events, Sensor::Lidar, lidar.rate_hz, lidar.phase_s, lidar.timing, duration,
                   seed, never);
    scheduleSensor(events, Sensor::Ceiling, ceiling.rate_hz, ceiling.phase_s, ceiling.timing,
                   duration, seed, never);
    scheduleSensor(events, Sensor::Forward, forward.rate_hz, forward.phase_s, forward.timing,
                   duration, seed, never);
    std::stable_sort(events.begin(), events.end(), [](const Event& a, const Event& b) {
        return a.stamp < b.stamp || (a.stamp == b.stamp && a.sensor < b.sensor);
    });
    return events;
}

double trackLength(const common::PoseTrack& track) {
    double length = 0;
    for (std::size_t i = 1; i < track.size(); ++i) {
        length += std::hypot(track[i].pose.x() - track[i - 1].pose.x(),
                             track[i].pose.y() - track[i - 1].pose.y());
    }
    return length;
}

TraverseSummary startSummary(const TraverseOptions& tr, const common::PoseTrack& track) {
    TraverseSummary sum;
    sum.name = tr.name;
    sum.roles = tr.roles;
    sum.duration_s = track.back().time_s - track.front().time_s;
    sum.start_time_s = track.front().time_s;
    sum.ground_truth_rows = track.size();
    sum.length_m = trackLength(track);
    return sum;
}

/// Drives `legs` from route position `s` into `track` (which gets the start pose too):
/// `pose(s, s_limit, facing_back)` places the vehicle, `speed(s, from, to)` is the leg's speed.
template <typename PoseFn, typename SpeedFn>
void drivePlan(const std::vector<PlanLeg>& legs, double s, double length, double start_time_s,
               const PoseFn& pose, const SpeedFn& speed, common::PoseTrack* track) {
    bool facing_back = false;
    for (const PlanLeg& leg : legs) {  // the first motion fixes the facing (checked constant)
        if (leg.kind == PlanLeg::Kind::Stop || leg.value == s) continue;
        facing_back = (leg.value < s) == (leg.kind == PlanLeg::Kind::Drive);
        break;
    }
    double t = 0;
    track->push_back({start_time_s + t, pose(s, length, facing_back)});
    for (const PlanLeg& leg : legs) {
        if (leg.kind == PlanLeg::Kind::Stop) {
            for (long k = std::lround(leg.value / kTrackDt); k > 0; --k) {
                t += kTrackDt;
                track->push_back({start_time_s + t, pose(s, length, facing_back)});
            }
            continue;
        }
        const double from = s, to = std::clamp(leg.value, 0.0, length);
        const double sign = to > from ? 1 : -1;
        while (s != to) {
            const double v = speed(s + 0.5 * sign * speed(s, from, to) * kTrackDt, from, to);
            s = sign > 0 ? std::min(s + v * kTrackDt, to) : std::max(s - v * kTrackDt, to);
            t += kTrackDt;
            track->push_back({start_time_s + t, pose(s, length, facing_back)});
        }
    }
}

// Bounds of the error of the start and end poses lookup-sim hands the survey: a vehicle parked
// over a surveyed mark, aligned by eye with a painted line (docs/survey.md).
constexpr double kMarkErrorMaxM = 0.05;
constexpr double kMarkErrorMaxDeg = 0.1;

// "x y yaw_deg" of `p` with a seeded error within the bounds above, never the exact truth.
std::string operatorMark(const mrpt::poses::CPose3D& p, uint32_t seed) {
    const double r = kMarkErrorMaxM * (0.5 + 0.5 * unit(hash3(seed, 1, 0)));
    const double dir = 2 * M_PI * unit(hash3(seed, 2, 0));
    const double sign = unit(hash3(seed, 3, 0)) < 0.5 ? -1.0 : 1.0;
    const double dyaw = sign * kMarkErrorMaxDeg * (0.5 + 0.5 * unit(hash3(seed, 4, 0)));
    char buf[96];
    std::snprintf(buf, sizeof(buf), "%.3f %.3f %.3f", p.x() + r * std::cos(dir),
                  p.y() + r * std::sin(dir), mrpt::RAD2DEG(p.yaw()) + dyaw);
    return buf;
}

uint32_t markSeed(const ScenarioOptions& sc, uint32_t salt) {
    return hash3(static_cast<uint32_t>(sc.seed), static_cast<uint32_t>(sc.seed >> 32), salt);
}

// The operator's start pose of a traverse: its true pose at the first lidar scan, with an error.
std::string operatorStartPose(const ScenarioOptions& sc, const common::PoseTrack& track,
                              std::size_t index) {
    return operatorMark(poseAt(track, track.front().time_s + sc.lidar.phase_s),
                        markSeed(sc, 0x57a27u + uint32_t(index)));
}

// The operator's end pose: where the drive ends, the vehicle at rest over a second mark, with
// an error of its own.
std::string operatorEndPose(const ScenarioOptions& sc, const common::PoseTrack& track,
                            std::size_t index) {
    return operatorMark(poseAt(track, track.back().time_s),
                        markSeed(sc, 0xe4d5bu + uint32_t(index)));
}

// The operator's marks along the drive: the vehicle at rest over a surveyed mark at each stop
// between its first and last motion, "t x y yaw_deg" at the stop's middle, each with an error
// of its own.
std::string operatorDriveMarks(const ScenarioOptions& sc, const common::PoseTrack& track,
                               std::size_t index) {
    std::string marks;
    constexpr double kMinStop_s = 0.5;
    const auto at_rest = [&](std::size_t a, std::size_t b) {
        return (track[a].pose.translation() - track[b].pose.translation()).norm() < 1e-9;
    };
    for (std::size_t a = 1, count = 0; a + 1 < track.size(); ++a) {
        if (!at_rest(a - 1, a)) continue;
        std::size_t b = a;
        while (b + 1 < track.size() && at_rest(b, b + 1)) ++b;
        const bool interior = a > 1 && b + 1 < track.size();
        if (interior && track[b].time_s - track[a - 1].time_s >= kMinStop_s) {
            const double t = 0.5 * (track[a - 1].time_s + track[b].time_s);
            char time[32];
            std::snprintf(time, sizeof(time), "%.3f ", t);
            marks +=
                (marks.empty() ? "" : "; ") + std::string(time) +
                operatorMark(poseAt(track, t),
                             markSeed(sc, 0x3a7c5u + 4096u * uint32_t(index) + uint32_t(count++)));
        }
        a = b;
    }
    return marks;
}

/// A scan of `lidar`'s geometry with no ranges yet.
mrpt::obs::CObservation2DRangeScan emptyScan(const LidarOptions& lidar) {
    mrpt::obs::CObservation2DRangeScan scan;
    scan.sensorLabel = lidar.label;
    scan.aperture = static_cast<float>(mrpt::DEG2RAD(lidar.aperture_deg));
    scan.rightToLeft = true;
    scan.maxRange = static_cast<float>(lidar.max_range_m);
    scan.stdError = static_cast<float>(lidar.noise_std_m);
    scan.sensorPose = lidar.mount.pose();
    scan.resizeScan(
        static_cast<std::size_t>(std::lround(lidar.aperture_deg / lidar.resolution_deg)) + 1);
    return scan;
}

/// Ray r of `scan` from its first rock hit: dust, range noise, or invalid beyond range.
void setRange(mrpt::obs::CObservation2DRangeScan& scan, std::size_t r, SurfaceHit hit,
              const LidarOptions& lidar, uint32_t noise_key) {
    if (lidar.dust_rate > 0 && unit(hash3(noise_key, r, 3)) < lidar.dust_rate) {
        // Airborne dust returns the pulse early, uniformly along the beam's first metres.
        const double d = 0.3 + unit(hash3(noise_key, r, 4)) * (lidar.dust_max_range_m - 0.3);
        if (d < hit.t) {
            hit.t = d;
            hit.kind = SurfaceKind::Wall;
        }
    }
    if (hit.kind == SurfaceKind::None || !(hit.t < lidar.max_range_m)) {
        scan.setScanRange(r, scan.maxRange);
        scan.setScanRangeValidity(r, false);
        return;
    }
    const double noise =
        lidar.noise_std_m * gaussian(hash3(noise_key, r, 1), hash3(noise_key, r, 2));
    scan.setScanRange(r, static_cast<float>(std::max(0.0, hit.t + noise)));
    scan.setScanRangeValidity(r, true);
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
    if (sc.imu.activeIn(!sc.world.grade.empty())) f << "imu_label = " << sc.imu.label << "\n";
    // No ceiling height and no exact start or end: the survey measures the one and is given
    // the others as an operator would give them.
    bool start_written = false;
    for (std::size_t i = 0; i < sc.traverses.size(); ++i) {
        const auto& t = sc.traverses[i];
        f << "\n[traverse_" << i << "]\n"
          << "name = " << t.name << "\n"
          << "rawlog = " << t.name << ".rawlog\n"
          << "ground_truth = " << t.name << ".rawlog.GT.txt\n"
          << "roles = " << t.roles << "\n";
        if (!start_written && t.roles.find("mapping") != std::string::npos) {
            f << "start_pose = " << operatorStartPose(sc, tracks[i], i) << "\n"
              << "end_pose = " << operatorEndPose(sc, tracks[i], i) << "\n";
            if (t.marks_at_stops) f << "marks = " << operatorDriveMarks(sc, tracks[i], i) << "\n";
            start_written = true;
        }
    }
    if (!f) throw common::ConfigError(path + ": cannot write");
}

}  // namespace

mrpt::obs::CObservation2DRangeScan simulateLidar(const TunnelWorld& world,
                                                 const mrpt::poses::CPose2D& vehicle,
                                                 const LidarOptions& lidar, uint32_t noise_key,
                                                 const mrpt::poses::CPose2D* vehicle_at_end) {
    mrpt::obs::CObservation2DRangeScan scan = emptyScan(lidar);
    const std::size_t rays = scan.getScanSize();
    const mrpt::poses::CPose2D sensor = vehicle + mrpt::poses::CPose2D(scan.sensorPose);
    // A horizontal scan plane at the mount height; only the rock counts (walls, and the floor
    // or roof where the plane meets them), as for a 2-D scanner above the furniture's reach.
    const Eigen::Vector3d origin(sensor.x(), sensor.y(), lidar.mount.z_m);
    const double rad_per_ray = mrpt::DEG2RAD(lidar.resolution_deg);
    for (std::size_t r = 0; r < rays; ++r) {
        mrpt::poses::CPose2D ray_sensor = sensor;
        Eigen::Vector3d ray_origin = origin;
        if (vehicle_at_end) {
            // The sweep runs from the first ray to the last while the vehicle moves.
            const double a = r / static_cast<double>(rays - 1);
            const mrpt::poses::CPose2D v(
                vehicle.x() + a * (vehicle_at_end->x() - vehicle.x()),
                vehicle.y() + a * (vehicle_at_end->y() - vehicle.y()),
                vehicle.phi() + a * mrpt::math::wrapToPi(vehicle_at_end->phi() - vehicle.phi()));
            ray_sensor = v + mrpt::poses::CPose2D(scan.sensorPose);
            ray_origin = Eigen::Vector3d(ray_sensor.x(), ray_sensor.y(), lidar.mount.z_m);
        }
        const double angle = ray_sensor.phi() - scan.aperture / 2 +
                             r * scan.aperture / static_cast<double>(rays - 1);
        const Eigen::Vector3d dir(std::cos(angle), std::sin(angle), 0.0);
        setRange(scan, r, world.traceStatic(ray_origin, dir, 0.0, lidar.max_range_m, rad_per_ray),
                 lidar, noise_key);
    }
    return scan;
}

mrpt::obs::CObservation2DRangeScan simulateLidar(const TunnelWorld& world,
                                                 const mrpt::poses::CPose3D& vehicle,
                                                 const LidarOptions& lidar, uint32_t noise_key,
                                                 const mrpt::poses::CPose3D* vehicle_at_end) {
    if (!world.graded()) {
        const mrpt::poses::CPose2D end =
            vehicle_at_end ? mrpt::poses::CPose2D(*vehicle_at_end) : mrpt::poses::CPose2D();
        return simulateLidar(world, mrpt::poses::CPose2D(vehicle), lidar, noise_key,
                             vehicle_at_end ? &end : nullptr);
    }
    mrpt::obs::CObservation2DRangeScan scan = emptyScan(lidar);
    const std::size_t rays = scan.getScanSize();
    const mrpt::poses::CPose3D mount = lidar.mount.pose();
    const double rad_per_ray = mrpt::DEG2RAD(lidar.resolution_deg);
    for (std::size_t r = 0; r < rays; ++r) {
        // The scan plane is the scanner's x-y plane: on a grade, and where the grade changes
        // under the wheelbase, it meets the rock at an angle and may reach floor or roof.
        mrpt::poses::CPose3D v = vehicle;
        if (vehicle_at_end) {
            const double a = r / static_cast<double>(rays - 1);
            const mrpt::poses::CPose3D& e = *vehicle_at_end;
            auto lerp = [a](double x, double y) { return x + a * (y - x); };
            auto lerpAngle = [a](double x, double y) {
                return x + a * mrpt::math::wrapToPi(y - x);
            };
            v = mrpt::poses::CPose3D(lerp(v.x(), e.x()), lerp(v.y(), e.y()), lerp(v.z(), e.z()),
                                     lerpAngle(v.yaw(), e.yaw()), lerpAngle(v.pitch(), e.pitch()),
                                     lerpAngle(v.roll(), e.roll()));
        }
        const mrpt::poses::CPose3D sensor = v + mount;
        const double angle = -scan.aperture / 2 + r * scan.aperture / static_cast<double>(rays - 1);
        const Eigen::Vector3d dir = sensor.getRotationMatrix().asEigen() *
                                    Eigen::Vector3d(std::cos(angle), std::sin(angle), 0);
        const Eigen::Vector3d origin(sensor.x(), sensor.y(), sensor.z());
        setRange(scan, r, world.traceStatic(origin, dir, 0.0, lidar.max_range_m, rad_per_ray),
                 lidar, noise_key);
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
    // Cruise speed with its slow wobble, limited by accelerating from `from` and braking to `to`.
    auto legSpeed = [&](double s, double from, double to) {
        const double sign = to >= from ? 1.0 : -1.0;
        const double wobble = 2 * fbm(s / 60.0, 0.5, seed, 2, 1.0, 0.5, 0).v - 1;
        double v = v_cruise * (1 + tr.speed_variation * std::clamp(2.0 * wobble, -1.0, 1.0));
        v = std::min(
            v, std::sqrt(v_min * v_min + 2 * tr.accel_mps2 * std::max(sign * (s - from), 0.0)));
        v = std::min(v,
                     std::sqrt(v_min * v_min + 2 * tr.accel_mps2 * std::max(sign * (to - s), 0.0)));
        return std::max(v, v_min);
    };
    // The vehicle on the floor at route position s, facing along the route or against it.
    auto poseAtS = [&](double s, double s_lim, bool facing_back) {
        const Vector2d p = path(s);
        const Vector2d ahead = path(std::min(s + 0.2, s_lim + 0.2)) - path(s - 0.2);
        double yaw = std::atan2(ahead.y(), ahead.x());
        if (facing_back) yaw = mrpt::math::wrapToPi(yaw + M_PI);
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
        return mrpt::poses::CPose3D(p.x(), p.y(), 0.25 * (zf + zr + zl + zri), yaw, pitch, roll);
    };
    common::PoseTrack track;
    double s = s_begin, t = 0;
    if (tr.plan.empty() && tr.direction != "reverse") {
        for (;;) {
            track.push_back({start_time_s + t, poseAtS(s, s_end, false)});
            if (s >= s_end) break;
            const double v = legSpeed(s + 0.5 * legSpeed(s, s_begin, s_end) * kTrackDt, s_begin,
                                      s_end);  // midpoint rule
            s = std::min(s + v * kTrackDt, s_end);
            t += kTrackDt;
        }
        return track;
    }
    std::vector<PlanLeg> legs;
    if (tr.plan.empty()) {
        s = s_end;  // reverse direction: end to start, facing the way of travel
        legs.push_back({PlanLeg::Kind::Drive, s_begin});
    } else {
        legs = parsePlan(tr.plan);
        for (auto& leg : legs) {
            if (std::isinf(leg.value)) leg.value = s_end;
        }
    }
    drivePlan(legs, s, length, start_time_s, poseAtS, legSpeed, &track);
    return track;
}

Simulator::Simulator(ScenarioOptions scenario) : scenario_(std::move(scenario)) {
    scenario_.check();
    world_ = std::make_unique<TunnelWorld>(scenario_.world, scenario_.seed);
    checkPlansOnRoute();
    checkLenses();
    double next = scenario_.start_time_s;
    for (std::size_t i = 0; i < scenario_.traverses.size(); ++i) {
        const double t0 = std::max(scenario_.start_time_s + i * scenario_.traverse_gap_s, next);
        tracks_.push_back(
            vehicleTrack(*world_, scenario_.traverses[i], scenario_.vehicleFor(i), t0));
        next = std::ceil(tracks_.back().back().time_s + 10.0);
        // Another day's look of the same mine: the same geometry and seed, other appearance.
        traverse_worlds_.push_back(
            scenario_.traverses[i].world
                ? std::make_unique<TunnelWorld>(*scenario_.traverses[i].world, scenario_.seed)
                : nullptr);
    }
    noteSpeedsNotReached();
}

void Simulator::noteSpeedsNotReached() {
    constexpr std::size_t kSpan = 50;  // speeds over 0.5 s of ground truth
    for (std::size_t i = 0; i < tracks_.size(); ++i) {
        const TraverseOptions& tr = scenario_.traverses[i];
        const common::PoseTrack& track = tracks_[i];
        if (!tr.plan.empty() || track.size() <= kSpan) continue;
        double peak = 0;
        for (std::size_t k = kSpan; k < track.size(); ++k) {
            const auto& a = track[k - kSpan];
            const auto& b = track[k];
            peak = std::max(peak, std::hypot(b.pose.x() - a.pose.x(), b.pose.y() - a.pose.y()) /
                                      (b.time_s - a.time_s));
        }
        if (3.6 * peak >= 0.9 * tr.speed_kmh) continue;
        char line[320];
        std::snprintf(line, sizeof line,
                      "%s [%s] speed_kmh %.0f is never reached: from rest to a stop at "
                      "accel_mps2 %.2f over its %.0f m the vehicle reaches %.0f km/h at most "
                      "(a longer world.length_m or a larger accel_mps2)",
                      scenario_.source_name.c_str(), ("traverse_" + std::to_string(i)).c_str(),
                      tr.speed_kmh, tr.accel_mps2, trackLength(track), 3.6 * peak);
        warnings_.push_back(line);
    }
}

void Simulator::checkLenses() const {
    auto probe = [&](const CameraOptions& cam, const std::string& section) {
        if (cam.distortion == "none") return;
        try {
            const CameraRenderer renderer(*world_, cam, CameraRenderer::Kind::Ceiling, 1);
        } catch (const std::exception& e) {
            throw common::ConfigError(scenario_.source_name + " [" + section +
                                      "] distortion: " + e.what());
        }
    };
    probe(scenario_.ceiling_camera, "ceiling_camera");
    probe(scenario_.forward_camera, "forward_camera");
    for (std::size_t i = 0; i < scenario_.traverses.size(); ++i) {
        const TraverseOptions& t = scenario_.traverses[i];
        const std::string p = "traverse_" + std::to_string(i) + ".";
        if (t.ceiling_camera) probe(*t.ceiling_camera, p + "ceiling_camera");
        if (t.forward_camera) probe(*t.forward_camera, p + "forward_camera");
    }
}

void Simulator::checkPlansOnRoute() const {
    const double length = world_->routeLength();
    for (std::size_t i = 0; i < scenario_.traverses.size(); ++i) {
        const TraverseOptions& t = scenario_.traverses[i];
        if (t.plan.empty()) continue;
        const std::vector<PlanLeg> legs = parsePlan(t.plan);
        for (std::size_t k = 0; k < legs.size(); ++k) {
            if (legs[k].kind == PlanLeg::Kind::Stop || legs[k].value <= length ||
                std::isinf(legs[k].value)) {
                continue;
            }
            std::ostringstream os;
            os << scenario_.source_name << " [traverse_" << i << "] plan: leg " << k + 1 << " ("
               << (legs[k].kind == PlanLeg::Kind::Drive ? "drive " : "reverse ") << legs[k].value
               << ") leaves the route, which is " << std::fixed << std::setprecision(1) << length
               << " m long";
            throw common::ConfigError(os.str());
        }
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
    (void)grid;
    const auto start = std::chrono::steady_clock::now();
    const TraverseOptions& tr = scenario_.traverses[index];
    const common::PoseTrack& track = tracks_[index];
    const double t0 = track.front().time_s;
    const double duration = track.back().time_s - t0;
    const uint32_t seed =
        hash3(static_cast<uint32_t>(scenario_.seed), static_cast<uint32_t>(scenario_.seed >> 32),
              static_cast<uint32_t>(index) + 1);
    TraverseSummary sum = startSummary(tr, track);

    const std::string stem = out_dir + "/" + tr.name;
    std::error_code ec;
    fs::remove_all(stem + "_Images", ec);  // no stale frames from an earlier run
    common::writeMrptPoseFile(stem + ".rawlog.GT.txt", track);

    const CameraOptions& ceiling_opt = scenario_.ceilingCameraFor(index);
    const CameraOptions& forward_opt = scenario_.forwardCameraFor(index);
    const LidarOptions& lidar_opt = scenario_.lidarFor(index);
    const OdometryOptions& odo_opt = scenario_.odometryFor(index);
    const std::vector<Event> events =
        scheduleEvents(ceiling_opt, forward_opt, lidar_opt, odo_opt, duration, seed);

    const TunnelWorld& seen = traverse_worlds_[index] ? *traverse_worlds_[index] : *world_;
    const CameraRenderer ceiling(seen, ceiling_opt, CameraRenderer::Kind::Ceiling,
                                 scenario_.threads);
    const CameraRenderer forward(seen, forward_opt, CameraRenderer::Kind::Forward,
                                 scenario_.threads);
    CameraState cam_state[2];
    OdometryState odo_state;

    common::RawlogWriter writer(stem + ".rawlog");
    std::size_t done = 0, last_report = 0;
    for (const Event& ev : events) {
        const double t_abs = t0 + ev.t;
        const mrpt::poses::CPose3D vehicle = poseAt(track, t_abs);
        const auto stamp = mrpt::Clock::fromDouble(t0 + ev.stamp);
        switch (ev.sensor) {
            case Sensor::Ceiling:
            case Sensor::Forward: {
                const bool is_ceiling = ev.sensor == Sensor::Ceiling;
                const double roof_z = world_->graded() ? scenario_.world.ceiling_height_m +
                                                             world_->level(vehicle.x(), vehicle.y())
                                                       : scenario_.world.ceiling_height_m;
                mrpt::obs::CObservationImage obs = captureFrame(
                    track, is_ceiling ? ceiling_opt : forward_opt, is_ceiling ? ceiling : forward,
                    ev, t0, seed, is_ceiling, roof_z, cam_state[is_ceiling ? 0 : 1]);
                obs.timestamp = stamp;
                writer.writeWithExternalImage(obs, frameName(obs.sensorLabel, ev.index));
                (is_ceiling ? sum.ceiling_frames : sum.forward_frames)++;
                break;
            }
            case Sensor::Lidar: {
                const mrpt::poses::CPose3D at_end =
                    poseAt(track, t_abs + 1e-3 * lidar_opt.sweep_ms);
                mrpt::obs::CObservation2DRangeScan scan =
                    simulateLidar(*world_, vehicle, lidar_opt, hash3(seed, 1000 + ev.index, 7),
                                  lidar_opt.sweep_ms > 0 ? &at_end : nullptr);
                scan.timestamp = stamp;
                writer.write(scan);
                sum.lidar_scans++;
                break;
            }
            case Sensor::Odometry: {
                // On a grade the wheels roll the distance along the slope.
                odo_state.slope_distance = world_->graded();
                mrpt::obs::CObservationOdometry obs =
                    odometryRecord(odo_opt, vehicle, ev, seed, odo_state);
                obs.timestamp = stamp;
                writer.write(obs);
                sum.odometry_records++;
                if (scenario_.imu.activeIn(world_->graded())) {
                    mrpt::obs::CObservationIMU imu = imuRecord(scenario_.imu, vehicle, ev, seed);
                    imu.timestamp = stamp;
                    writer.write(imu);
                }
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

#include "lookup/survey/traverse.h"

#include "lookup/survey/scan_deskew.h"

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <optional>

#include "lookup/common/camera_params.h"
#include "lookup/common/rawlog_io.h"

namespace lookup::survey {
namespace {

std::string listLabels(const std::set<std::string>& labels) {
    std::string s;
    for (const auto& l : labels) s += (s.empty() ? "" : ", ") + l;
    return s.empty() ? "none" : s;
}

bool finitePose(const mrpt::poses::CPose3D& p) {
    return std::isfinite(p.x()) && std::isfinite(p.y()) && std::isfinite(p.z()) &&
           std::isfinite(p.yaw()) && std::isfinite(p.pitch()) && std::isfinite(p.roll());
}

// Makes non-finite or negative ranges invalid (counted in `skipped`); returns why the whole
// scan is unusable, or "".
std::string sanitiseScan(mrpt::obs::CObservation2DRangeScan& scan, SkippedRecords& skipped) {
    if (!finitePose(scan.sensorPose)) return "lidar mounting pose is not finite";
    if (!std::isfinite(scan.aperture) || !(scan.aperture > 0)) return "lidar aperture not > 0";
    if (!std::isfinite(scan.maxRange) || !(scan.maxRange > 0)) return "lidar maxRange not > 0";
    std::size_t usable = 0;
    for (std::size_t i = 0; i < scan.getScanSize(); ++i) {
        const float r = scan.getScanRange(i);
        if (!std::isfinite(r) || r < 0) {
            // Zero as well as invalid: some MRPT map insertions read invalid ranges too.
            scan.setScanRange(i, 0.0f);
            scan.setScanRangeValidity(i, false);
            ++skipped.lidar_ranges;
        } else if (scan.getScanRangeValidity(i)) {
            ++usable;
        }
    }
    return usable == 0 ? "no finite lidar range" : "";
}

std::string odometryProblem(const mrpt::obs::CObservationOdometry& odo) {
    const auto& p = odo.odometry;
    if (!std::isfinite(p.x()) || !std::isfinite(p.y()) || !std::isfinite(p.phi())) {
        return "odometry pose is not finite";
    }
    const auto& v = odo.velocityLocal;
    if (odo.hasVelocities &&
        (!std::isfinite(v.vx) || !std::isfinite(v.vy) || !std::isfinite(v.omega))) {
        return "odometry velocity is not finite";
    }
    return "";
}

/// The vehicle's attitude from an inclinometer reading, its mount's tilt taken off (small
/// angles); nullopt without a finite pitch and roll.
std::optional<Attitude> attitudeOf(const mrpt::obs::CObservationIMU& imu) {
    using mrpt::obs::IMU_PITCH, mrpt::obs::IMU_ROLL;
    if (!imu.has(IMU_PITCH) || !imu.has(IMU_ROLL)) return std::nullopt;
    const double pitch = imu.get(IMU_PITCH) - imu.sensorPose.pitch();
    const double roll = imu.get(IMU_ROLL) - imu.sensorPose.roll();
    if (!std::isfinite(pitch) || !std::isfinite(roll)) return std::nullopt;
    return Attitude{pitch, roll};
}

void noteSkip(SkippedRecords& skipped, const std::string& rawlog, std::size_t record,
              const std::string& reason) {
    if (skipped.first.empty()) {
        skipped.first = rawlog + ": record " + std::to_string(record) + ": " + reason;
    }
}

}  // namespace

std::string intrinsicsProblem(const mrpt::obs::CObservationImage& image) {
    const auto& c = image.cameraParams;
    if (!std::isfinite(c.fx()) || !std::isfinite(c.fy()) || !(c.fx() > 0) || !(c.fy() > 0)) {
        return "focal length fx=" + std::to_string(c.fx()) + " fy=" + std::to_string(c.fy()) +
               " is not finite and > 0";
    }
    if (!std::isfinite(c.cx()) || !std::isfinite(c.cy())) return "principal point is not finite";
    if (c.ncols == 0 || c.nrows == 0) return "image size in the intrinsics is zero";
    for (double d : c.dist) {
        if (!std::isfinite(d)) return "distortion is not finite";
    }
    if (const std::string why = common::cameraProblem(c); !why.empty()) return why;
    if (!finitePose(image.cameraPose)) return "camera mounting pose is not finite";
    return "";
}

TraverseData readTraverse(const std::string& rawlog, const SurveyOptions& options,
                          bool need_laser) {
    TraverseData t;
    t.rawlog = rawlog;
    AttitudeTrack attitude;
    common::RawlogReader reader(rawlog);
    std::map<std::string, double> last_time;  // per label
    mrpt::obs::CObservation::Ptr o;
    while (reader.next(o)) {
        const std::size_t record = reader.recordIndex();
        t.labels.insert(o->sensorLabel);
        const double time = mrpt::Clock::toDouble(o->timestamp);
        if (auto it = last_time.find(o->sensorLabel); it != last_time.end() && time < it->second) {
            throw common::RawlogError(rawlog, record,
                                      "non-monotonic time stamp for " + o->sensorLabel + ": " +
                                          std::to_string(time) + " s after " +
                                          std::to_string(it->second) + " s");
        }
        last_time[o->sensorLabel] = time;

        const bool is_ceiling = o->sensorLabel == options.ceiling_camera_label;
        const bool is_forward =
            !options.forward_camera_label.empty() && o->sensorLabel == options.forward_camera_label;
        if (is_ceiling || is_forward) {
            auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(o);
            if (!img) {
                throw common::RawlogError(rawlog, record,
                                          o->sensorLabel + " is a " +
                                              o->GetRuntimeClass()->className +
                                              ", expected CObservationImage");
            }
            if (img->image.isExternallyStored()) {
                const std::string file = img->image.getExternalStorageFileAbsolutePath();
                if (!std::filesystem::is_regular_file(file)) {
                    throw common::RawlogError(rawlog, record, "missing external image " + file);
                }
            }
            if (const std::string why = intrinsicsProblem(*img); !why.empty()) {
                ++(is_ceiling ? t.skipped.ceiling_intrinsics : t.skipped.forward_intrinsics);
                noteSkip(t.skipped, rawlog, record, o->sensorLabel + ": " + why);
                continue;
            }
            if (is_ceiling) {
                t.ceiling.push_back(img);
                t.ceiling_records.push_back(record);
            } else {
                t.forward.push_back(img);
            }
        } else if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o);
                   scan && o->sensorLabel == options.lidar_label) {
            const std::size_t before = t.skipped.lidar_ranges;
            if (const std::string why = sanitiseScan(*scan, t.skipped); !why.empty()) {
                ++t.skipped.scans;
                noteSkip(t.skipped, rawlog, record, o->sensorLabel + ": " + why);
                continue;
            }
            if (t.skipped.lidar_ranges > before) {
                noteSkip(t.skipped, rawlog, record,
                         o->sensorLabel + ": " + std::to_string(t.skipped.lidar_ranges - before) +
                             " non-finite or negative ranges made invalid");
            }
            t.laser_sequence.push_back(o);
            ++t.scan_count;
        } else if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o);
                   odo && o->sensorLabel == options.odometry_label) {
            if (const std::string why = odometryProblem(*odo); !why.empty()) {
                ++t.skipped.odometry;
                noteSkip(t.skipped, rawlog, record, o->sensorLabel + ": " + why);
                continue;
            }
            t.laser_sequence.push_back(o);
            ++t.odometry_count;
        } else if (auto imu = std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(o);
                   imu && !options.imu_label.empty() && o->sensorLabel == options.imu_label) {
            const auto a = attitudeOf(*imu);
            if (!a) {
                ++t.skipped.imu;
                noteSkip(t.skipped, rawlog, record, o->sensorLabel + ": no finite pitch and roll");
                continue;
            }
            attitude.add(time, *a);
        }
    }
    if (t.ceiling.empty() && t.skipped.ceiling_intrinsics > 0) {
        throw common::RawlogError(rawlog, "every " + options.ceiling_camera_label +
                                              " image refused (first: " + t.skipped.first + ")");
    }
    if (t.ceiling.empty()) {
        throw common::RawlogError(rawlog, "no CObservationImage labelled '" +
                                              options.ceiling_camera_label +
                                              "' (labels present: " + listLabels(t.labels) + ")");
    }
    if (need_laser && t.scan_count == 0) {
        throw common::RawlogError(rawlog, "no CObservation2DRangeScan labelled '" +
                                              options.lidar_label +
                                              "' (labels present: " + listLabels(t.labels) + ")");
    }
    if (need_laser && t.odometry_count == 0) {
        throw common::RawlogError(rawlog, "no CObservationOdometry labelled '" +
                                              options.odometry_label +
                                              "' (labels present: " + listLabels(t.labels) + ")");
    }
    t.levelling = levelTraverse(t, attitude, options.max_pose_gap_s, options.floor_return_margin_m,
                                options.roof_return_margin_m);
    t.scans_deskewed = deskewTraverse(t, 1e-3 * options.lidar_sweep_ms);
    return t;
}

}  // namespace lookup::survey

#pragma once
// One survey traverse read from its rawlog: the ceiling and forward images (headers only;
// pixels stay on disk), and the odometry + lidar sequence the laser stage consumes.

#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservationImage.h>

#include <set>
#include <string>
#include <vector>

#include "lookup/survey/levelling.h"
#include "lookup/survey/survey_options.h"

namespace lookup::survey {

/// Sensor data the survey refused while reading a traverse, by reason (none of it reaches the
/// laser stage or the database).
struct SkippedRecords {
    std::size_t lidar_ranges = 0;        ///< non-finite or negative ranges made invalid
    std::size_t scans = 0;               ///< scans dropped: no usable range or bad geometry
    std::size_t odometry = 0;            ///< odometry with a non-finite pose or velocity
    std::size_t imu = 0;                 ///< inclinometer readings without finite pitch and roll
    std::size_t ceiling_intrinsics = 0;  ///< ceiling images with unusable intrinsics/mount
    std::size_t forward_intrinsics = 0;  ///< forward images with unusable intrinsics/mount
    std::string first;                   ///< the first one: "<rawlog>: record N: reason"

    std::size_t records() const {
        return scans + odometry + imu + ceiling_intrinsics + forward_intrinsics;
    }
};

/// Why camera intrinsics or a mounting pose cannot be used ("" = usable): non-finite or
/// non-positive focal lengths, a zero image size, a non-finite principal point or distortion.
std::string intrinsicsProblem(const mrpt::obs::CObservationImage& image);

struct TraverseData {
    std::string rawlog;                                      ///< path of the rawlog
    std::vector<mrpt::obs::CObservationImage::Ptr> ceiling;  ///< in time order
    std::vector<std::size_t> ceiling_records;                ///< rawlog record of each
    std::vector<mrpt::obs::CObservationImage::Ptr> forward;  ///< in time order
    /// CObservationOdometry and CObservation2DRangeScan with the configured labels, in order.
    std::vector<mrpt::obs::CObservation::Ptr> laser_sequence;
    std::size_t scan_count = 0;
    std::size_t odometry_count = 0;
    std::size_t scans_deskewed = 0;  ///< scans redrawn for the motion over the sweep
    LevellingReport levelling;       ///< odometry and scans projected onto the horizontal
    std::set<std::string> labels;    ///< every sensor label seen
    SkippedRecords skipped;          ///< refused sensor data
};

/// Reads `rawlog`. Throws common::RawlogError naming the file, record and reason when the
/// rawlog is unreadable or truncated, when a labelled sensor's time stamps go backwards, when an
/// external image file is missing, or when the ceiling camera (or, with `need_laser`, the lidar
/// or odometry) label is absent — then the message lists the labels present. Non-finite sensor
/// data is refused and counted in TraverseData::skipped: NaN/inf/negative lidar ranges become
/// invalid returns (a scan with none left, or with a non-finite pose or aperture, is dropped),
/// odometry with a non-finite pose or velocity is dropped, images with unusable intrinsics are
/// dropped. With inclinometer readings (options.imu_label), odometry and scans are levelled
/// (levelling.h) before the scans are de-skewed.
TraverseData readTraverse(const std::string& rawlog, const SurveyOptions& options, bool need_laser);

}  // namespace lookup::survey

#pragma once
// One survey traverse read from its rawlog: the ceiling and forward images (headers only;
// pixels stay on disk), and the odometry + lidar sequence the laser stage consumes.

#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservationImage.h>

#include <set>
#include <string>
#include <vector>

#include "lookup/survey/survey_options.h"

namespace lookup::survey {

struct TraverseData {
    std::string rawlog;                                      ///< path of the rawlog
    std::vector<mrpt::obs::CObservationImage::Ptr> ceiling;  ///< in time order
    std::vector<std::size_t> ceiling_records;                ///< rawlog record of each
    std::vector<mrpt::obs::CObservationImage::Ptr> forward;  ///< in time order
    /// CObservationOdometry and CObservation2DRangeScan with the configured labels, in order.
    std::vector<mrpt::obs::CObservation::Ptr> laser_sequence;
    std::size_t scan_count = 0;
    std::size_t odometry_count = 0;
    std::set<std::string> labels;  ///< every sensor label seen
};

/// Reads `rawlog`. Throws common::RawlogError naming the file, record and reason when the
/// rawlog is unreadable or truncated, when a labelled sensor's time stamps go backwards, when an
/// external image file is missing, or when the ceiling camera (or, with `need_laser`, the lidar
/// or odometry) label is absent — then the message lists the labels present.
TraverseData readTraverse(const std::string& rawlog, const SurveyOptions& options, bool need_laser);

}  // namespace lookup::survey

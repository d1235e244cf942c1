#include "lookup/survey/traverse.h"

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <filesystem>
#include <map>

#include "lookup/common/rawlog_io.h"

namespace lookup::survey {
namespace {

std::string listLabels(const std::set<std::string>& labels) {
    std::string s;
    for (const auto& l : labels) s += (s.empty() ? "" : ", ") + l;
    return s.empty() ? "none" : s;
}

}  // namespace

TraverseData readTraverse(const std::string& rawlog, const SurveyOptions& options,
                          bool need_laser) {
    TraverseData t;
    t.rawlog = rawlog;
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
            if (is_ceiling) {
                t.ceiling.push_back(img);
                t.ceiling_records.push_back(record);
            } else {
                t.forward.push_back(img);
            }
        } else if (o->sensorLabel == options.lidar_label &&
                   std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            t.laser_sequence.push_back(o);
            ++t.scan_count;
        } else if (std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o) &&
                   o->sensorLabel == options.odometry_label) {
            t.laser_sequence.push_back(o);
            ++t.odometry_count;
        }
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
    return t;
}

}  // namespace lookup::survey

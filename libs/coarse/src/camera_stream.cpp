#include "lookup/coarse/camera_stream.h"

#include <mrpt/obs/CObservationOdometry.h>

#include "lookup/common/odometry_track.h"

namespace lookup::coarse {

CameraFrameStream::CameraFrameStream(const std::string& rawlog_path, std::string camera_label,
                                     std::string odometry_label)
    : reader_(rawlog_path),
      camera_label_(std::move(camera_label)),
      odometry_label_(std::move(odometry_label)) {}

bool CameraFrameStream::next(CameraFrame& frame) {
    mrpt::obs::CObservation::Ptr obs;
    while (reader_.next(obs)) {
        labels_seen_.emplace(obs->sensorLabel, obs->GetRuntimeClass()->className);
        if (!odometry_label_.empty() && obs->sensorLabel == odometry_label_) {
            if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(obs)) {
                odometry_now_ = odo->odometry;
            }
            continue;
        }
        if (obs->sensorLabel != camera_label_) continue;
        auto image = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(obs);
        if (!image) {
            throw common::RawlogError(reader_.path(), reader_.recordIndex(),
                                      "observation labelled '" + camera_label_ + "' is a " +
                                          obs->GetRuntimeClass()->className +
                                          ", not a CObservationImage");
        }
        int width = 0, height = 0;
        try {
            image->image.forceLoad();
            width = static_cast<int>(image->image.getWidth());
            height = static_cast<int>(image->image.getHeight());
        } catch (const std::exception& e) {
            throw common::RawlogError(reader_.path(), reader_.recordIndex(),
                                      std::string("cannot load the image: ") + e.what());
        }
        if (width <= 0 || height <= 0) {
            throw common::RawlogError(reader_.path(), reader_.recordIndex(), "empty image");
        }
        if (frames_ == 0) {
            width_ = width;
            height_ = height;
        } else if (width != width_ || height != height_) {
            throw common::RawlogError(reader_.path(), reader_.recordIndex(),
                                      "image is " + std::to_string(width) + "x" +
                                          std::to_string(height) + " but the first '" +
                                          camera_label_ + "' image is " + std::to_string(width_) +
                                          "x" + std::to_string(height_));
        }
        frame.record = reader_.recordIndex();
        frame.index = frames_++;
        frame.time_s = mrpt::Clock::toDouble(image->timestamp);
        frame.observation = image;
        frame.travelled_m.reset();
        if (odometry_now_) {
            if (odometry_at_last_frame_) {
                frame.travelled_m = common::signedTravel(*odometry_at_last_frame_, *odometry_now_);
            }
            odometry_at_last_frame_ = odometry_now_;
        }
        return true;
    }
    if (frames_ == 0) {
        std::string present;
        for (const auto& [label, cls] : labels_seen_) {
            present += (present.empty() ? "" : ", ") + label + " (" + cls + ")";
        }
        throw common::RawlogError(
            reader_.path(),
            "no CObservationImage labelled '" + camera_label_ +
                "'; labels present: " + (present.empty() ? "none (empty rawlog)" : present));
    }
    return false;
}

}  // namespace lookup::coarse

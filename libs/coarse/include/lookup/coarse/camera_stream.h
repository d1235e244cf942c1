#pragma once
// Streams the images of one camera from a rawlog, with the distance travelled between them
// when the rawlog carries wheel odometry: what an online coarse localiser sees.

#include <mrpt/obs/CObservationImage.h>
#include <mrpt/poses/CPose2D.h>

#include <cstddef>
#include <map>
#include <optional>
#include <string>

#include "lookup/common/rawlog_io.h"

namespace lookup::coarse {

struct CameraFrame {
    std::size_t record = 0;  ///< rawlog entry index (as RawLogViewer)
    std::size_t index = 0;   ///< index among this camera's frames
    double time_s = 0;       ///< time stamp [s] (mrpt::Clock::toDouble)
    mrpt::obs::CObservationImage::Ptr observation;
    /// Odometry distance since the previous frame of this camera [m], negative while reversing
    /// (common::signedTravel); empty for the first frame and when the rawlog has no odometry
    /// with the configured label.
    std::optional<double> travelled_m;
};

class CameraFrameStream {
  public:
    /// `odometry_label` empty: odometry ignored.
    CameraFrameStream(const std::string& rawlog_path, std::string camera_label,
                      std::string odometry_label = "ODOMETRY");

    /// Next image of the camera; false at the end. Throws common::RawlogError naming the file
    /// (and record) when the rawlog ends without any image of the label (the message lists the
    /// labels that are present), when an image cannot be loaded, or when its size differs from
    /// the first image's.
    bool next(CameraFrame& frame);

    const std::string& path() const { return reader_.path(); }
    int imageWidth() const { return width_; }
    int imageHeight() const { return height_; }

  private:
    common::RawlogReader reader_;
    std::string camera_label_;
    std::string odometry_label_;
    std::size_t frames_ = 0;
    int width_ = 0;
    int height_ = 0;
    std::optional<mrpt::poses::CPose2D> odometry_now_;
    std::optional<mrpt::poses::CPose2D> odometry_at_last_frame_;
    std::map<std::string, std::string> labels_seen_;  ///< label -> class name
};

}  // namespace lookup::coarse

#pragma once
// Every stage matches, describes and learns on grey images, while cameras and image files may
// deliver colour: one conversion for all of them.

#include <opencv2/core/mat.hpp>

namespace lookup::common {

/// `image` as one channel: the same pixels (shared, not copied) when it already has one, else
/// converted from OpenCV's BGR or BGRA order. The depth is kept; an empty image stays empty.
/// Throws std::invalid_argument for another number of channels.
cv::Mat greyOf(const cv::Mat& image);

}  // namespace lookup::common

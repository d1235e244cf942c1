#pragma once
// Every stage matches, describes and learns on grey images, while cameras and image files may
// deliver colour: one conversion for all of them.

#include <opencv2/core/mat.hpp>

namespace lookup::common {

/// `image` as one channel: the same pixels (shared, not copied) when it already has one, else
/// converted from OpenCV's BGR or BGRA order. The depth is kept; an empty image stays empty.
/// Throws std::invalid_argument for another number of channels.
cv::Mat greyOf(const cv::Mat& image);

/// `image` averaged down (cv::INTER_AREA) to `max_width` columns, its aspect kept (cappedSize),
/// as the database stores ceiling images; `image` itself when no wider or `max_width` <= 0.
cv::Mat averagedDownTo(const cv::Mat& image, int max_width);

/// The standard deviation of `image`'s pixel noise (one channel, any depth), estimated from
/// the response to a Laplacian-difference mask that texture smoother than a pixel barely excites
/// (Immerkaer, "Fast noise variance estimation", 1996): sharp texture adds to it.
double noiseSigma(const cv::Mat& image);

}  // namespace lookup::common

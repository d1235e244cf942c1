#include "lookup/survey/image_quality.h"

#include <opencv2/imgproc.hpp>

#include "lookup/common/grey.h"

namespace lookup::survey {

ImageQuality measureImageQuality(const cv::Mat& image) {
    ImageQuality q;
    if (image.empty()) return q;
    const cv::Mat grey = common::greyOf(image);
    cv::Mat lap;
    cv::Laplacian(grey, lap, CV_64F);
    cv::Scalar mean, stddev;
    cv::meanStdDev(lap, mean, stddev);
    q.sharpness = stddev[0] * stddev[0];
    q.mean_intensity = cv::mean(grey)[0];
    const double clipped = cv::countNonZero(grey <= 2) + cv::countNonZero(grey >= 253);
    q.clipped_fraction = clipped / static_cast<double>(grey.total());
    return q;
}

}  // namespace lookup::survey

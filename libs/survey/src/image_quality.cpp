#include "lookup/survey/image_quality.h"

#include <algorithm>
#include <opencv2/imgproc.hpp>

#include "lookup/common/grey.h"

namespace lookup::survey {

ImageQuality measureImageQuality(const cv::Mat& image, int max_width_px) {
    ImageQuality q;
    if (image.empty()) return q;
    // Judged as the database stores it and the matcher sees it: the variance of the Laplacian
    // of one scene falls as the resolution grows, so a camera's pixel count must not decide.
    const cv::Mat grey = common::averagedDownTo(common::greyOf(image), max_width_px);
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

ImageQuality medianQuality(const std::vector<ImageQuality>& images) {
    ImageQuality m;
    if (images.empty()) return m;
    auto median = [&](double ImageQuality::*field) {
        std::vector<double> v;
        for (const auto& q : images) v.push_back(q.*field);
        std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
        return v[v.size() / 2];
    };
    m.sharpness = median(&ImageQuality::sharpness);
    m.mean_intensity = median(&ImageQuality::mean_intensity);
    m.clipped_fraction = median(&ImageQuality::clipped_fraction);
    return m;
}

}  // namespace lookup::survey

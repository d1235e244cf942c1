#include "lookup/common/grey.h"

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <stdexcept>
#include <string>

#include "lookup/common/camera_params.h"

namespace lookup::common {

cv::Mat greyOf(const cv::Mat& image) {
    cv::Mat grey;
    switch (image.channels()) {
        case 1:
            grey = image;
            break;
        case 3:
            cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
            break;
        case 4:
            cv::cvtColor(image, grey, cv::COLOR_BGRA2GRAY);
            break;
        default:
            throw std::invalid_argument("an image of " + std::to_string(image.channels()) +
                                        " channels is neither grey, BGR nor BGRA");
    }
    return grey;
}

cv::Mat averagedDownTo(const cv::Mat& image, int max_width) {
    const auto size = cappedSize(image.cols, image.rows, max_width);
    if (size.x == image.cols) return image;
    cv::Mat shrunk;
    cv::resize(image, shrunk, cv::Size(size.x, size.y), 0, 0, cv::INTER_AREA);
    return shrunk;
}

double noiseSigma(const cv::Mat& image) {
    if (image.rows < 3 || image.cols < 3) return 0.0;
    const cv::Matx33f mask(1, -2, 1, -2, 4, -2, 1, -2, 1);
    cv::Mat response;
    cv::filter2D(image, response, CV_32F, mask);
    const cv::Mat inner = response(cv::Rect(1, 1, image.cols - 2, image.rows - 2));
    return std::sqrt(CV_PI / 2.0) / 6.0 * cv::mean(cv::abs(inner))[0];
}

}  // namespace lookup::common

#include "lookup/common/grey.h"

#include <opencv2/imgproc.hpp>

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

}  // namespace lookup::common

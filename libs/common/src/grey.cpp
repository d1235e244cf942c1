#include "lookup/common/grey.h"

#include <opencv2/imgproc.hpp>

#include <stdexcept>
#include <string>

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

}  // namespace lookup::common

#include "lookup/database/heat_maps.h"

#include <cstdio>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace lookup::database {

std::string heatMapFileName(std::size_t index) {
    char name[32];
    std::snprintf(name, sizeof name, "heat_%06zu.png", index);
    return name;
}

cv::Mat encodeHeatMap(const cv::Mat& heat) {
    CV_Assert(heat.type() == CV_32FC1);
    cv::Mat out;
    heat.convertTo(out, CV_16U, 65535.0);  // saturates outside [0, 1]
    return out;
}

cv::Mat loadHeatMap(const ReferenceDatabase& db, std::size_t index) {
    const std::string& dir = db.info().heatmaps_dir;
    if (dir.empty()) return {};
    const std::string path = db.directory() + "/" + dir + "/" + heatMapFileName(index);
    cv::Mat stored = cv::imread(path, cv::IMREAD_GRAYSCALE | cv::IMREAD_ANYDEPTH);
    if (stored.empty()) {
        throw std::runtime_error(path + ": heat map listed in db.ini is missing or unreadable");
    }
    cv::Mat heat;
    stored.convertTo(heat, CV_32F, stored.depth() == CV_16U ? 1.0 / 65535 : 1.0 / 255);
    const auto& camera = db.reference(index).ceiling_camera;
    const cv::Size image_size(int(camera.ncols), int(camera.nrows));
    if (image_size.area() == 0 || heat.size() == image_size) return heat;
    if (heat.cols > image_size.width || heat.rows > image_size.height) {
        throw std::runtime_error(path + ": heat map " + std::to_string(heat.cols) + "x" +
                                 std::to_string(heat.rows) + " is larger than the " +
                                 std::to_string(image_size.width) + "x" +
                                 std::to_string(image_size.height) + " ceiling image");
    }
    cv::Mat resized;
    cv::resize(heat, resized, image_size, 0, 0, cv::INTER_LINEAR);
    return resized;
}

}  // namespace lookup::database

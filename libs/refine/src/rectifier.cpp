#include "lookup/refine/rectifier.h"

#include <mrpt/img/CImage.h>

#include <algorithm>
#include <cmath>
#include <deque>
#include <mutex>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>
#include <stdexcept>

namespace lookup::refine {
namespace {

bool hasCoefficients(const mrpt::img::TCamera& c) {
    if (c.distortion == mrpt::img::DistortionModel::none) return false;
    for (double d : c.dist) {
        if (d != 0.0) return true;
    }
    return false;
}

cv::Matx33d intrinsicMatrix(const mrpt::img::TCamera& c) {
    return {c.fx(), 0, c.cx(), 0, c.fy(), c.cy(), 0, 0, 1};
}

}  // namespace

mrpt::img::TCamera idealPinhole(const mrpt::img::TCamera& camera) {
    mrpt::img::TCamera ideal = camera;
    ideal.distortion = mrpt::img::DistortionModel::none;
    ideal.dist.fill(0.0);
    return ideal;
}

// Below this ratio of target to source focal length, bilinear sampling skips source pixels and
// aliases the ceiling's fine texture into the patches: the image is first averaged down.
constexpr double kShrinkBelowScale = 0.75;

struct Rectifier::Maps {
    mrpt::img::TCamera camera;
    cv::Size shrunk;     // size the image is first averaged down to; empty = none
    bool remap = true;   // false: the shrunk image already is one of the target
    cv::Mat map1, map2;  // cv::remap's fixed-point maps (CV_16SC2, CV_16UC1)
};

struct Rectifier::Cache {
    std::mutex mutex;
    std::deque<Maps> maps;  // a deque keeps references stable while it grows
};

Rectifier::Rectifier(const mrpt::img::TCamera& target)
    : target_(idealPinhole(target)), cache_(std::make_shared<Cache>()) {
    if (const std::string why = common::cameraProblem(target_); !why.empty()) {
        throw std::invalid_argument("rectification target camera: " + why);
    }
    if (target_.ncols == 0 || target_.nrows == 0) {
        throw std::invalid_argument("rectification target camera: image size is zero");
    }
}

bool Rectifier::isIdentity(const mrpt::img::TCamera& c) const {
    // db.ini keeps intrinsics to 5 decimals: the survey camera read back from it differs from
    // the images' own by < 1e-5 px, which moves no pixel measurably.
    constexpr double kSamePx = 1e-3;
    const auto same = [](double a, double b) { return std::abs(a - b) <= kSamePx; };
    return c.ncols == target_.ncols && c.nrows == target_.nrows && same(c.fx(), target_.fx()) &&
           same(c.fy(), target_.fy()) && same(c.cx(), target_.cx()) && same(c.cy(), target_.cy()) &&
           !hasCoefficients(c);
}

cv::Mat Rectifier::rectify(const cv::Mat& image, const mrpt::img::TCamera& camera) const {
    if (const std::string why = common::cameraProblem(camera, image.cols, image.rows);
        !why.empty()) {
        throw std::invalid_argument(why);
    }
    if (isIdentity(camera)) return image;
    const Maps& maps = mapsFor(camera);
    cv::Mat source = image;
    if (!maps.shrunk.empty()) cv::resize(image, source, maps.shrunk, 0, 0, cv::INTER_AREA);
    if (!maps.remap) return source;
    cv::Mat out;
    cv::remap(source, out, maps.map1, maps.map2, cv::INTER_LINEAR, cv::BORDER_CONSTANT,
              cv::Scalar::all(0));
    return out;
}

const Rectifier::Maps& Rectifier::mapsFor(const mrpt::img::TCamera& camera) const {
    std::lock_guard<std::mutex> lock(cache_->mutex);
    for (const auto& m : cache_->maps) {
        if (m.camera == camera) return m;
    }
    Maps m{camera, {}, true, {}, {}};
    mrpt::img::TCamera source = camera;
    const double scale = std::min(target_.fx() / camera.fx(), target_.fy() / camera.fy());
    if (scale < kShrinkBelowScale) {
        m.shrunk = cv::Size(std::max(1, int(std::lround(camera.ncols * scale))),
                            std::max(1, int(std::lround(camera.nrows * scale))));
        source = common::resizedCamera(camera, m.shrunk.width, m.shrunk.height);
        m.remap = !isIdentity(source);
    }
    if (m.remap) {
        const cv::Matx33d K = intrinsicMatrix(source), K_ideal = intrinsicMatrix(target_);
        const cv::Size out(int(target_.ncols), int(target_.nrows));
        if (source.distortion == mrpt::img::DistortionModel::kannala_brandt) {
            const cv::Vec4d d(source.k1(), source.k2(), source.k3(), source.k4());
            cv::fisheye::initUndistortRectifyMap(K, d, cv::Matx33d::eye(), K_ideal, out, CV_16SC2,
                                                 m.map1, m.map2);
        } else {
            const std::vector<double> d =
                hasCoefficients(source)
                    ? std::vector<double>(source.dist.begin(), source.dist.end())
                    : std::vector<double>(5, 0.0);
            cv::initUndistortRectifyMap(K, d, cv::noArray(), K_ideal, out, CV_16SC2, m.map1,
                                        m.map2);
        }
    }
    cache_->maps.push_back(std::move(m));
    return cache_->maps.back();
}

mrpt::obs::CObservationImage Rectifier::rectify(const mrpt::obs::CObservationImage& obs) const {
    mrpt::obs::CObservationImage out = obs;
    if (isIdentity(obs.cameraParams)) return out;
    cv::Mat pixels;
    try {
        pixels = obs.image.asCvMatRef();  // loads an external image
    } catch (const std::exception& e) {
        throw std::runtime_error("'" + obs.sensorLabel + "': cannot load the image: " + e.what());
    }
    out.image = mrpt::img::CImage(rectify(pixels, obs.cameraParams), mrpt::img::SHALLOW_COPY);
    out.cameraParams = target_;
    return out;
}

void Rectifier::rectify(ReferenceImage& reference) const {
    // A camera that cannot describe its image stays: the Refiner refuses it, saying why.
    if (!common::cameraProblem(reference.camera, reference.image.cols, reference.image.rows)
             .empty()) {
        return;
    }
    if (isIdentity(reference.camera)) {
        reference.camera = target_;
        return;
    }
    if (!reference.heat_map.empty()) {
        // The heat map scores the reference's own pixels: it moves with them.
        reference.heat_map = rectify(reference.heat_map, reference.camera);
    }
    reference.image = rectify(reference.image, reference.camera);
    reference.camera = target_;
    reference.pyramid.reset();
    reference.sample_points.reset();
}

std::size_t Rectifier::cachedCameras() const {
    std::lock_guard<std::mutex> lock(cache_->mutex);
    return cache_->maps.size();
}

}  // namespace lookup::refine

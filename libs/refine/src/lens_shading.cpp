#include "lookup/refine/lens_shading.h"

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "lookup/common/grey.h"

namespace lookup::refine {

namespace {

// The mean is kept about this many pixels wide: blotches are out of focus, a few percent of the
// width across or more, and the fit below costs far less than at full resolution.
constexpr int kMeanWidth = 80;
constexpr int kFitIterations = 6;
// Judged again every this many images (the fit costs far more than adding an image): a lens
// gets dirtier over minutes, not frames.
constexpr std::size_t kJudgeEvery = 10;
// A column of the turned mean shorter than this is left to its neighbours (canvas corners).
constexpr int kMinColumn = 5;

cv::Mat greyFloat(const cv::Mat& image) {
    cv::Mat out;
    common::greyOf(image).convertTo(out, CV_32F);
    return out;
}

// Turns an image of `size` about its centre so that `direction` points down the columns, onto
// a square canvas that holds every pixel.
cv::Mat turnToColumns(cv::Size size, cv::Point2d direction, int* side) {
    const double degrees = std::atan2(direction.x, direction.y) * 180.0 / CV_PI;
    *side = static_cast<int>(std::ceil(std::hypot(size.width, size.height))) + 2;
    const cv::Point2f centre(0.5f * (size.width - 1), 0.5f * (size.height - 1));
    cv::Mat turn = cv::getRotationMatrix2D(centre, -degrees, 1.0);
    turn.at<double>(0, 2) += 0.5 * (*side - 1) - centre.x;
    turn.at<double>(1, 2) += 0.5 * (*side - 1) - centre.y;
    return turn;
}

}  // namespace

cv::Point2d driveInImage(const mrpt::poses::CPose3D& camera_on_vehicle,
                         const mrpt::img::TCamera& camera) {
    const auto r = camera_on_vehicle.getRotationMatrix();  // its first row: the x axis
    return {camera.fx() * r(0, 0), camera.fy() * r(0, 1)};
}

std::string dirtyLensWarning(double dirty_share, double least_transmission,
                             const LensShadingOptions& options, const std::string& corrected) {
    char text[256];
    std::snprintf(text, sizeof text,
                  "the ceiling camera's lens is dirty: %.1f %% of the image lets less than %.0f %% "
                  "of the light through (the least %.0f %%); divided out of %s, but matching "
                  "behind dirt is at its noise: clean the lens",
                  100 * dirty_share, 100 * options.dirty_transmission, 100 * least_transmission,
                  corrected.c_str());
    return text;
}

void LensShadingOptions::declareKeys(common::OptionsTable& t) {
    t.add("lens_correction", enabled);
    t.add("lens_frames", frames, 2, 100000);
    t.add("lens_min_travel_m", min_travel_m, common::kPositive);
    t.add("lens_dirty_transmission", dirty_transmission, 0.0, 1.0);
    t.add("lens_min_dirty_share", min_dirty_share, 0.0, 1.0);
    t.add("lens_tolerance", tolerance, 0.0, 1.0);
    t.add("lens_max_gain", max_gain, 1.0, 256.0);
}

void LensShadingOptions::check(common::OptionsCheck& c) const {
    c.require(tolerance < 1 - dirty_transmission, "lens_tolerance",
              "< 1 - lens_dirty_transmission");
}

void LensShading::add(const cv::Mat& image, cv::Point2d drive_direction) {
    if (!options_.enabled || image.empty() || (image.channels() != 1 && image.channels() != 3))
        return;
    const double norm = std::hypot(drive_direction.x, drive_direction.y);
    if (!(norm > 0)) return;
    drive_direction *= 1.0 / norm;
    if (image.size() != size_ || std::abs(drive_direction.ddot(direction_)) < kSameDirection) {
        // another camera, or mounted otherwise: start over
        size_ = image.size();
        direction_ = drive_direction;
        mean_.release();
        gain_.release();
        added_ = 0;
        dirty_ = false;
        dirty_share_ = 0;
        least_ = 1;
    }
    cv::Mat small;
    const double scale = 1.0 / std::max(1, (image.cols + kMeanWidth / 2) / kMeanWidth);
    cv::resize(greyFloat(image), small, cv::Size(), scale, scale, cv::INTER_AREA);
    ++added_;
    if (mean_.empty()) {
        mean_ = small;
    } else {
        const double weight = 1.0 / std::min<std::size_t>(added_, options_.frames);
        cv::addWeighted(mean_, 1.0 - weight, small, weight, 0.0, mean_);
    }
    const auto frames = static_cast<std::size_t>(options_.frames);
    if (added_ >= frames && (added_ - frames) % kJudgeEvery == 0) judge();
}

void LensShading::judge() {
    // Along the drive the ceiling's structures (a pipe, a cable, the walls) stay where they are
    // across the image, so they stay in the mean; the lens's blotches and the lamp's light vary
    // along the drive too. The light is fitted along the drive only (the mean turned so the
    // drive runs down its columns), so the streaks are kept as light and only what is darker
    // than the light along its line is dirt.
    cv::Mat log_mean;
    cv::log(cv::max(mean_, 1.0f), log_mean);
    // What the camera never sees (a rectified image's black border) is neither light nor dirt.
    const cv::Mat seen = mean_ >= 1.0f;
    int side = 0;
    const cv::Mat turn = turnToColumns(mean_.size(), direction_, &side);
    cv::Mat turned, inside;
    cv::warpAffine(log_mean, turned, turn, cv::Size(side, side), cv::INTER_LINEAR,
                   cv::BORDER_REPLICATE);
    cv::warpAffine(seen, inside, turn, cv::Size(side, side), cv::INTER_NEAREST, cv::BORDER_CONSTANT,
                   0);
    cv::Mat light;
    cv::warpAffine(lightAlongColumns(turned, inside), light, turn, mean_.size(),
                   cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_REPLICATE);
    cv::Mat transmission;
    cv::exp(cv::min(log_mean - light, 0.0f), transmission);
    transmission.setTo(1.0, ~seen);
    cv::GaussianBlur(transmission, transmission, cv::Size(), 1.0);
    transmission = cv::min(transmission / (1.0 - options_.tolerance), 1.0);
    double least = 1.0;
    cv::minMaxLoc(transmission, &least);
    const cv::Mat below = transmission < options_.dirty_transmission;
    least_ = least;
    dirty_share_ = static_cast<double>(cv::countNonZero(below)) / below.total();
    dirty_ = dirty_share_ >= options_.min_dirty_share;
    if (!dirty_) {
        gain_.release();
        return;
    }
    cv::Mat gain = 1.0 / cv::max(transmission, 1.0 / options_.max_gain);
    cv::resize(gain, gain_, size_, 0, 0, cv::INTER_LINEAR);
}

cv::Mat LensShading::lightAlongColumns(const cv::Mat& log_mean, const cv::Mat& inside) const {
    // Per column, a parabola in the log (a lamp's spot is close to a Gaussian) fitted from
    // above: points under the fit by more than the tolerance (dirt) are left out and it is
    // fitted again.
    const double drop = std::log(1.0 - options_.tolerance);
    cv::Mat light(log_mean.size(), CV_32F, cv::Scalar(0));
    std::vector<int> rows;
    std::vector<char> used;
    for (int u = 0; u < log_mean.cols; ++u) {
        rows.clear();
        for (int v = 0; v < log_mean.rows; ++v) {
            if (inside.at<uchar>(v, u)) rows.push_back(v);
        }
        if (static_cast<int>(rows.size()) < kMinColumn) continue;
        const double middle = 0.5 * (rows.front() + rows.back());
        const double half = std::max(1.0, 0.5 * (rows.back() - rows.front()));
        auto basis = [&](int v) {
            const double x = (v - middle) / half;
            return Eigen::Vector3d(1.0, x, x * x);
        };
        used.assign(rows.size(), 1);
        Eigen::Vector3d c = Eigen::Vector3d::Zero();
        for (int iteration = 0; iteration < kFitIterations; ++iteration) {
            Eigen::Matrix3d normal = Eigen::Matrix3d::Zero();
            Eigen::Vector3d rhs = Eigen::Vector3d::Zero();
            for (std::size_t i = 0; i < rows.size(); ++i) {
                if (!used[i]) continue;
                const Eigen::Vector3d b = basis(rows[i]);
                normal += b * b.transpose();
                rhs += b * log_mean.at<float>(rows[i], u);
            }
            if (normal.determinant() < 1e-9) break;
            c = normal.ldlt().solve(rhs);
            for (std::size_t i = 0; i < rows.size(); ++i) {
                used[i] = log_mean.at<float>(rows[i], u) - c.dot(basis(rows[i])) > drop;
            }
        }
        for (int v : rows) light.at<float>(v, u) = static_cast<float>(c.dot(basis(v)));
    }
    return light;
}

cv::Mat LensShading::correct(const cv::Mat& image) const {
    if (!dirty_ || image.size() != size_ || image.depth() != CV_8U ||
        (image.channels() != 1 && image.channels() != 3)) {
        return image;
    }
    cv::Mat gain = gain_;
    if (image.channels() == 3) cv::merge(std::vector<cv::Mat>{gain_, gain_, gain_}, gain);
    cv::Mat out;
    cv::multiply(image, gain, out, 1.0, image.type());
    return out;
}

}  // namespace lookup::refine

// LensShading: dirt on a ceiling camera's lens is found in the mean of a drive's images and
// divided out; a clean lens, whose mean keeps the ceiling's streaks along the drive and the
// lamp's spot, is left alone, whichever way the camera is turned on the vehicle.
#include "lookup/refine/lens_shading.h"

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/imgproc.hpp>
#include <vector>

#include "lookup/refine/testing/synthetic_ceiling.h"

using namespace lookup::refine;

namespace {

constexpr int kWidth = 320, kHeight = 240;

// A long strip of ceiling: noise texture, a dark cable and a light duct running along it.
cv::Mat ceilingStrip() {
    cv::Mat strip;
    synthetic::makeNoiseTexture(cv::Size(600, 6000), 7).convertTo(strip, CV_32F);
    strip.colRange(180, 186) *= 0.4;
    strip.colRange(380, 440) *= 1.4;
    return strip;
}

// The strip as a camera sees it `travel_px` along, the drive running along `direction` (unit)
// in the image, under a lamp's spot.
cv::Mat view(const cv::Mat& strip, cv::Point2d direction, double travel_px) {
    cv::Mat map_x(kHeight, kWidth, CV_32F), map_y(kHeight, kWidth, CV_32F),
        lamp(kHeight, kWidth, CV_32F);
    for (int v = 0; v < kHeight; ++v) {
        for (int u = 0; u < kWidth; ++u) {
            const double du = u - kWidth / 2.0, dv = v - kHeight / 2.0;
            const double along = du * direction.x + dv * direction.y;
            const double across = du * direction.y - dv * direction.x;
            map_x.at<float>(v, u) = static_cast<float>(strip.cols / 2.0 + across);
            map_y.at<float>(v, u) = static_cast<float>(200.0 + travel_px + along);
            lamp.at<float>(v, u) =
                static_cast<float>(std::exp(-(du * du + dv * dv) / (2 * 150.0 * 150.0)));
        }
    }
    cv::Mat seen;
    cv::remap(strip, seen, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REFLECT);
    return seen.mul(lamp);
}

// Soft dark blotches, as out-of-focus dust: the share of the light let through.
cv::Mat dirt() {
    cv::Mat t(kHeight, kWidth, CV_32F, cv::Scalar(1));
    const double blotches[][4] = {{60, 50, 25, 0.6}, {200, 120, 35, 0.5}, {270, 200, 20, 0.4}};
    for (const auto& b : blotches) {
        for (int v = 0; v < kHeight; ++v) {
            for (int u = 0; u < kWidth; ++u) {
                const double d2 =
                    ((u - b[0]) * (u - b[0]) + (v - b[1]) * (v - b[1])) / (b[2] * b[2]);
                t.at<float>(v, u) *= static_cast<float>(1 - b[3] * std::exp(-d2));
            }
        }
    }
    return t;
}

cv::Mat to8U(const cv::Mat& radiance) {
    cv::Mat out;
    radiance.convertTo(out, CV_8U);
    return out;
}

struct Drive {
    LensShading lens;
    cv::Mat clean, seen;  ///< the last image without and with the lens's dirt
};

// 60 images 25 px of travel apart, through a lens with `transmission`.
void drive(Drive& d, cv::Point2d direction, const cv::Mat& transmission) {
    const cv::Mat strip = ceilingStrip();
    for (int i = 0; i < 60; ++i) {
        const cv::Mat radiance = view(strip, direction, 25.0 * i);
        d.clean = to8U(radiance);
        d.seen = to8U(radiance.mul(transmission));
        d.lens.add(d.seen, direction);
    }
}

// Mean absolute difference to the clean image where the dirt takes over 20 % of the light.
double errorBehindDirt(const cv::Mat& image, const cv::Mat& clean, const cv::Mat& transmission) {
    cv::Mat difference;
    cv::absdiff(image, clean, difference);
    return cv::mean(difference, transmission < 0.8)[0];
}

class LensShadingTurned : public ::testing::TestWithParam<double> {
  protected:
    cv::Point2d direction() const {
        const double a = GetParam() * CV_PI / 180;
        return {std::sin(a), std::cos(a)};
    }
};

}  // namespace

TEST_P(LensShadingTurned, ACleanLensIsLeftAlone) {
    Drive d;
    drive(d, direction(), cv::Mat(kHeight, kWidth, CV_32F, cv::Scalar(1)));
    ASSERT_EQ(d.lens.imagesAdded(), 60u);
    EXPECT_FALSE(d.lens.dirty()) << d.lens.dirtyShare() << " of the image, least "
                                 << d.lens.leastTransmission();
    EXPECT_GT(d.lens.leastTransmission(), d.lens.options().dirty_transmission);
    EXPECT_EQ(d.lens.correct(d.seen).data, d.seen.data);  // the image itself, untouched
}

TEST_P(LensShadingTurned, DirtIsFoundAndDividedOut) {
    Drive d;
    const cv::Mat transmission = dirt();
    drive(d, direction(), transmission);
    ASSERT_TRUE(d.lens.dirty());
    EXPECT_GT(d.lens.dirtyShare(), 0.05);
    EXPECT_LT(d.lens.leastTransmission(), 0.6);
    const double before = errorBehindDirt(d.seen, d.clean, transmission);
    const double after = errorBehindDirt(d.lens.correct(d.seen), d.clean, transmission);
    // What is left is the ceiling's texture the mean of 60 images still holds, a few percent.
    EXPECT_GT(before, 30.0);
    EXPECT_LT(after, before / 3) << "before " << before;
}

INSTANTIATE_TEST_SUITE_P(Mounts, LensShadingTurned,
                         ::testing::Values(0.0, 90.0, 180.0, 30.0, -60.0));

TEST(LensShading, AnotherMountStartsTheMeanOver) {
    Drive d;
    drive(d, {0, 1}, dirt());
    ASSERT_TRUE(d.lens.dirty());
    d.lens.add(d.seen, {0, -2});  // the same line, driven the other way: the same mount
    EXPECT_EQ(d.lens.imagesAdded(), 61u);
    d.lens.add(d.seen, {1, 0});
    EXPECT_EQ(d.lens.imagesAdded(), 1u);
    EXPECT_FALSE(d.lens.dirty());
    EXPECT_EQ(d.lens.correct(d.seen).data, d.seen.data);
}

TEST(LensShading, NothingIsJudgedBeforeEnoughImages) {
    Drive d;
    const cv::Mat strip = ceilingStrip();
    const cv::Mat transmission = dirt();
    for (int i = 0; i + 1 < d.lens.options().frames; ++i) {
        d.lens.add(to8U(view(strip, {0, 1}, 25.0 * i).mul(transmission)), {0, 1});
    }
    EXPECT_FALSE(d.lens.dirty());
    EXPECT_DOUBLE_EQ(d.lens.leastTransmission(), 1.0);
}

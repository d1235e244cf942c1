#include "lookup/common/grey.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include <cmath>
#include <stdexcept>

namespace lookup::common {
namespace {

TEST(Grey, OneChannelIsSharedNotCopied) {
    const cv::Mat grey(4, 6, CV_8UC1, cv::Scalar(7));
    const cv::Mat out = greyOf(grey);
    EXPECT_EQ(out.data, grey.data);
}

TEST(Grey, BgrAndBgraWeighBlueGreenAndRedAsOpenCvDoes) {
    // Pure blue, green and red give the luma weights 0.114, 0.587 and 0.299 of 200.
    for (const int channels : {3, 4}) {
        cv::Mat colour(1, 3, CV_8UC(channels), cv::Scalar::all(0));
        for (int c = 0; c < 3; ++c) colour.ptr<uchar>(0)[c * channels + c] = 200;
        const cv::Mat out = greyOf(colour);
        ASSERT_EQ(out.type(), CV_8UC1) << channels;
        EXPECT_NEAR(out.at<uchar>(0, 0), 23, 1) << channels;
        EXPECT_NEAR(out.at<uchar>(0, 1), 117, 1) << channels;
        EXPECT_NEAR(out.at<uchar>(0, 2), 60, 1) << channels;
    }
}

TEST(Grey, TwoChannelsAreRefused) {
    EXPECT_THROW(greyOf(cv::Mat(2, 2, CV_8UC2)), std::invalid_argument);
    EXPECT_TRUE(greyOf(cv::Mat()).empty());
}

TEST(Grey, NoiseSigmaFindsTheNoiseOnAnIlluminatedImageNotTheLight) {
    // A lamp's smooth light cone, 8-bit like a camera's image, with read noise of 1.2 and 4 grey
    // levels: the light's gradient must not count as noise.
    for (const double sigma : {1.2, 4.0}) {
        cv::Mat light(240, 320, CV_32F), noise(240, 320, CV_32F), image;
        for (int v = 0; v < light.rows; ++v) {
            for (int u = 0; u < light.cols; ++u) {
                const double r2 = ((u - 160.0) * (u - 160.0) + (v - 120.0) * (v - 120.0)) / 2e4;
                light.at<float>(v, u) = static_cast<float>(40 + 160 * std::exp(-r2));
            }
        }
        cv::RNG(5).fill(noise, cv::RNG::NORMAL, 0, sigma);
        cv::Mat(light + noise).convertTo(image, CV_8U);
        EXPECT_NEAR(noiseSigma(image), sigma, 0.15 * sigma);
        EXPECT_LT(noiseSigma(light), 0.1);
    }
    EXPECT_EQ(noiseSigma(cv::Mat(2, 2, CV_8UC1, cv::Scalar(3))), 0.0);
}

}  // namespace
}  // namespace lookup::common

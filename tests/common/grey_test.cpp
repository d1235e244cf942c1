#include "lookup/common/grey.h"

#include <gtest/gtest.h>

#include <opencv2/core.hpp>

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

}  // namespace
}  // namespace lookup::common

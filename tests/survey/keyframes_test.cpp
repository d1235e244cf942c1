#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "lookup/survey/image_quality.h"
#include "lookup/survey/keyframes.h"
#include "survey_fixture.h"

using namespace lookup::survey;

TEST(ImageQuality, BlurLowersSharpnessAndExposureIsMeasured) {
    const cv::Mat sharp =
        lookup::test::ceilingTexture(mrpt::poses::CPose3D(1, 2, 0, 0, 0, 0), 80, 60);
    cv::Mat blurred;
    cv::GaussianBlur(sharp, blurred, cv::Size(0, 0), 3.0);
    const auto qs = measureImageQuality(sharp);
    const auto qb = measureImageQuality(blurred);
    EXPECT_GT(qs.sharpness, SurveyOptions().min_sharpness);
    EXPECT_LT(qb.sharpness, SurveyOptions().min_sharpness);
    const auto dark = measureImageQuality(cv::Mat(60, 80, CV_8UC1, cv::Scalar(0)));
    EXPECT_DOUBLE_EQ(dark.mean_intensity, 0.0);
    EXPECT_DOUBLE_EQ(dark.clipped_fraction, 1.0);
}

TEST(Keyframes, SpacingRespectedAndBadFramesSkipped) {
    // 0.1 m per frame along x; frames 5 and 6 are blurred, frame 13 is dark.
    std::vector<KeyframeCandidate> c;
    for (int i = 0; i < 40; ++i)
        c.push_back({i * 0.1, mrpt::poses::CPose3D(i * 0.1, 0, 0, 0, 0, 0)});
    SurveyOptions o;
    o.keyframe_spacing_m = 0.25;
    std::vector<std::size_t> asked;
    const auto sel = selectKeyframes(c, o, [&](std::size_t i) {
        asked.push_back(i);
        ImageQuality q{1000, 128, 0};
        if (i == 5 || i == 6) q.sharpness = 1;
        if (i == 13) q.mean_intensity = 5;
        return q;
    });
    ASSERT_FALSE(sel.kept.empty());
    EXPECT_EQ(sel.kept.front(), 0u);
    for (std::size_t k = 1; k < sel.kept.size(); ++k) {
        EXPECT_GE(sel.kept_travelled_m[k] - sel.kept_travelled_m[k - 1], 0.25 - 1e-9);
        EXPECT_NE(sel.kept[k], 5u);
        EXPECT_NE(sel.kept[k], 6u);
        EXPECT_NE(sel.kept[k], 13u);
    }
    // 0, 3, then 6 is due but 5.. are bad: 5 is not due; 6 blurred -> 7, then 10, 13 dark -> 14.
    const std::vector<std::size_t> expected = {0, 3, 7, 10, 14, 17, 20, 23, 26, 29, 32, 35, 38};
    EXPECT_EQ(sel.kept, expected);
    EXPECT_EQ(sel.rejected_blur, 1u);
    EXPECT_EQ(sel.rejected_exposure, 1u);
    // Quality is only computed for frames that are due.
    EXPECT_LT(asked.size(), c.size() / 2);
}

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "lookup/survey/image_quality.h"
#include "lookup/survey/keyframes.h"
#include "lookup/survey/survey.h"
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

TEST(ImageQuality, AnImageIsJudgedAtTheWidthTheDatabaseStoresItAt) {
    // The same ceiling from a camera with 4x the pixels: smooth at its own resolution, as sharp
    // as the stored image once averaged down to it.
    cv::Mat stored;
    cv::GaussianBlur(lookup::test::ceilingTexture(mrpt::poses::CPose3D(1, 2, 0, 0, 0, 0), 320, 240),
                     stored, cv::Size(0, 0), 1.0);
    cv::Mat recorded;
    cv::resize(stored, recorded, cv::Size(1280, 960), 0, 0, cv::INTER_CUBIC);
    const double min_sharpness = SurveyOptions().min_sharpness;
    ASSERT_GT(measureImageQuality(stored).sharpness, min_sharpness);
    EXPECT_LT(measureImageQuality(recorded).sharpness, min_sharpness);
    const auto judged = measureImageQuality(recorded, 320);
    EXPECT_GT(judged.sharpness, min_sharpness);
    EXPECT_NEAR(judged.mean_intensity, measureImageQuality(stored).mean_intensity, 1.0);
    EXPECT_DOUBLE_EQ(measureImageQuality(stored, 320).sharpness,
                     measureImageQuality(stored).sharpness);
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
        if (i == 13) q.mean_intensity = 1;
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

TEST(Keyframes, TheDefaultsKeepADimOrHalfSaturatedCameraAndSkipFramesWithNothingLeft) {
    // A camera that is always this dim or this bright still localises: a gate that skipped all
    // its frames would leave the survey without references.
    const SurveyOptions o;
    std::vector<KeyframeCandidate> c;
    for (int i = 0; i < 6; ++i)
        c.push_back({i * 0.1, mrpt::poses::CPose3D(i * 0.3, 0, 0, 0, 0, 0)});
    const std::vector<ImageQuality> frames = {
        {29, 5, 0.28},     // dim: read noise's Laplacian, a third of the pixels black
        {900, 190, 0.45},  // lamp too bright: half the pixels saturated
        {500, 60, 0.0},    // nominal
        {12, 1, 0.99},     // no light
        {700, 252, 0.97},  // washed out
        {2, 128, 0.0},     // featureless: smoother than any sensor's noise
    };
    const auto sel = selectKeyframes(c, o, [&](std::size_t i) { return frames[i]; });
    EXPECT_EQ(sel.kept, (std::vector<std::size_t>{0, 1, 2}));
    EXPECT_EQ(sel.rejected_exposure, 2u);
    EXPECT_EQ(sel.rejected_blur, 1u);
}

TEST(ImageQuality, ATraverseOfDimOrSaturatedReferencesIsSaidOnce) {
    const SurveyOptions o;
    auto warningsFor = [&](std::vector<ImageQuality> refs) {
        TraverseReport r;
        r.references = refs.size();
        r.ceiling_images = medianQuality(refs);
        return traverseWarnings(r, "left.rawlog", o);
    };
    // Medians, not means: one lamp-lit frame does not hide a dim traverse.
    const auto dim = warningsFor({{40, 6, 0.2}, {45, 8, 0.1}, {300, 120, 0.0}});
    ASSERT_EQ(dim.size(), 1u);
    EXPECT_NE(dim[0].find("left.rawlog: the ceiling images are dim"), std::string::npos) << dim[0];
    EXPECT_NE(dim[0].find("mean grey 8.0"), std::string::npos) << dim[0];
    const auto saturated = warningsFor({{900, 200, 0.6}, {900, 190, 0.55}, {500, 60, 0.0}});
    ASSERT_EQ(saturated.size(), 1u);
    EXPECT_NE(saturated[0].find("saturated"), std::string::npos) << saturated[0];
    EXPECT_NE(saturated[0].find("55 % of pixels clipped"), std::string::npos) << saturated[0];
    EXPECT_TRUE(warningsFor({{500, 60, 0.0}, {400, 70, 0.02}}).empty());
    EXPECT_TRUE(warningsFor({}).empty());  // no references: said elsewhere
}

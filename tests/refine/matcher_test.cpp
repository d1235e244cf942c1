#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <opencv2/imgproc.hpp>

#include "lookup/refine/geometry.h"
#include "lookup/refine/matcher.h"
#include "lookup/refine/sampler.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

using namespace lookup::refine;
using mrpt::poses::CPose3D;

namespace {

struct Pair {
    cv::Mat ref, qry;
    cv::Matx33d H;  // true reference -> query pixel map
};

// Reference at the origin, query moved by (dx, dy) m and `yaw` rad; camera 3.5 m below the
// ceiling, f = 250 px: 71.4 px per metre.
Pair makePair(double dx, double dy, double yaw = 0.0, std::uint64_t seed = 1) {
    static const auto ceiling = synthetic::SyntheticCeiling::make(5.0, 10.0, 0.01, seed);
    const auto cam = synthetic::makeCamera(320, 240, 250);
    const CPose3D on_vehicle = synthetic::ceilingCameraOnVehicle();
    const CPose3D ref_cam = CPose3D() + on_vehicle;
    const CPose3D qry_cam = CPose3D(dx, dy, 0, yaw, 0, 0) + on_vehicle;
    Pinhole p;
    pinholeFrom(cam, p, nullptr);
    return {ceiling.render(cam, ref_cam), ceiling.render(cam, qry_cam),
            ceilingHomography(p, ref_cam, p, qry_cam, ceiling.height_m)};
}

cv::Point2d apply(const cv::Matx33d& H, cv::Point2f p) {
    const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1.0);
    return {v[0] / v[2], v[1] / v[2]};
}

}  // namespace

TEST(Matcher, RecoversSubpixelOffsetToATenthOfAPixel) {
    // 0.1 m, -0.07 m: (-7.14, +5.0) px, fractional parts included.
    const Pair pair = makePair(0.1, -0.07);
    MatcherOptions o;
    const auto points = gridPoints(pair.ref.size(), 24, o.patch_px / 2);
    const auto levels = effectivePyramidLevels(o);
    const auto matches = matchPoints(ImagePyramid::build(pair.ref, levels),
                                     ImagePyramid::build(pair.qry, levels), points, {}, o);
    ASSERT_EQ(matches.size(), points.size());
    double sum = 0;
    int n = 0;
    for (const auto& m : matches) {
        ASSERT_TRUE(m.matched()) << toString(m.status) << " at " << m.reference_px;
        const cv::Point2d truth = apply(pair.H, m.reference_px);
        const double err = cv::norm(cv::Point2d(m.query_px) - truth);
        EXPECT_LT(err, 0.25) << "at " << m.reference_px;
        sum += err;
        ++n;
    }
    EXPECT_LT(sum / n, 0.1) << "mean sub-pixel error";
}

TEST(Matcher, CoarseToFineEqualsExhaustiveOnTexture) {
    for (const auto& [search, patch] : {std::pair{40, 40}, std::pair{70, 60}}) {
        const Pair pair = makePair(0.15, 0.2, 0.03);
        MatcherOptions fast;
        fast.search_range_px = search;
        fast.patch_px = patch;
        MatcherOptions exhaustive = fast;
        exhaustive.pyramid_levels = 0;
        ASSERT_GT(effectivePyramidLevels(fast), 0);
        const auto points = gridPoints(pair.ref.size(), 40, patch / 2);
        const ImagePyramid r = ImagePyramid::build(pair.ref, 2),
                           q = ImagePyramid::build(pair.qry, 2);
        const auto a = matchPoints(r, q, points, {}, fast);
        const auto b = matchPoints(r, q, points, {}, exhaustive);
        int matched = 0;
        for (std::size_t i = 0; i < points.size(); ++i) {
            if (!b[i].matched()) continue;
            ++matched;
            ASSERT_TRUE(a[i].matched()) << "point " << points[i] << ": " << toString(a[i].status)
                                        << " exhaustive " << b[i].query_px;
            EXPECT_EQ(a[i].query_px, b[i].query_px) << "point " << points[i];
        }
        EXPECT_GE(matched, int(points.size()) * 3 / 4) << "L_SR " << search;
    }
}

TEST(Matcher, SimdAndScalarGiveIdenticalMatches) {
    const Pair pair = makePair(-0.12, 0.05, -0.02);
    MatcherOptions o;
    o.search_range_px = 70;
    o.patch_px = 60;
    const auto points = gridPoints(pair.ref.size(), 24, 30);
    const ImagePyramid r = ImagePyramid::build(pair.ref, 2), q = ImagePyramid::build(pair.qry, 2);
    const auto simd = matchPoints(r, q, points, {}, o, bestSimdLevel());
    const auto scalar = matchPoints(r, q, points, {}, o, SimdLevel::Scalar);
    for (std::size_t i = 0; i < points.size(); ++i) {
        EXPECT_EQ(simd[i].status, scalar[i].status);
        EXPECT_EQ(simd[i].query_px, scalar[i].query_px);
        EXPECT_EQ(simd[i].quality, scalar[i].quality);
        EXPECT_EQ(simd[i].sad_per_px, scalar[i].sad_per_px);
    }
}

TEST(Matcher, PredictedOffsetReachesMotionBeyondTheWindow) {
    // 0.8 m = 57 px: outside +-20 px, found when the window is centred on the prediction.
    const Pair pair = makePair(0.8, 0.0);
    MatcherOptions o;
    const auto points = gridPoints(pair.ref.size(), 12, 20);
    const ImagePyramid r = ImagePyramid::build(pair.ref, 2), q = ImagePyramid::build(pair.qry, 2);
    std::vector<cv::Point2f> predicted;
    for (const auto& p : points) {
        const cv::Point2d t = apply(pair.H, p);
        predicted.emplace_back(float(t.x - p.x + 6.0), float(t.y - p.y - 4.0));  // 7 px off
    }
    const auto blind = matchPoints(r, q, points, {}, o);
    const auto guided = matchPoints(r, q, points, predicted, o);
    int good_blind = 0, good_guided = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        const cv::Point2d t = apply(pair.H, points[i]);
        if (blind[i].matched() && cv::norm(cv::Point2d(blind[i].query_px) - t) < 0.5) ++good_blind;
        if (guided[i].matched() && cv::norm(cv::Point2d(guided[i].query_px) - t) < 0.5) {
            ++good_guided;
        }
    }
    EXPECT_EQ(good_blind, 0);
    EXPECT_GE(good_guided, 9);  // points whose true match left the query image are refused
}

TEST(Matcher, BlankImageGivesLowTextureNotMatches) {
    const cv::Mat blank(240, 320, CV_8UC1, cv::Scalar(128));
    const ImagePyramid b = ImagePyramid::build(blank, 2);
    const auto matches = matchPoints(b, b, gridPoints(blank.size(), 12, 20), {}, MatcherOptions());
    for (const auto& m : matches) EXPECT_EQ(m.status, MatchStatus::LowTexture);
}

TEST(Matcher, PointsOnTheBorderAreRefusedWithAReason) {
    const Pair pair = makePair(0.0, 0.0);
    const ImagePyramid r = ImagePyramid::build(pair.ref, 2), q = ImagePyramid::build(pair.qry, 2);
    const std::vector<cv::Point2f> border = {{0, 0},     {319, 120}, {5, 5},
                                             {160, 239}, {-50, 10},  {std::nanf(""), 3}};
    for (const auto& m : matchPoints(r, q, border, {}, MatcherOptions())) {
        EXPECT_EQ(m.status, MatchStatus::OutOfImage) << m.reference_px;
    }
    // A window running off the query: the best lies on the clipped border.
    MatcherOptions o;
    const auto m = matchPoints(r, q, {{20, 120}}, {{-30, 0}}, o);
    EXPECT_FALSE(m[0].matched());
}

TEST(Matcher, MismatchedImageGivesInconsistentOrRejectedMatches) {
    const Pair pair = makePair(0.0, 0.0);
    const cv::Mat other = synthetic::makeNoiseTexture(pair.ref.size(), 99);
    const ImagePyramid r = ImagePyramid::build(pair.ref, 2), q = ImagePyramid::build(other, 2);
    const auto points = gridPoints(pair.ref.size(), 24, 20);
    int consistent = 0;
    for (const auto& m : matchPoints(r, q, points, {}, MatcherOptions())) {
        if (m.matched() && cv::norm(m.query_px - m.reference_px) < 1.0) ++consistent;
    }
    EXPECT_LE(consistent, 2);
}

TEST(Matcher, MotionCompensationMatchesARotatedView) {
    // 12 deg of yaw: plain SAD compares patches whose outer pixels have moved by several pixels
    // and loses most points; warping the reference by a prediction (here 2 deg and 3 px off the
    // truth, as a coarse pose would be) aligns the patches and recovers true correspondences.
    const double yaw = 12.0 * M_PI / 180.0;
    const Pair pair = makePair(0.1, -0.05, yaw);
    const Pair predicted = makePair(0.14, -0.05, yaw - 2.0 * M_PI / 180.0);
    MatcherOptions o;
    const auto points = gridPoints(pair.ref.size(), 24, o.patch_px / 2);
    const ImagePyramid r = ImagePyramid::build(pair.ref, 2), q = ImagePyramid::build(pair.qry, 2);
    std::vector<cv::Point2f> offsets;
    for (const auto& p : points) {
        const cv::Point2d t = apply(predicted.H, p);
        offsets.emplace_back(float(t.x - p.x), float(t.y - p.y));
    }
    const auto plain = matchPoints(r, q, points, offsets, o);
    const auto compensated = matchPointsCompensated(r, q, points, predicted.H, o);
    ASSERT_EQ(compensated.size(), points.size());
    int good_plain = 0, good_compensated = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
        if (plain[i].matched() &&
            cv::norm(cv::Point2d(plain[i].query_px) - apply(pair.H, plain[i].reference_px)) < 0.5) {
            ++good_plain;
        }
        const PointMatch& m = compensated[i];
        if (!m.matched()) continue;
        // Returned pixels are true reference pixels, near the requested sample point.
        EXPECT_LT(cv::norm(m.reference_px - points[i]), 1.5) << "point " << points[i];
        const double err = cv::norm(cv::Point2d(m.query_px) - apply(pair.H, m.reference_px));
        EXPECT_LT(err, 0.5) << "point " << points[i];
        if (err < 0.5) ++good_compensated;
    }
    std::printf("rotated view: %d plain, %d compensated of %zu\n", good_plain, good_compensated,
                points.size());
    EXPECT_GE(good_compensated, 18);
    EXPECT_LT(good_plain, good_compensated / 2);
}

TEST(Matcher, MotionCompensationWithIdentityEqualsPlainMatching) {
    const Pair pair = makePair(0.05, 0.03);
    MatcherOptions o;
    const auto points = gridPoints(pair.ref.size(), 24, o.patch_px / 2 + 2);
    const ImagePyramid r = ImagePyramid::build(pair.ref, 2), q = ImagePyramid::build(pair.qry, 2);
    const auto plain = matchPoints(r, q, points, {}, o);
    const auto compensated = matchPointsCompensated(r, q, points, cv::Matx33d::eye(), o);
    for (std::size_t i = 0; i < points.size(); ++i) {
        EXPECT_EQ(plain[i].status, compensated[i].status) << "point " << points[i];
        if (plain[i].matched()) {
            EXPECT_NEAR(plain[i].query_px.x, compensated[i].query_px.x, 1e-3);
            EXPECT_NEAR(plain[i].query_px.y, compensated[i].query_px.y, 1e-3);
        }
    }
}

TEST(Matcher, MotionCompensationRefusesADegenerateHomography) {
    const Pair pair = makePair(0.05, 0.03);
    MatcherOptions o;
    const auto points = gridPoints(pair.ref.size(), 12, o.patch_px / 2);
    const ImagePyramid r = ImagePyramid::build(pair.ref, 2), q = ImagePyramid::build(pair.qry, 2);
    for (const cv::Matx33d& H : {cv::Matx33d::zeros(), cv::Matx33d(1, 0, NAN, 0, 1, 0, 0, 0, 1)}) {
        for (const auto& m : matchPointsCompensated(r, q, points, H, o)) {
            EXPECT_FALSE(m.matched());
        }
    }
}

TEST(Matcher, IlluminationHighPassMatchesUnderTheVehiclesOwnLight) {
    // The lamp moves with the camera: both images carry the same bright centre and dark rim,
    // while the ceiling (low-contrast, as shotcrete) moves 14 px x 7 px under it.
    const Pair pair = makePair(0.2, 0.1);
    const auto light = [](const cv::Mat& image) {
        cv::Mat out(image.size(), CV_8UC1);
        const double cx = image.cols / 2.0, cy = image.rows / 2.0;
        for (int y = 0; y < image.rows; ++y) {
            for (int x = 0; x < image.cols; ++x) {
                const double r2 = (x - cx) * (x - cx) + (y - cy) * (y - cy);
                const double lamp = 0.35 + 0.9 * std::exp(-r2 / (2 * 110.0 * 110.0));
                const double ceiling = 128 + 0.15 * (image.at<uchar>(y, x) - 128);
                out.at<uchar>(y, x) = cv::saturate_cast<uchar>(lamp * ceiling);
            }
        }
        return out;
    };
    const cv::Mat ref = light(pair.ref), qry = light(pair.qry);
    const auto points = gridPoints(ref.size(), 24, 20);
    const auto correct = [&](const MatcherOptions& o) {
        const int levels = effectivePyramidLevels(o);
        const auto matches = matchPoints(ImagePyramid::build(ref, levels, o),
                                         ImagePyramid::build(qry, levels, o), points, {}, o);
        int n = 0;
        for (const auto& m : matches) {
            const cv::Point2d truth = apply(pair.H, m.reference_px);
            if (m.matched() && cv::norm(cv::Point2d(m.query_px) - truth) < 0.5) ++n;
        }
        return n;
    };
    MatcherOptions high_pass;
    ASSERT_GT(high_pass.illumination_sigma_px, 0.0);  // on by default
    MatcherOptions raw = high_pass;
    raw.illumination_sigma_px = 0.0;
    const int with = correct(high_pass), without = correct(raw);
    std::printf("correct matches: %d with the high-pass, %d without, of %zu\n", with, without,
                points.size());
    EXPECT_GE(with, int(points.size()) * 3 / 4);
    EXPECT_LE(2 * without, with);
}

TEST(Matcher, IlluminationPreprocessingIsRecordedOnThePyramid) {
    const Pair pair = makePair(0.0, 0.0);
    MatcherOptions o;
    o.illumination_sigma_px = 6.0;
    const auto p = ImagePyramid::build(pair.ref, 2, o);
    EXPECT_TRUE(p.preprocessedFor(o));
    EXPECT_EQ(p.levels.size(), 3u);
    EXPECT_EQ(p.levels[0].type(), CV_8UC1);
    MatcherOptions other = o;
    other.illumination_sigma_px = 0.0;
    EXPECT_FALSE(p.preprocessedFor(other));
    // High-passed and normalised: mean 128, the texture kept (standard deviation near 48).
    cv::Scalar mean, stddev;
    cv::meanStdDev(p.levels[0], mean, stddev);
    EXPECT_NEAR(mean[0], 128.0, 3.0);
    EXPECT_NEAR(stddev[0], 48.0, 6.0);
}

TEST(Matcher, ADimBlurredNoisyQueryMatchesASharpReferenceOnceItsContrastIsStretched) {
    // Another vehicle's weaker lamp: a tenth of the survey's contrast, the sensor's noise, and
    // at 40 km/h a 3 ms exposure smears the ceiling by 2.4 px along the drive (7 px: 9 ms).
    // The blur is symmetric, so the SAD minimum stays where the sharp reference's texture is,
    // once both images are stretched to the same contrast: a gain of 4 leaves the query at 0.4
    // of the reference's and no peak stands out.
    const Pair pair = makePair(0.12, -0.05);
    const auto dim_blurred = [](const cv::Mat& image, int smear_px) {
        cv::Mat blurred, noise(image.size(), CV_32F), out;
        cv::blur(image, blurred, cv::Size(smear_px, 1));
        cv::RNG(5).fill(noise, cv::RNG::NORMAL, 0.0, 1.0);
        blurred.convertTo(out, CV_32F, 0.1, 10.0);
        out += noise;
        out.convertTo(out, CV_8U);
        return out;
    };
    const auto correct = [&](const MatcherOptions& o, int smear_px) {
        const auto points = gridPoints(pair.ref.size(), 24, o.patch_px / 2);
        const int levels = effectivePyramidLevels(o);
        const ImagePyramid r = ImagePyramid::build(pair.ref, levels, o);
        const ImagePyramid q = ImagePyramid::build(dim_blurred(pair.qry, smear_px), levels, o);
        int n = 0;
        for (const auto& m : matchPoints(r, q, points, {}, o)) {
            const cv::Point2d truth = apply(pair.H, m.reference_px);
            if (m.matched() && cv::norm(cv::Point2d(m.query_px) - truth) < 0.5) ++n;
        }
        return n;
    };
    MatcherOptions stretched;
    stretched.min_distinctiveness = 0.2;  // as share/lookup/localize.ini
    stretched.max_contrast_gain = 64;
    MatcherOptions capped = stretched;
    capped.max_contrast_gain = 4;
    for (const int smear_px : {3, 7}) {
        const int with = correct(stretched, smear_px), without = correct(capped, smear_px);
        std::printf("smear %d px: %d of 24 correct stretched, %d with the gain capped at 4\n",
                    smear_px, with, without);
        EXPECT_GE(with, 18) << "smear " << smear_px << " px";
        EXPECT_LE(2 * without, with) << "smear " << smear_px << " px";
    }
}

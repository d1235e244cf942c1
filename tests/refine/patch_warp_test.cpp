#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "lookup/refine/patch_warp.h"

using namespace lookup::refine;

namespace {

// A smooth texture like a ceiling's pyramid level: random grey blurred over a few pixels.
cv::Mat texture(cv::Size size, std::uint64_t seed) {
    cv::Mat image(size, CV_8UC1);
    cv::RNG(seed).fill(image, cv::RNG::UNIFORM, 0, 256);
    cv::GaussianBlur(image, image, cv::Size(0, 0), 1.5);
    return image;
}

// Patch pixel -> source pixel: a rotation, a scale, a little perspective and a shift.
cv::Matx33d patchToSource(double yaw, double scale, double px, cv::Point2d at) {
    const double c = std::cos(yaw) * scale, s = std::sin(yaw) * scale;
    return cv::Matx33d(c, -s, at.x, s, c, at.y, px, -px, 1.0);
}

cv::Mat openCv(const cv::Mat& src, const cv::Matx33d& dst_to_src, cv::Size size) {
    cv::Mat dst;
    cv::warpPerspective(src, dst, cv::Mat(dst_to_src), size,
                        cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                        cv::Scalar(0));
    return dst;
}

double maxDifference(const cv::Mat& a, const cv::Mat& b) { return cv::norm(a, b, cv::NORM_INF); }

// Whether every sample of a side x side patch has its four taps inside `image`.
bool tapsInside(const cv::Matx33d& M, int side, cv::Size image) {
    for (const cv::Point2d corner : {cv::Point2d(0, 0), cv::Point2d(side - 1, 0),
                                     cv::Point2d(0, side - 1), cv::Point2d(side - 1, side - 1)}) {
        const cv::Vec3d v = M * cv::Vec3d(corner.x, corner.y, 1.0);
        const cv::Point2d p(v[0] / v[2], v[1] / v[2]);
        if (!cv::Rect2d(0.5, 0.5, image.width - 2.0, image.height - 2.0).contains(p)) return false;
    }
    return true;
}

}  // namespace

// The hand-written warp must be cv::warpPerspective up to OpenCV's 1/32-pixel rounding: every
// patch width (blocks of eight, the overlapping last block, widths under eight), patches well
// inside, across the image's edges and wholly outside.
TEST(PatchWarp, Avx2IsOpenCvsWarpUpToItsPositionRounding) {
    if (bestSimdLevel() != SimdLevel::Avx2) GTEST_SKIP() << "no AVX2 on this CPU";
    const cv::Mat src = texture({320, 240}, 3);
    cv::RNG rng(11);
    int compared = 0;
    for (int side = 1; side <= 70; side += side < 20 ? 1 : 7) {
        for (int trial = 0; trial < 12; ++trial) {
            const cv::Point2d at(rng.uniform(-1.5 * side, 320.0), rng.uniform(-1.5 * side, 240.0));
            const cv::Matx33d M = patchToSource(rng.uniform(-3.2, 3.2), rng.uniform(0.8, 1.25),
                                                rng.uniform(-2e-4, 2e-4), at);
            cv::Mat mine(side, side, CV_8UC1, cv::Scalar(77));
            warpPatch(SimdLevel::Avx2, src, M, mine);
            const cv::Mat theirs = openCv(src, M, mine.size());
            // OpenCV's rounding moves a sample by up to 1/64 pixel along each axis: a grey level
            // on this texture; where a tap falls off the edge onto the black border, the step
            // there (up to 255) moves by up to 1/32 of it.
            EXPECT_LE(maxDifference(mine, theirs), tapsInside(M, side, src.size()) ? 1.0 : 8.0)
                << "side " << side << " at " << at;
            ++compared;
        }
    }
    EXPECT_GT(compared, 200);
}

TEST(PatchWarp, AWholePixelShiftCopiesThePixelsExactly) {
    const cv::Mat src = texture({97, 61}, 5);
    for (SimdLevel level : {SimdLevel::Scalar, bestSimdLevel()}) {
        cv::Mat dst(23, 29, CV_8UC1);
        warpPatch(level, src, cv::Matx33d(1, 0, 40, 0, 1, 17, 0, 0, 1), dst);
        EXPECT_EQ(maxDifference(dst, src(cv::Rect(40, 17, 29, 23))), 0.0) << toString(level);
    }
}

TEST(PatchWarp, WritesOnlyTheViewItIsGiven) {
    const cv::Mat src = texture({64, 64}, 7);
    cv::Mat buffer(40, 72, CV_8UC1, cv::Scalar(200));
    cv::Mat view = buffer(cv::Rect(5, 3, 18, 30));
    warpPatch(bestSimdLevel(), src, patchToSource(0.4, 1.0, 0.0, {20, 10}), view);
    cv::Mat outside = buffer.clone();
    outside(cv::Rect(5, 3, 18, 30)).setTo(200);
    EXPECT_EQ(cv::countNonZero(outside != 200), 0);
    EXPECT_GT(cv::countNonZero(view != 200), 400);
}

TEST(PatchWarp, AMapOffToInfinityGivesBlackNotACrash) {
    if (bestSimdLevel() != SimdLevel::Avx2) GTEST_SKIP() << "no AVX2 on this CPU";
    const cv::Mat src = texture({64, 64}, 9);
    const double nan = std::numeric_limits<double>::quiet_NaN();
    for (const cv::Matx33d& M :
         {cv::Matx33d(1, 0, 1e12, 0, 1, 0, 0, 0, 1), cv::Matx33d(1, 0, 0, 0, 1, 0, 0, 0, 0),
          cv::Matx33d(nan, 0, 0, 0, 1, 0, 0, 0, 1)}) {
        cv::Mat dst(16, 16, CV_8UC1, cv::Scalar(5));
        warpPatch(SimdLevel::Avx2, src, M, dst);
        EXPECT_EQ(cv::countNonZero(dst), 0) << M;
    }
}

// A view's taps outside it count as border, as OpenCV has it, and its last row is read only up
// to the end of the parent's buffer (AddressSanitizer would report a gather past it).
TEST(PatchWarp, AViewIsSampledAsAnImageOfItsOwn) {
    if (bestSimdLevel() != SimdLevel::Avx2) GTEST_SKIP() << "no AVX2 on this CPU";
    const cv::Mat parent = texture({64, 64}, 13);
    const cv::Mat view = parent(cv::Rect(20, 40, 44, 24));  // the parent's bottom-right corner
    for (const cv::Point2d at : {cv::Point2d(30.3, 14.6), cv::Point2d(36.5, 20.25)}) {
        const cv::Matx33d M = patchToSource(0.05, 1.0, 0.0, at);
        cv::Mat mine(12, 16, CV_8UC1);
        warpPatch(SimdLevel::Avx2, view, M, mine);
        EXPECT_LE(maxDifference(mine, openCv(view, M, mine.size())), 8.0) << at;
    }
}

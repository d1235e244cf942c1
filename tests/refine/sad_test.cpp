#include <gtest/gtest.h>

#include <opencv2/core.hpp>

#include "lookup/refine/matcher.h"
#include "lookup/refine/sad.h"

using namespace lookup::refine;

// Every SIMD level the CPU has must give exactly the scalar SAD, for every patch width
// (full 16/32-byte chunks and each tail length) and for query blocks touching the row end.
TEST(Sad, SimdEqualsScalarForAllWidths) {
    cv::RNG rng(7);
    cv::Mat image(96, 120, CV_8UC1);
    rng.fill(image, cv::RNG::UNIFORM, 0, 256);
    const ImagePyramid pyr = ImagePyramid::build(image, 0);
    const cv::Mat& q = pyr.levels[0];
    std::vector<SimdLevel> levels = {SimdLevel::Scalar};
    if (bestSimdLevel() != SimdLevel::Scalar) levels.push_back(SimdLevel::Sse2);
    if (bestSimdLevel() == SimdLevel::Avx2) levels.push_back(SimdLevel::Avx2);
    ASSERT_GE(levels.size(), 2u) << "this x86-64 build should have SSE2 at least";
    for (int w = 1; w <= 80; ++w) {
        const int h = 1 + w % 17;
        const PaddedPatch p = PaddedPatch::from(image, cv::Rect(3, 5, w, h));
        for (int trial = 0; trial < 8; ++trial) {
            const int x = trial == 0 ? q.cols - w : rng.uniform(0, q.cols - w + 1);
            const int y = trial == 0 ? q.rows - h : rng.uniform(0, q.rows - h + 1);
            const std::uint8_t* block = q.ptr<std::uint8_t>(y) + x;
            const std::uint32_t expected = sadScalar(p, block, q.step[0]);
            for (SimdLevel level : levels) {
                EXPECT_EQ(sad(level, p, block, q.step[0]), expected)
                    << "width " << w << " level " << toString(level);
            }
        }
    }
}

TEST(Sad, KnownValue) {
    cv::Mat a(4, 20, CV_8UC1, cv::Scalar(10));
    cv::Mat b(4, 20, CV_8UC1, cv::Scalar(13));
    const PaddedPatch p = PaddedPatch::from(a, cv::Rect(0, 0, 20, 4));
    const ImagePyramid pb = ImagePyramid::build(b, 0);
    EXPECT_EQ(sad(bestSimdLevel(), p, pb.levels[0].data, pb.levels[0].step[0]), 3u * 80u);
}

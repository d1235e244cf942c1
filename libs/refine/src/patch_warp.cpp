#include "lookup/refine/patch_warp.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <opencv2/imgproc.hpp>

#if defined(__x86_64__) || defined(__i386__)
#define LOOKUP_REFINE_X86 1
#include <immintrin.h>
#endif

namespace lookup::refine {

#ifdef LOOKUP_REFINE_X86
namespace {

// One sample with any of its taps outside the image (or a position far off or not finite).
std::uint8_t sampleNearBorder(const cv::Mat& src, float sx, float sy) {
    if (!(std::abs(sx) < 1e6f && std::abs(sy) < 1e6f)) return 0;
    const int x0 = cvFloor(sx), y0 = cvFloor(sy);
    const float fx = sx - float(x0), fy = sy - float(y0);
    const auto at = [&](int x, int y) {
        return x >= 0 && y >= 0 && x < src.cols && y < src.rows ? float(src.at<std::uint8_t>(y, x))
                                                                : 0.f;
    };
    const float top = at(x0, y0) + fx * (at(x0 + 1, y0) - at(x0, y0));
    const float bottom = at(x0, y0 + 1) + fx * (at(x0 + 1, y0 + 1) - at(x0, y0 + 1));
    return static_cast<std::uint8_t>(top + fy * (bottom - top) + 0.5f);
}

// The grey level `shift` bits up in each gathered 32-bit word.
__attribute__((target("avx2"))) inline __m256 tap(__m256i taps, int shift, __m256i byte) {
    return _mm256_cvtepi32_ps(_mm256_and_si256(_mm256_srli_epi32(taps, shift), byte));
}

__attribute__((target("avx2,fma"))) void warpPatchAvx2(const cv::Mat& src, const cv::Matx33d& M,
                                                       cv::Mat& dst) {
    const std::uint8_t* s = src.ptr<std::uint8_t>();
    const auto step = static_cast<int>(src.step[0]);
    // Taps x0, x0 + 1 are read as one 4-byte gather, which must stay inside the buffer (a view's
    // last row may end where its parent's buffer does).
    const auto last_row_bytes = static_cast<int>(
        std::min<std::ptrdiff_t>(src.datalimit - src.ptr<std::uint8_t>(src.rows - 1), step));
    const int x0_max = std::min(src.cols - 2, last_row_bytes - 4);
    const __m256i below = _mm256_set1_epi32(-1), right = _mm256_set1_epi32(x0_max + 1),
                  bottom = _mm256_set1_epi32(src.rows - 1), steps = _mm256_set1_epi32(step),
                  byte = _mm256_set1_epi32(0xff);
    const __m256 lane = _mm256_setr_ps(0, 1, 2, 3, 4, 5, 6, 7);
    const __m256 m00 = _mm256_set1_ps(float(M(0, 0))), m10 = _mm256_set1_ps(float(M(1, 0))),
                 m20 = _mm256_set1_ps(float(M(2, 0)));
    const int lanes = std::min(dst.cols, 8);
    for (int y = 0; y < dst.rows; ++y) {
        std::uint8_t* d = dst.ptr<std::uint8_t>(y);
        const __m256 cx = _mm256_set1_ps(float(M(0, 1) * y + M(0, 2))),
                     cy = _mm256_set1_ps(float(M(1, 1) * y + M(1, 2))),
                     cw = _mm256_set1_ps(float(M(2, 1) * y + M(2, 2)));
        // Eight pixels at a time; the last block overlaps the one before (same values).
        for (int next = 0; next < dst.cols; next += 8) {
            const int x = std::max(0, std::min(next, dst.cols - 8));
            const __m256 xs = _mm256_add_ps(_mm256_set1_ps(float(x)), lane);
            const __m256 w = _mm256_fmadd_ps(m20, xs, cw);
            const __m256 inv_w = _mm256_div_ps(_mm256_set1_ps(1.f), w);
            const __m256 sx = _mm256_mul_ps(_mm256_fmadd_ps(m00, xs, cx), inv_w);
            const __m256 sy = _mm256_mul_ps(_mm256_fmadd_ps(m10, xs, cy), inv_w);
            const __m256 fx0 = _mm256_floor_ps(sx), fy0 = _mm256_floor_ps(sy);
            const __m256i x0 = _mm256_cvttps_epi32(fx0), y0 = _mm256_cvttps_epi32(fy0);
            const __m256i inside = _mm256_and_si256(
                _mm256_and_si256(_mm256_cmpgt_epi32(x0, below), _mm256_cmpgt_epi32(right, x0)),
                _mm256_and_si256(_mm256_cmpgt_epi32(y0, below), _mm256_cmpgt_epi32(bottom, y0)));
            if (lanes < 8 || _mm256_movemask_epi8(inside) != -1) {
                alignas(32) float px[8], py[8];
                _mm256_store_ps(px, sx);
                _mm256_store_ps(py, sy);
                for (int k = 0; k < lanes; ++k) d[x + k] = sampleNearBorder(src, px[k], py[k]);
                continue;
            }
            const __m256i at = _mm256_add_epi32(_mm256_mullo_epi32(y0, steps), x0);
            const __m256i upper = _mm256_i32gather_epi32(reinterpret_cast<const int*>(s), at, 1);
            const __m256i lower =
                _mm256_i32gather_epi32(reinterpret_cast<const int*>(s + step), at, 1);
            const __m256 fx = _mm256_sub_ps(sx, fx0), fy = _mm256_sub_ps(sy, fy0);
            const __m256 v00 = tap(upper, 0, byte), v01 = tap(upper, 8, byte);
            const __m256 v10 = tap(lower, 0, byte), v11 = tap(lower, 8, byte);
            const __m256 top = _mm256_fmadd_ps(fx, _mm256_sub_ps(v01, v00), v00);
            const __m256 low = _mm256_fmadd_ps(fx, _mm256_sub_ps(v11, v10), v10);
            const __m256 v = _mm256_fmadd_ps(fy, _mm256_sub_ps(low, top), top);
            const __m256i grey = _mm256_cvttps_epi32(_mm256_add_ps(v, _mm256_set1_ps(0.5f)));
            const __m256i bytes = _mm256_packus_epi16(_mm256_packus_epi32(grey, grey),
                                                      _mm256_packus_epi32(grey, grey));
            const auto first = static_cast<std::uint32_t>(_mm256_cvtsi256_si32(bytes));
            const auto second = static_cast<std::uint32_t>(_mm256_extract_epi32(bytes, 4));
            std::memcpy(d + x, &first, 4);
            std::memcpy(d + x + 4, &second, 4);
        }
    }
}

}  // namespace
#endif

void warpPatch(SimdLevel level, const cv::Mat& src, const cv::Matx33d& dst_to_src, cv::Mat& dst) {
    CV_Assert(src.type() == CV_8UC1 && dst.type() == CV_8UC1);
#ifdef LOOKUP_REFINE_X86
    if (level == SimdLevel::Avx2 && !src.empty()) {
        warpPatchAvx2(src, dst_to_src, dst);
        return;
    }
#endif
    cv::warpPerspective(src, dst, cv::Mat(dst_to_src), dst.size(),
                        cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                        cv::Scalar(0));
}

}  // namespace lookup::refine

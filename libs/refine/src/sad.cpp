#include "lookup/refine/sad.h"

#include <algorithm>
#include <cstring>

#if defined(__x86_64__) || defined(__i386__)
#define LOOKUP_REFINE_X86 1
#include <immintrin.h>
#endif

namespace lookup::refine {

const char* toString(SimdLevel level) {
    switch (level) {
        case SimdLevel::Avx2:
            return "avx2";
        case SimdLevel::Sse2:
            return "sse2";
        default:
            return "scalar";
    }
}

SimdLevel bestSimdLevel() {
#ifdef LOOKUP_REFINE_X86
    static const SimdLevel level = [] {
        __builtin_cpu_init();
        if (__builtin_cpu_supports("avx2")) return SimdLevel::Avx2;
        if (__builtin_cpu_supports("sse2")) return SimdLevel::Sse2;
        return SimdLevel::Scalar;
    }();
    return level;
#else
    return SimdLevel::Scalar;
#endif
}

PaddedPatch PaddedPatch::from(const cv::Mat& image, const cv::Rect& roi) {
    CV_Assert(image.type() == CV_8UC1);
    CV_Assert((roi & cv::Rect(0, 0, image.cols, image.rows)) == roi);
    PaddedPatch p;
    p.width = roi.width;
    p.height = roi.height;
    p.stride = (roi.width + 31) / 32 * 32;
    p.data.assign(static_cast<std::size_t>(p.stride) * p.height, 0);
    for (int y = 0; y < roi.height; ++y) {
        std::memcpy(&p.data[static_cast<std::size_t>(y) * p.stride],
                    image.ptr<std::uint8_t>(roi.y + y) + roi.x, roi.width);
    }
    return p;
}

std::uint32_t sadScalar(const PaddedPatch& patch, const std::uint8_t* query,
                        std::size_t query_stride) {
    std::uint32_t sum = 0;
    for (int y = 0; y < patch.height; ++y) {
        const std::uint8_t* a = &patch.data[static_cast<std::size_t>(y) * patch.stride];
        const std::uint8_t* b = query + y * query_stride;
        for (int x = 0; x < patch.width; ++x) {
            sum += static_cast<std::uint32_t>(std::abs(int(a[x]) - int(b[x])));
        }
    }
    return sum;
}

#ifdef LOOKUP_REFINE_X86
namespace {

// 32 x 0xff then 32 x 0: loading at maskFor(n) keeps the first n (0..32) bytes.
alignas(32) const std::uint8_t kMaskBytes[64] = {
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,
    0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff};
const std::uint8_t* maskFor(int n) { return kMaskBytes + 32 - n; }

// The patch's padding is zero, so masking the query's overrun bytes to zero makes them add 0.
std::uint32_t sadSse2(const PaddedPatch& patch, const std::uint8_t* query,
                      std::size_t query_stride) {
    const int full = patch.width / 16;
    const int rem = patch.width % 16;
    const __m128i tail_mask = _mm_loadu_si128(reinterpret_cast<const __m128i*>(maskFor(rem)));
    __m128i acc = _mm_setzero_si128();
    for (int y = 0; y < patch.height; ++y) {
        const std::uint8_t* a = &patch.data[static_cast<std::size_t>(y) * patch.stride];
        const std::uint8_t* b = query + y * query_stride;
        for (int c = 0; c < full; ++c) {
            const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + 16 * c));
            const __m128i vb = _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + 16 * c));
            acc = _mm_add_epi64(acc, _mm_sad_epu8(va, vb));
        }
        if (rem) {
            const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + 16 * full));
            const __m128i vb = _mm_and_si128(
                _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + 16 * full)), tail_mask);
            acc = _mm_add_epi64(acc, _mm_sad_epu8(va, vb));
        }
    }
    return static_cast<std::uint32_t>(_mm_cvtsi128_si32(acc) +
                                      _mm_cvtsi128_si32(_mm_srli_si128(acc, 8)));
}

__attribute__((target("avx2"))) std::uint32_t sadAvx2(const PaddedPatch& patch,
                                                      const std::uint8_t* query,
                                                      std::size_t query_stride) {
    const int full = patch.width / 32;
    const int rem = patch.width % 32;
    const bool tail32 = rem > 16;
    const __m256i mask32 = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(maskFor(rem)));
    const __m128i mask16 = _mm_loadu_si128(reinterpret_cast<const __m128i*>(maskFor(rem)));
    __m256i acc = _mm256_setzero_si256();
    __m128i acc16 = _mm_setzero_si128();
    for (int y = 0; y < patch.height; ++y) {
        const std::uint8_t* a = &patch.data[static_cast<std::size_t>(y) * patch.stride];
        const std::uint8_t* b = query + y * query_stride;
        for (int c = 0; c < full; ++c) {
            const __m256i va = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a + 32 * c));
            const __m256i vb = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b + 32 * c));
            acc = _mm256_add_epi64(acc, _mm256_sad_epu8(va, vb));
        }
        if (tail32) {
            const __m256i va = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a + 32 * full));
            const __m256i vb = _mm256_and_si256(
                _mm256_loadu_si256(reinterpret_cast<const __m256i*>(b + 32 * full)), mask32);
            acc = _mm256_add_epi64(acc, _mm256_sad_epu8(va, vb));
        } else if (rem) {
            const __m128i va = _mm_loadu_si128(reinterpret_cast<const __m128i*>(a + 32 * full));
            const __m128i vb = _mm_and_si128(
                _mm_loadu_si128(reinterpret_cast<const __m128i*>(b + 32 * full)), mask16);
            acc16 = _mm_add_epi64(acc16, _mm_sad_epu8(va, vb));
        }
    }
    const __m128i sum = _mm_add_epi64(
        _mm_add_epi64(_mm256_castsi256_si128(acc), _mm256_extracti128_si256(acc, 1)), acc16);
    return static_cast<std::uint32_t>(_mm_cvtsi128_si32(sum) +
                                      _mm_cvtsi128_si32(_mm_srli_si128(sum, 8)));
}

}  // namespace
#endif

std::uint32_t sad(SimdLevel level, const PaddedPatch& patch, const std::uint8_t* query,
                  std::size_t query_stride) {
#ifdef LOOKUP_REFINE_X86
    switch (level) {
        case SimdLevel::Avx2:
            return sadAvx2(patch, query, query_stride);
        case SimdLevel::Sse2:
            return sadSse2(patch, query, query_stride);
        default:
            break;
    }
#else
    (void)level;
#endif
    return sadScalar(patch, query, query_stride);
}

}  // namespace lookup::refine

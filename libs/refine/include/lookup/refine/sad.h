#pragma once
// Sum of Absolute Differences kernels: the matcher's hot path (paper Sec. III-A). A plain
// scalar version is kept as the reference; SSE2 and AVX2 versions (runtime dispatch, so the
// library runs on any x86-64 and builds elsewhere) must return exactly the same integers.

#include <cstddef>
#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace lookup::refine {

enum class SimdLevel { Scalar, Sse2, Avx2 };
const char* toString(SimdLevel level);

/// Best level this CPU supports (AVX2 > SSE2 > scalar).
SimdLevel bestSimdLevel();

/// A reference patch copied into a zero-padded buffer whose stride is a multiple of 32.
struct PaddedPatch {
    std::vector<std::uint8_t> data;
    int width = 0;
    int height = 0;
    int stride = 0;

    /// Copies `roi` of the CV_8UC1 `image` (roi must lie inside the image).
    static PaddedPatch from(const cv::Mat& image, const cv::Rect& roi);
};

/// SAD between `patch` and the query block whose top-left pixel is `query` (row stride
/// `query_stride` bytes). The SIMD versions read up to 31 bytes beyond each block row
/// (ImagePyramid guarantees they are readable) and ignore them.
std::uint32_t sadScalar(const PaddedPatch& patch, const std::uint8_t* query,
                        std::size_t query_stride);
std::uint32_t sad(SimdLevel level, const PaddedPatch& patch, const std::uint8_t* query,
                  std::size_t query_stride);

}  // namespace lookup::refine

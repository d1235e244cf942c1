#pragma once
// Whole-image descriptors of the coarse stage (SeqSLAM, Milford & Wyeth 2012, Sec. III-A):
// the grey image is area-downsampled to a small thumbnail and each P x P patch is normalised
// to zero mean and unit deviation, which removes the illumination changes of a headlight-lit
// tunnel while keeping its coarse structure.

#include <mrpt/img/CImage.h>

#include <cstdint>
#include <vector>

#include "lookup/coarse/options.h"

namespace lookup::coarse {

/// Patch-normalised thumbnail, row-major, thumb_width_px x thumb_height_px bytes. Each value
/// is 128 + 32 z (clamped to [0, 255]) where z is the pixel's deviation from its patch mean
/// in patch standard deviations; flat patches are 128.
using Descriptor = std::vector<std::uint8_t>;

/// Descriptor of a grey or colour image. Throws std::invalid_argument for an empty image.
Descriptor computeDescriptor(const mrpt::img::CImage& image, const CoarseOptions& options);

/// Mean absolute difference of two descriptors of equal length, in descriptor units
/// (divide by 32 for patch standard deviations). Throws std::invalid_argument on a length
/// mismatch.
float descriptorDifference(const Descriptor& a, const Descriptor& b);

}  // namespace lookup::coarse

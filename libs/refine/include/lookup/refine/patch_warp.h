#pragma once
// Bilinear perspective warp of a small patch: the motion-compensated matcher warps every
// sample point's patch on every pyramid level, and cv::warpPerspective's per-call set-up and
// 1/32-pixel remap tables cost more than the SAD search on patches this small. The AVX2
// version computes eight source positions at a time in float and gathers their four taps;
// without AVX2 it calls OpenCV.

#include <opencv2/core.hpp>

#include "lookup/refine/sad.h"

namespace lookup::refine {

/// dst(x, y) = `src` sampled bilinearly where `dst_to_src` maps pixel (x, y), 0 for taps
/// outside `src`: cv::warpPerspective with WARP_INVERSE_MAP, INTER_LINEAR and a constant 0
/// border. Both inputs CV_8UC1; `dst` keeps its size (it may be a view into a larger buffer).
/// The AVX2 version samples at the exact position where OpenCV rounds it to 1/32 pixel: on a
/// ceiling's texture the two differ by a grey level, a few more where taps straddle the edge.
void warpPatch(SimdLevel level, const cv::Mat& src, const cv::Matx33d& dst_to_src, cv::Mat& dst);

}  // namespace lookup::refine

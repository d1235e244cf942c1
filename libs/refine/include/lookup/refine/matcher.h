#pragma once
// Pixel Correspondence Matcher (paper Sec. III-A): for each sample point, the l_patch x l_patch
// reference patch centred on it is compared by SAD with every candidate in an L_SR x L_SR query
// window centred on the same pixel (or on a predicted offset), with a sub-pixel peak and a
// quality. Coarse-to-fine: exhaustive search on pyramid level `pyramid_levels`, then a local
// +-refine_radius_px search (re-centred until the best is interior) on each finer level;
// pyramid_levels = 0 is the paper's exhaustive search, kept for verification.
//
// Conventions: a patch of side l centred on integer pixel c covers c - l/2 .. c - l/2 + l - 1;
// window offsets run from -L_SR/2 to +L_SR/2 inclusive.

#include <vector>

#include "lookup/refine/options.h"
#include "lookup/refine/sad.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

/// Number of coarser pyramid levels the matcher uses for these options (levels are dropped
/// while the coarsest patch would be smaller than min_top_patch_px).
int effectivePyramidLevels(const MatcherOptions& options);

/// Matches every point (rounded to integer pixels) of `reference` into `query`.
/// `predicted_offsets` (query - reference, px) is empty or one per point; the search window is
/// centred at the point plus its rounded offset. Both pyramids need at least
/// effectivePyramidLevels(options) + 1 levels. Never throws on image content: a point that
/// cannot be matched gets a status saying why.
std::vector<PointMatch> matchPoints(const ImagePyramid& reference, const ImagePyramid& query,
                                    const std::vector<cv::Point2f>& points,
                                    const std::vector<cv::Point2f>& predicted_offsets,
                                    const MatcherOptions& options);

/// Same, with the SAD kernel forced (tests and benchmarks compare kernels).
std::vector<PointMatch> matchPoints(const ImagePyramid& reference, const ImagePyramid& query,
                                    const std::vector<cv::Point2f>& points,
                                    const std::vector<cv::Point2f>& predicted_offsets,
                                    const MatcherOptions& options, SimdLevel simd);

/// Motion-compensated matching (MatcherOptions::compensate_motion): the reference level 0 is
/// warped into the query frame by `reference_to_query` (the homography predicted from the
/// coarse pose, e.g. ceilingHomography), so SAD compares patches that the predicted rotation,
/// scale and tilt have already aligned; each point is searched around its predicted position
/// H * p with the usual L_SR window. Returned matches carry true reference pixels (the integer
/// warped-frame centre mapped back through H^-1) and query pixels, ready for the homography
/// estimator. Points whose predicted position is not finite or whose warped patch would need
/// reference pixels outside the reference image are OutOfImage. With H = identity this is
/// matchPoints without offsets.
std::vector<PointMatch> matchPointsCompensated(const ImagePyramid& reference,
                                               const ImagePyramid& query,
                                               const std::vector<cv::Point2f>& points,
                                               const cv::Matx33d& reference_to_query,
                                               const MatcherOptions& options, SimdLevel simd);

/// Same with the kernel chosen by options.use_simd.
std::vector<PointMatch> matchPointsCompensated(const ImagePyramid& reference,
                                               const ImagePyramid& query,
                                               const std::vector<cv::Point2f>& points,
                                               const cv::Matx33d& reference_to_query,
                                               const MatcherOptions& options);

}  // namespace lookup::refine

#pragma once
// Training labels for the sample-point FCN (paper Sec. III-B): points on a dense regular grid
// of a reference are matched into a query image and RANSAC splits them into inliers (good
// sample points) and outliers. No manual labels.

#include <opencv2/core.hpp>
#include <vector>

#include "lookup/refine/homography.h"
#include "lookup/refine/options.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

/// Dense grid (spacing `grid_step_px`, kept patch_px / 2 from the borders) -> match ->
/// RANSAC homography. Each returned match carries `inlier` (the label) and `status` (points the
/// matcher rejected are labelled outliers). Points near the border whose search window is
/// clipped get BorderPeak / OutOfImage when the motion points outwards: a trainer may prefer to
/// mask those in the loss rather than call them bad. `result`, if given, receives the fit.
/// Images are CV_8UC1 (or CV_8UC3, converted).
std::vector<PointMatch> labelGridPoints(const cv::Mat& reference, const cv::Mat& query,
                                        int grid_step_px, const MatcherOptions& matcher,
                                        const HomographyOptions& homography,
                                        HomographyResult* result = nullptr);

}  // namespace lookup::refine

#include "lookup/refine/labels.h"

#include "lookup/refine/matcher.h"

namespace lookup::refine {

std::vector<PointMatch> labelGridPoints(const cv::Mat& reference, const cv::Mat& query,
                                        int grid_step_px, const MatcherOptions& matcher,
                                        const HomographyOptions& homography,
                                        HomographyResult* result) {
    CV_Assert(grid_step_px >= 1);
    const int levels = effectivePyramidLevels(matcher);
    const ImagePyramid ref = ImagePyramid::build(reference, levels, matcher);
    const ImagePyramid qry = ImagePyramid::build(query, levels, matcher);
    std::vector<cv::Point2f> points;
    const int margin = matcher.patch_px / 2;
    for (int y = margin; y + margin < reference.rows; y += grid_step_px) {
        for (int x = margin; x + margin < reference.cols; x += grid_step_px) {
            points.emplace_back(float(x), float(y));
        }
    }
    std::vector<PointMatch> matches = matchPoints(ref, qry, points, {}, matcher);
    const HomographyResult fit = estimateHomography(matches, homography);
    if (result) *result = fit;
    return matches;
}

}  // namespace lookup::refine

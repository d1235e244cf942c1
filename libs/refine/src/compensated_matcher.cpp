#include <cmath>
#include <opencv2/imgproc.hpp>

#include "lookup/refine/geometry.h"
#include "lookup/refine/matcher.h"

namespace lookup::refine {

std::vector<PointMatch> matchPointsCompensated(const ImagePyramid& reference,
                                               const ImagePyramid& query,
                                               const std::vector<cv::Point2f>& points,
                                               const cv::Matx33d& H, const MatcherOptions& options,
                                               SimdLevel simd) {
    std::vector<PointMatch> out(points.size());
    for (std::size_t i = 0; i < points.size(); ++i) {
        out[i].reference_px = out[i].query_px = points[i];  // OutOfImage until matched
    }
    if (reference.empty() || query.empty() || !cv::checkRange(cv::Mat(H)) ||
        std::abs(cv::determinant(H)) < 1e-12) {
        return out;
    }
    const cv::Matx33d H_inv = H.inv();
    const cv::Mat& ref0 = reference.levels[0];
    const cv::Mat& qry0 = query.levels[0];

    // Which points keep their whole warped patch on reference pixels: the patch square maps
    // through H^-1 to a convex quadrilateral, inside the reference iff its corners are (one
    // pixel of margin for the bilinear taps).
    const double half = options.patch_px / 2.0;
    const cv::Rect2d inside(1.0, 1.0, ref0.cols - 3.0, ref0.rows - 3.0);
    std::vector<cv::Point2f> centres;
    std::vector<std::size_t> index;
    for (std::size_t i = 0; i < points.size(); ++i) {
        cv::Point2d q;
        if (!applyHomography(H, cv::Point2d(points[i]), q) || std::abs(q.x) > 1e6 ||
            std::abs(q.y) > 1e6) {
            continue;
        }
        const cv::Point2d c(std::round(q.x), std::round(q.y));
        bool ok = true;
        for (const cv::Point2d corner :
             {cv::Point2d(-half - 1, -half - 1), cv::Point2d(half + 1, -half - 1),
              cv::Point2d(-half - 1, half + 1), cv::Point2d(half + 1, half + 1)}) {
            cv::Point2d r;
            ok = ok && applyHomography(H_inv, c + corner, r) && inside.contains(r);
        }
        if (!ok) continue;
        centres.emplace_back(float(c.x), float(c.y));
        index.push_back(i);
    }
    if (centres.empty()) return out;

    // The reference as the query camera would see it (black where the reference has no pixel;
    // the corner test keeps every used patch off that area).
    cv::Mat warped;
    cv::warpPerspective(ref0, warped, cv::Mat(H), qry0.size(), cv::INTER_LINEAR,
                        cv::BORDER_CONSTANT, cv::Scalar(0));
    ImagePyramid warped_pyramid =
        ImagePyramid::build(warped, int(query.levels.size()) - 1, /*normalize=*/false);
    warped_pyramid.normalized = reference.normalized;

    std::vector<PointMatch> matched =
        matchPoints(warped_pyramid, query, centres, {}, options, simd);
    for (std::size_t k = 0; k < index.size(); ++k) {
        PointMatch& m = matched[k];
        cv::Point2d r;
        applyHomography(H_inv, cv::Point2d(centres[k]), r);  // finite: checked with the corners
        m.reference_px = cv::Point2f(float(r.x), float(r.y));
        if (!m.matched()) m.query_px = centres[k];
        out[index[k]] = m;
    }
    return out;
}

std::vector<PointMatch> matchPointsCompensated(const ImagePyramid& reference,
                                               const ImagePyramid& query,
                                               const std::vector<cv::Point2f>& points,
                                               const cv::Matx33d& H,
                                               const MatcherOptions& options) {
    return matchPointsCompensated(reference, query, points, H, options,
                                  options.use_simd ? bestSimdLevel() : SimdLevel::Scalar);
}

}  // namespace lookup::refine

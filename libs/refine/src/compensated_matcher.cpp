#include <algorithm>
#include <cmath>
#include <vector>

#include "lookup/refine/geometry.h"
#include "lookup/refine/matcher.h"
#include "lookup/refine/patch_warp.h"

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

    // The reference as the query camera would see it, but only where the matcher reads it:
    // each point's patch on each pyramid level, warped from the reference's own level with
    // the homography scaled to that level (level k pixel i sits at level-0 pixel 2^k i, as
    // pyrDown has it). Warping whole images cost more than the search itself and did not
    // shrink with fewer sample points.
    const int n_levels = int(std::min(reference.levels.size(), query.levels.size()));
    ImagePyramid warped_pyramid;
    warped_pyramid.normalized = reference.normalized;
    warped_pyramid.illumination_sigma_px = reference.illumination_sigma_px;
    warped_pyramid.max_contrast_gain = reference.max_contrast_gain;
    // Level buffers are kept between calls and never cleared: the matcher reads a reference
    // level only inside the patches written below (it copies each patch's own rectangle).
    thread_local std::vector<cv::Mat> buffers;
    if (int(buffers.size()) < n_levels) buffers.resize(std::size_t(n_levels));
    for (int k = 0; k < n_levels; ++k) {
        const cv::Mat& q = query.levels[k];
        // 32 spare columns as ImagePyramid::build leaves for SIMD.
        buffers[std::size_t(k)].create(q.rows, q.cols + 32, CV_8UC1);
        cv::Mat level = buffers[std::size_t(k)](cv::Rect(0, 0, q.cols, q.rows));
        const double s = 1.0 / (1 << k);
        const cv::Matx33d S(s, 0, 0, 0, s, 0, 0, 0, 1), S_inv(1 / s, 0, 0, 0, 1 / s, 0, 0, 0, 1);
        const cv::Matx33d H_k_inv = S * H_inv * S_inv;
        const int side = options.patch_px >> k;
        for (const cv::Point2f& c : centres) {
            // The matcher's patch at this level, one pixel wider each side.
            const cv::Point centre(int(c.x) >> k, int(c.y) >> k);
            const cv::Rect patch =
                cv::Rect(centre.x - side / 2 - 1, centre.y - side / 2 - 1, side + 2, side + 2) &
                cv::Rect(0, 0, level.cols, level.rows);
            if (patch.empty()) continue;
            const cv::Matx33d patch_to_ref =
                H_k_inv * cv::Matx33d(1, 0, patch.x, 0, 1, patch.y, 0, 0, 1);
            cv::Mat dst = level(patch);
            warpPatch(simd, reference.levels[k], patch_to_ref, dst);
        }
        warped_pyramid.levels.push_back(level);
    }

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

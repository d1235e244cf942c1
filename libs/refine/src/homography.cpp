#include "lookup/refine/homography.h"

#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>

namespace lookup::refine {

bool decomposeHomography(const cv::Matx33d& H, const cv::Matx33d& K_reference,
                         const cv::Matx33d& K_query, PlaneMotion& chosen,
                         std::vector<PlaneMotion>* all) {
    // Normalised homography between the two cameras' rays, then decomposition with K = I.
    const cv::Matx33d Hn = K_query.inv() * H * K_reference;
    if (!cv::checkRange(cv::Mat(Hn)) || std::abs(cv::determinant(Hn)) < 1e-12) return false;
    std::vector<cv::Mat> Rs, ts, ns;
    const int n = cv::decomposeHomographyMat(Hn, cv::Matx33d::eye(), Rs, ts, ns);
    if (n <= 0) return false;
    std::vector<PlaneMotion> motions;
    for (int i = 0; i < n; ++i) {
        PlaneMotion m;
        m.rotation = cv::Matx33d(Rs[i]);
        m.translation_over_d = cv::Vec3d(ts[i]);
        m.normal = cv::Vec3d(ns[i]);
        m.tilt_deg = std::acos(std::clamp(m.rotation(2, 2), -1.0, 1.0)) * 180.0 / CV_PI;
        m.yaw_deg = std::atan2(m.rotation(1, 0), m.rotation(0, 0)) * 180.0 / CV_PI;
        motions.push_back(m);
    }
    // Paper: choose the smaller pitch and roll; of the sign-flipped pair, the plane in front.
    const auto better = [](const PlaneMotion& a, const PlaneMotion& b) {
        if (std::abs(a.tilt_deg - b.tilt_deg) > 1e-6) return a.tilt_deg < b.tilt_deg;
        return a.normal[2] > b.normal[2];
    };
    chosen = *std::min_element(motions.begin(), motions.end(), better);
    if (all) *all = motions;
    return true;
}

HomographyResult estimateHomography(std::vector<PointMatch>& matches, const HomographyOptions& o,
                                    const cv::Matx33d* K_reference, const cv::Matx33d* K_query) {
    HomographyResult r;
    std::vector<cv::Point2f> src, dst;
    std::vector<std::size_t> index;
    for (std::size_t i = 0; i < matches.size(); ++i) {
        matches[i].inlier = false;
        if (!matches[i].matched()) continue;
        src.push_back(matches[i].reference_px);
        dst.push_back(matches[i].query_px);
        index.push_back(i);
    }
    r.used_points = int(src.size());
    if (src.size() < 4) {
        r.reason = "only " + std::to_string(src.size()) + " matched points (a homography needs 4)";
        return r;
    }
    r.ransac = int(src.size()) > o.ransac_min_points;
    std::vector<std::uint8_t> mask;
    cv::Mat H;
    try {
        H = r.ransac ? cv::findHomography(src, dst, cv::RANSAC, o.ransac_threshold_px, mask,
                                          o.ransac_max_iterations, o.ransac_confidence)
                     : cv::findHomography(src, dst, 0, 0.0, mask);
    } catch (const cv::Exception& e) {
        r.reason = std::string("cv::findHomography failed: ") + e.what();
        return r;
    }
    if (H.empty() || !cv::checkRange(H)) {
        r.reason = "no homography fits the matches (degenerate point set)";
        return r;
    }
    r.H = cv::Matx33d(H);
    for (std::size_t k = 0; k < index.size(); ++k) {
        const bool in = mask.empty() || mask[k] != 0;
        matches[index[k]].inlier = in;
        r.inliers += in ? 1 : 0;
    }
    r.ok = true;
    if (K_reference && K_query) {
        std::vector<PlaneMotion> all;
        r.decomposed = decomposeHomography(r.H, *K_reference, *K_query, r.motion, &all);
        r.solutions = int(all.size());
    }
    return r;
}

}  // namespace lookup::refine

#include "lookup/refine/correspondence_methods.h"

#include <cmath>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "lookup/common/config.h"
#include "lookup/refine/geometry.h"

namespace lookup::refine {

namespace {
const common::EnumNames<CorrespondenceMethod> kMethods = {{"sad", CorrespondenceMethod::Sad},
                                                          {"orb", CorrespondenceMethod::Orb},
                                                          {"ecc", CorrespondenceMethod::Ecc}};
}  // namespace

const char* toString(CorrespondenceMethod m) {
    for (const auto& [name, value] : kMethods) {
        if (value == m) return name.c_str();
    }
    return "sad";
}

bool parseCorrespondenceMethod(const std::string& name, CorrespondenceMethod& out) {
    const auto method = common::enumValue(kMethods, name);
    if (method) out = *method;
    return method.has_value();
}

// ---------------------------------------------------------------- options
void CorrespondenceOptions::declareKeys(common::OptionsTable& t) {
    t.add("method", method, kMethods);
    t.add("orb_features", orb_features, 8, 100000);
    t.add("orb_ratio", orb_ratio);
    t.add("orb_min_matches", orb_min_matches, 4, 100000);  // a homography needs 4 points
    t.add("ecc_pyramid_levels", ecc_pyramid_levels, 0, 4);
    t.add("ecc_max_iterations", ecc_max_iterations, 1, 100000);
    t.add("ecc_epsilon", ecc_epsilon);
    t.add("ecc_min_correlation", ecc_min_correlation, -1.0, 1.0);
    t.add("ecc_gauss_filter_px", ecc_gauss_filter_px, 1, 99);
}

void CorrespondenceOptions::check() const {
    common::OptionsCheck c("refine.correspondence");
    checkRanges(c);
    c.require(orb_ratio > 0.0 && orb_ratio <= 1.0, "orb_ratio", "in (0, 1]");
    c.require(ecc_epsilon > 0.0, "ecc_epsilon", "> 0");
    c.require(ecc_gauss_filter_px % 2 == 1, "ecc_gauss_filter_px", "odd");
    c.throwIfFailed();
}

// ---------------------------------------------------------------- matchers
namespace {

bool usableHomography(const cv::Matx33d& H) {
    return cv::checkRange(cv::Mat(H)) && std::abs(cv::determinant(H)) > 1e-12;
}

// The matcher's pyramids pad each row (ImagePyramid: a view into a wider buffer); OpenCV's
// filters read pixels beyond a view's edge (no BORDER_ISOLATED inside ORB / ECC), so the black
// padding would become a strong edge shared by both images. A compact copy has true borders.
cv::Mat compact(const cv::Mat& image) { return image.isContinuous() ? image : image.clone(); }

CorrespondenceResult failed(std::string reason) {
    CorrespondenceResult r;
    r.reason = std::move(reason);
    return r;
}

}  // namespace

CorrespondenceResult matchOrb(const cv::Mat& reference_view, const cv::Mat& query_view,
                              const std::optional<cv::Matx33d>& reference_to_query,
                              const CorrespondenceOptions& options) {
    if (reference_view.empty() || query_view.empty() || reference_view.type() != CV_8UC1 ||
        query_view.type() != CV_8UC1) {
        return failed("orb: reference or query image empty or not CV_8UC1");
    }
    const cv::Mat reference = compact(reference_view), query = compact(query_view);
    // Detect on the reference as the query camera would see it, when a prediction exists, so
    // the descriptors compare aligned views; keypoints stay off the warp's black border.
    cv::Mat ref_view = reference, mask;
    cv::Matx33d H_inv = cv::Matx33d::eye();
    if (reference_to_query) {
        if (!usableHomography(*reference_to_query)) {
            return failed("orb: predicted homography is singular or not finite");
        }
        H_inv = reference_to_query->inv();
        cv::warpPerspective(reference, ref_view, cv::Mat(*reference_to_query), query.size(),
                            cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
        cv::warpPerspective(cv::Mat(reference.size(), CV_8UC1, cv::Scalar(255)), mask,
                            cv::Mat(*reference_to_query), query.size(), cv::INTER_NEAREST,
                            cv::BORDER_CONSTANT, cv::Scalar(0));
        cv::erode(mask, mask, cv::getStructuringElement(cv::MORPH_RECT, cv::Size(33, 33)));
    }

    const cv::Ptr<cv::ORB> orb = cv::ORB::create(options.orb_features);
    std::vector<cv::KeyPoint> k_ref, k_qry;
    cv::Mat d_ref, d_qry;
    if (mask.empty()) {
        orb->detectAndCompute(ref_view, cv::noArray(), k_ref, d_ref);
    } else {
        orb->detectAndCompute(ref_view, mask, k_ref, d_ref);
    }
    orb->detectAndCompute(query, cv::noArray(), k_qry, d_qry);
    CorrespondenceResult res;
    res.reference_features = int(k_ref.size());
    res.query_features = int(k_qry.size());
    if (k_ref.size() < 2 || k_qry.size() < 2) {
        res.reason = "orb: too few features (reference " + std::to_string(k_ref.size()) +
                     ", query " + std::to_string(k_qry.size()) + ")";
        return res;
    }

    std::vector<std::vector<cv::DMatch>> knn;
    cv::BFMatcher(cv::NORM_HAMMING).knnMatch(d_ref, d_qry, knn, 2);
    for (const auto& pair : knn) {
        if (pair.size() < 2) continue;
        const cv::DMatch& best = pair[0];
        if (!(best.distance < options.orb_ratio * pair[1].distance)) continue;
        cv::Point2d ref_px;
        if (!applyHomography(H_inv, cv::Point2d(k_ref[best.queryIdx].pt), ref_px)) continue;
        PointMatch m;
        m.reference_px = cv::Point2f(float(ref_px.x), float(ref_px.y));
        m.query_px = k_qry[best.trainIdx].pt;
        m.quality = pair[1].distance > 0 ? 1.f - best.distance / pair[1].distance : 0.f;
        m.sad_per_px = best.distance;
        m.status = MatchStatus::Matched;
        res.matches.push_back(m);
    }
    if (int(res.matches.size()) < options.orb_min_matches) {
        res.reason = "orb: " + std::to_string(res.matches.size()) +
                     " matches pass the ratio test (< orb_min_matches " +
                     std::to_string(options.orb_min_matches) + "; " + std::to_string(k_ref.size()) +
                     " and " + std::to_string(k_qry.size()) + " features)";
        res.matches.clear();
        return res;
    }
    res.ok = true;
    return res;
}

CorrespondenceResult matchEcc(const cv::Mat& reference_view, const cv::Mat& query_view,
                              const std::vector<cv::Point2f>& points,
                              const std::optional<cv::Matx33d>& reference_to_query,
                              const CorrespondenceOptions& options) {
    CorrespondenceResult res;
    // Until ECC succeeds every point is testable but unmatched (counts against N_th).
    for (const auto& p : points) {
        PointMatch m;
        m.reference_px = m.query_px = p;
        m.status = MatchStatus::NotDistinctive;
        res.matches.push_back(m);
    }
    if (reference_view.empty() || query_view.empty() || reference_view.type() != CV_8UC1 ||
        query_view.type() != CV_8UC1) {
        res.reason = "ecc: reference or query image empty or not CV_8UC1";
        return res;
    }
    const cv::Mat reference = compact(reference_view), query = compact(query_view);
    cv::Matx33d W = reference_to_query.value_or(cv::Matx33d::eye());
    if (!usableHomography(W)) {
        res.reason = "ecc: predicted homography is singular or not finite";
        return res;
    }

    // Coarse to fine: pyrDown halves coordinates exactly (x_l = x_0 / 2^l), so the warp at
    // level l is S W S^-1 with S = diag(2^-l, 2^-l, 1).
    std::vector<cv::Mat> ref_levels{reference}, qry_levels{query};
    for (int l = 0; l < options.ecc_pyramid_levels; ++l) {
        if (ref_levels.back().cols < 64 || ref_levels.back().rows < 64) break;
        cv::Mat r, q;
        cv::pyrDown(ref_levels.back(), r);
        cv::pyrDown(qry_levels.back(), q);
        ref_levels.push_back(r);
        qry_levels.push_back(q);
    }
    const cv::TermCriteria stop(cv::TermCriteria::COUNT + cv::TermCriteria::EPS,
                                options.ecc_max_iterations, options.ecc_epsilon);
    for (int l = int(ref_levels.size()) - 1; l >= 0; --l) {
        const double s = std::ldexp(1.0, -l);
        const cv::Matx33d S(s, 0, 0, 0, s, 0, 0, 0, 1), S_inv(1 / s, 0, 0, 0, 1 / s, 0, 0, 0, 1);
        cv::Mat warp(S * W * S_inv);
        warp.convertTo(warp, CV_32F);
        try {
            res.correlation =
                cv::findTransformECC(ref_levels[l], qry_levels[l], warp, cv::MOTION_HOMOGRAPHY,
                                     stop, cv::noArray(), options.ecc_gauss_filter_px);
        } catch (const cv::Exception& e) {
            // OpenCV throws when the correlation decreases (no convergence) or turns NaN.
            res.reason = "ecc: did not converge at pyramid level " + std::to_string(l) + ": " +
                         (e.err.empty() ? std::string(e.what()) : e.err);
            return res;
        }
        cv::Mat warp64;
        warp.convertTo(warp64, CV_64F);
        W = S_inv * cv::Matx33d(warp64.ptr<double>()) * S;
        if (!std::isfinite(res.correlation) || !usableHomography(W)) {
            res.reason = "ecc: degenerate warp at pyramid level " + std::to_string(l);
            return res;
        }
    }
    res.warp = W;
    if (res.correlation < options.ecc_min_correlation) {
        res.reason = "ecc: correlation " + std::to_string(res.correlation) +
                     " < ecc_min_correlation " + std::to_string(options.ecc_min_correlation);
        return res;
    }
    const cv::Rect2d inside(0.0, 0.0, query.cols - 1.0, query.rows - 1.0);
    for (PointMatch& m : res.matches) {
        cv::Point2d q;
        if (!applyHomography(W, cv::Point2d(m.reference_px), q) || !inside.contains(q)) {
            m.status = MatchStatus::OutOfImage;
            continue;
        }
        m.query_px = cv::Point2f(float(q.x), float(q.y));
        m.quality = float(res.correlation);
        m.status = MatchStatus::Matched;
    }
    res.ok = true;
    return res;
}

}  // namespace lookup::refine

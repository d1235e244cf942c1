#pragma once
// Baseline correspondence methods that can replace the SAD matcher inside the Refiner: the
// off-the-shelf OpenCV ways of relating two ceiling images.
//
//   orb  cv::ORB features on both images, brute-force Hamming kNN with Lowe's ratio test;
//        sparse, at the detector's corners (not at the sample points).
//   ecc  cv::findTransformECC (MOTION_HOMOGRAPHY, Evangelidis & Psarakis 2008), coarse to fine
//        on an image pyramid; a dense warp, sampled at the sample points.
//
// Both return PointMatch correspondences in the SAD matcher's form (true reference pixels ->
// query pixels), so the homography RANSAC, the Ceres estimator and the acceptance run
// unchanged. With a coarse pose the Refiner passes the predicted plane-induced homography
// (ceilingHomography): ORB then detects on the reference warped into the query frame (as the
// motion-compensated SAD does) and ECC starts from it; without one, ORB matches the raw
// images and ECC starts from the identity.
//
// Counting for the acceptance (N_th, an inlier share over "testable sample points"):
//   orb  every ratio-test match is a testable point; the share is RANSAC inliers / matches.
//        Fewer than orb_min_matches matches give none at all (the reference is rejected).
//   ecc  every sample point whose warped position lies in the query image is a testable
//        point, and each is an exact sample of one homography, so RANSAC finds all of them
//        inliers: the share measures overlap, not agreement. ECC's own check is its
//        correlation coefficient (ecc_min_correlation); a warp below it, or one that does not
//        converge, marks every point NotDistinctive (0 inliers, the reference is rejected).

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

#include "lookup/refine/options.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

const char* toString(CorrespondenceMethod m);
/// "sad", "orb" or "ecc"; false for anything else.
bool parseCorrespondenceMethod(const std::string& name, CorrespondenceMethod& out);

/// What a baseline matcher found for one reference.
struct CorrespondenceResult {
    bool ok = false;     ///< correspondences were produced (they may still be outliers)
    std::string reason;  ///< why not ok (no features, ECC did not converge, ...)
    std::vector<PointMatch> matches;

    int reference_features = 0;  ///< ORB keypoints in the (warped) reference
    int query_features = 0;      ///< ORB keypoints in the query
    double correlation = 0.0;    ///< ECC: final enhanced correlation coefficient, in [-1, 1]
    cv::Matx33d warp = cv::Matx33d::eye();  ///< ECC: reference pixel -> query pixel
};

/// ORB + ratio test. `reference` and `query` are CV_8UC1. `reference_to_query` (optional)
/// is the predicted homography; features are then detected on the warped reference (masked
/// to where it has pixels) and mapped back through its inverse. PointMatch::quality is
/// 1 - best/second-best Hamming distance; sad_per_px is the best distance (bits).
CorrespondenceResult matchOrb(const cv::Mat& reference, const cv::Mat& query,
                              const std::optional<cv::Matx33d>& reference_to_query,
                              const CorrespondenceOptions& options);

/// ECC homography from `reference` (template) to `query` (CV_8UC1), started from
/// `reference_to_query` or the identity, run from pyramid level ecc_pyramid_levels down to
/// full resolution; the converged warp W gives one correspondence per point: p -> W(p).
/// PointMatch::quality is the correlation coefficient. Points mapped outside the query are
/// OutOfImage. Never throws on image content: OpenCV's exceptions become the reason.
CorrespondenceResult matchEcc(const cv::Mat& reference, const cv::Mat& query,
                              const std::vector<cv::Point2f>& points,
                              const std::optional<cv::Matx33d>& reference_to_query,
                              const CorrespondenceOptions& options);

}  // namespace lookup::refine

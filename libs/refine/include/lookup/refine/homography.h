#pragma once
// Homography Estimator (paper Sec. III-C): a 3x3 homography from reference to query pixels,
// with RANSAC when there are more than ransac_min_points matches (plain least squares
// otherwise), and its decomposition into rotation, translation / plane distance and plane
// normal, keeping the physically sensible solution: the smallest pitch and roll (tilt).
//
// Determinism: cv::findHomography's RANSAC seeds its own cv::RNG with a fixed constant on
// every call (OpenCV 4.x, modules/calib3d/src/ptsetreg.cpp), so equal input gives equal output;
// a test checks it.

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "lookup/refine/options.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

/// One solution of the decomposition: X_query = R X_ref + t * d for a plane n^T X_ref = d
/// (reference camera frame).
struct PlaneMotion {
    cv::Matx33d rotation;          ///< reference camera -> query camera
    cv::Vec3d translation_over_d;  ///< t / d (unitless; d = distance of the plane)
    cv::Vec3d normal;              ///< plane normal in the reference camera frame
    double tilt_deg = 0.0;         ///< angle between the two optical axes (pitch and roll)
    double yaw_deg = 0.0;          ///< rotation about the optical axis
};

struct HomographyResult {
    bool ok = false;
    std::string reason;                  ///< why not ok
    cv::Matx33d H = cv::Matx33d::eye();  ///< reference pixel -> query pixel
    int used_points = 0;                 ///< matched points given to the estimator
    int inliers = 0;
    bool ransac = false;  ///< RANSAC was used (more than ransac_min_points)
    bool decomposed = false;
    PlaneMotion motion;  ///< the smallest-tilt solution (valid if decomposed)
    int solutions = 0;   ///< number of decomposition solutions
};

/// Decomposes H (pixels) given both cameras' intrinsics; returns every solution in `all` and
/// the chosen one (smallest tilt, then normal facing the camera). false if H is degenerate.
bool decomposeHomography(const cv::Matx33d& H, const cv::Matx33d& K_reference,
                         const cv::Matx33d& K_query, PlaneMotion& chosen,
                         std::vector<PlaneMotion>* all = nullptr);

/// Estimates H from the matched points of `matches` and sets their `inlier` flags
/// (unmatched points are never inliers). Decomposes when both intrinsics are given.
HomographyResult estimateHomography(std::vector<PointMatch>& matches,
                                    const HomographyOptions& options,
                                    const cv::Matx33d* K_reference = nullptr,
                                    const cv::Matx33d* K_query = nullptr);

}  // namespace lookup::refine

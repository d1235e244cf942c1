#pragma once
// Ceiling-plane geometry (DESIGN.md, Geometry): the ceiling is the plane z = h of the map
// frame; cameras follow MRPT (+Z optical axis, +X image right, +Y image down), pinhole with
// intrinsics fx, fy, cx, cy on rectified pixels.

#include <mrpt/img/TCamera.h>
#include <mrpt/poses/CPose3D.h>

#include <opencv2/core.hpp>
#include <optional>
#include <string>
#include <vector>

namespace lookup::refine {

struct Pinhole {
    double fx = 0, fy = 0, cx = 0, cy = 0;
    cv::Matx33d K() const { return {fx, 0, cx, 0, fy, cy, 0, 0, 1}; }
};

/// Reads the pinhole part of `camera`; false (with `why`) when a value is not finite or a focal
/// length is not positive.
bool pinholeFrom(const mrpt::img::TCamera& camera, Pinhole& out, std::string* why);

/// True when `camera` has non-zero lens distortion coefficients.
bool hasDistortion(const mrpt::img::TCamera& camera);

/// Pixels `px` of `camera` (lens distortion included) in its ideal pinhole twin (the same
/// intrinsics, no distortion); unchanged when `camera` has none.
std::vector<cv::Point2d> undistortPixels(const std::vector<cv::Point2f>& px,
                                         const mrpt::img::TCamera& camera);
/// The inverse: pixels `px` of `camera`'s ideal pinhole twin where `camera` records them.
std::vector<cv::Point2d> distortPixels(const std::vector<cv::Point2f>& px,
                                       const mrpt::img::TCamera& camera);

/// Point of the plane z = h seen at pixel `px` by a camera at `camera_in_map`; empty when the
/// ray does not meet the plane in front of the camera.
std::optional<cv::Point3d> backProjectToCeiling(const Pinhole& camera,
                                                const mrpt::poses::CPose3D& camera_in_map,
                                                const cv::Point2d& px, double h);

/// Pixel of map point `p` in a camera at `camera_in_map`; empty when behind the camera.
std::optional<cv::Point2d> projectToImage(const Pinhole& camera,
                                          const mrpt::poses::CPose3D& camera_in_map,
                                          const cv::Point3d& p);

/// `out` = H * p (homogeneous); false when the point maps to infinity or to a non-finite pixel.
bool applyHomography(const cv::Matx33d& H, const cv::Point2d& p, cv::Point2d& out);

/// Homography from pixels of camera A to pixels of camera B induced by the plane z = h.
cv::Matx33d ceilingHomography(const Pinhole& a, const mrpt::poses::CPose3D& a_in_map,
                              const Pinhole& b, const mrpt::poses::CPose3D& b_in_map, double h);

}  // namespace lookup::refine

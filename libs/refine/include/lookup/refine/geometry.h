#pragma once
// Ceiling-plane geometry (DESIGN.md, Geometry): the ceiling is the plane z = h of the floor's
// frame, which is the map's on level ground and the references' own on a grade (floorFrame);
// cameras follow MRPT (+Z optical axis, +X image right, +Y image down), pinhole with
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

/// The floor under vehicles with 3-D poses as a frame: origin at their mean position, z along
/// the mean of their up axes, x along the first one's heading. On a grade the ceiling runs
/// parallel to the floor, so the plane z = h above it holds in this frame, not in the map's.
/// Planar poses (z 0, level: laser-derived, coarse, tracked) carry no height and are left out;
/// none when every pose is planar (the map's frame is then the floor's).
std::optional<mrpt::poses::CPose3D> floorFrame(const std::vector<mrpt::poses::CPose3D>& vehicles);

/// The height of the floor plane of `floor` (a floorFrame) at the map position x, y.
double floorHeightAt(const mrpt::poses::CPose3D& floor, double x, double y);

/// `pose` in the floor's frame; a planar pose is first put on the floor plane under its x, y
/// (z 0 and level in that frame).
mrpt::poses::CPose3D inFloorFrame(const mrpt::poses::CPose3D& pose,
                                  const mrpt::poses::CPose3D& floor);

/// Homography from pixels of camera A to pixels of camera B induced by the plane z = h.
cv::Matx33d ceilingHomography(const Pinhole& a, const mrpt::poses::CPose3D& a_in_map,
                              const Pinhole& b, const mrpt::poses::CPose3D& b_in_map, double h);

}  // namespace lookup::refine

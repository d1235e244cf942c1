#pragma once
// Lens rectification before matching: every ceiling image, query or reference, is resampled
// into one ideal pinhole camera (no distortion) chosen per database, so the SAD matcher compares
// patches of one projection and the estimator's pinhole geometry (geometry.h) holds for every
// pixel. Cameras are MRPT TCamera calibrations: DistortionModel::none, plumb_bob (OpenCV's
// radial-tangential model, dist = k1 k2 p1 p2 k3 [k4 k5 k6]) or kannala_brandt (OpenCV's fisheye
// model, TCamera::k1() .. k4()). The maps (cv::initUndistortRectifyMap and its fisheye twin) are
// built once per source camera and cached; rectifying is then one cv::remap per image. A source
// much finer than the target (a camera of more pixels than the database stores) is first
// averaged down to about the target's scale (cv::INTER_AREA), so its fine texture is not aliased.
//
// Pixels of the ideal camera that the source does not see (a query camera with a longer focal
// length, a pincushion lens) are 0.

#include <mrpt/img/TCamera.h>
#include <mrpt/obs/CObservationImage.h>

#include <memory>
#include <opencv2/core.hpp>
#include <string>

#include "lookup/common/camera_params.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

/// The ideal pinhole twin of `camera`: the same size, focal lengths and principal point, no
/// distortion (DistortionModel::none, all coefficients 0).
mrpt::img::TCamera idealPinhole(const mrpt::img::TCamera& camera);

class Rectifier {
  public:
    /// Images are mapped into idealPinhole(`target`). Throws std::invalid_argument when
    /// common::cameraProblem(target) is not empty or the size is zero.
    explicit Rectifier(const mrpt::img::TCamera& target);

    /// The ideal camera every rectified image is in.
    const mrpt::img::TCamera& target() const { return target_; }

    /// True when an image of `camera` already is one of target() (same size, intrinsics within
    /// 0.001 px, no non-zero distortion coefficient): rectify() then returns it unchanged, without
    /// a copy.
    bool isIdentity(const mrpt::img::TCamera& camera) const;

    /// `image` (any depth, 1 or 3 channels) taken with `camera`, resampled bilinearly into
    /// target(). Throws std::invalid_argument with common::cameraProblem()'s reason when `camera`
    /// does not describe `image`.
    cv::Mat rectify(const cv::Mat& image, const mrpt::img::TCamera& camera) const;

    /// A copy of `obs` with its image (loaded if external, then kept in memory) rectified and
    /// cameraParams = target(); time stamp, label and cameraPose unchanged. Throws as above, and
    /// std::runtime_error naming the label when the image cannot be loaded.
    mrpt::obs::CObservationImage rectify(const mrpt::obs::CObservationImage& obs) const;

    /// Rectifies `reference.image` and its heat map (same maps) from `reference.camera`, and sets
    /// `reference.camera` = target(). Call before ReferenceImage::prepare(): cached pyramids and
    /// sample points are dropped. A reference whose camera cannot describe its image is left
    /// as it is (the Refiner refuses it, naming the reason).
    void rectify(ReferenceImage& reference) const;

    /// Source cameras whose maps are cached (shared by copies of this Rectifier).
    std::size_t cachedCameras() const;

  private:
    struct Maps;
    struct Cache;
    /// The cached maps from `camera` (built on first use).
    const Maps& mapsFor(const mrpt::img::TCamera& camera) const;
    mrpt::img::TCamera target_;
    std::shared_ptr<Cache> cache_;
};

}  // namespace lookup::refine

#pragma once
// Test and benchmark fixture: a textured ceiling plane rendered through pinhole cameras at
// known poses with the exact plane-induced homography (cv::warpPerspective), so every image
// pair has a known motion. Deterministic for a given seed.

#include <mrpt/img/TCamera.h>
#include <mrpt/poses/CPose3D.h>

#include <cstdint>
#include <opencv2/core.hpp>

#include "lookup/refine/types.h"

namespace lookup::refine::synthetic {

/// Multi-scale noise: octaves of uniform noise upsampled (bicubic) and summed, 8-bit.
cv::Mat makeNoiseTexture(cv::Size size, std::uint64_t seed, int octaves = 6);

/// Pinhole camera with square pixels and the principal point at the centre.
mrpt::img::TCamera makeCamera(int width, int height, double focal_px);

/// A ceiling camera 1.5 m above the vehicle base looking up (+Z camera = +z vehicle).
mrpt::poses::CPose3D ceilingCameraOnVehicle();

struct SyntheticCeiling {
    cv::Mat texture;               ///< CV_8UC1
    double height_m = 5.0;         ///< plane z = height_m
    double x0_m = 0, y0_m = 0;     ///< map position of texture pixel (0, 0)
    double metres_per_px = 0.008;  ///< texture resolution

    /// A square ceiling of side `size_m` centred on (0, 0).
    static SyntheticCeiling make(double height_m, double size_m, double metres_per_px,
                                 std::uint64_t seed);

    /// What `camera` at `camera_in_map` sees (bilinear, 8-bit; black outside the texture).
    cv::Mat render(const mrpt::img::TCamera& camera,
                   const mrpt::poses::CPose3D& camera_in_map) const;

    /// What a rolling-shutter `camera` on a vehicle at `vehicle_in_map` (at the stamp) sees:
    /// each row from the camera at that row's time (`timing`; rows 0: the camera's).
    cv::Mat renderRollingShutter(const mrpt::img::TCamera& camera,
                                 const mrpt::poses::CPose3D& camera_on_vehicle,
                                 const mrpt::poses::CPose3D& vehicle_in_map,
                                 RowTiming timing) const;

    /// A reference rendered at `vehicle_in_map` with the given camera.
    ReferenceImage reference(std::int64_t id, const mrpt::img::TCamera& camera,
                             const mrpt::poses::CPose3D& camera_on_vehicle,
                             const mrpt::poses::CPose3D& vehicle_in_map) const;
};

}  // namespace lookup::refine::synthetic

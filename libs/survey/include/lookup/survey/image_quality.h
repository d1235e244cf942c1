#pragma once
// Ceiling image quality used to skip bad keyframes: blur (variance of the Laplacian, Pech-Pacheco
// et al. 2000) and exposure (mean grey level, share of clipped pixels).

#include <mrpt/img/TCamera.h>
#include <mrpt/obs/CObservationImage.h>

#include <opencv2/core/mat.hpp>
#include <string>
#include <vector>

namespace lookup::survey {

struct ImageQuality {
    double sharpness = 0;         ///< variance of the Laplacian [grey^2]; low = blurred
    double mean_intensity = 0;    ///< mean grey level [0..255]
    double clipped_fraction = 0;  ///< share of pixels <= 2 or >= 253 [0..1]
    bool usable = true;           ///< false: unreadable, empty or of the wrong size
};

/// Measures a grey or colour 8-bit image (colour is converted to grey first), averaged down to
/// `max_width_px` first when wider (0: as it is), as the database stores ceiling images.
ImageQuality measureImageQuality(const cv::Mat& image, int max_width_px = 0);

/// Median of each measure over `images` (all zero when empty).
ImageQuality medianQuality(const std::vector<ImageQuality>& images);

/// Quality of a candidate ceiling image (its pixels loaded from the rawlog or its external
/// file); not usable, with `problem` naming the image and the reason, when it is unreadable,
/// not 8-bit, or not the size its intrinsics (and `expected`, when given) say. Measured at
/// `max_width_px` as measureImageQuality.
ImageQuality ceilingQuality(const mrpt::obs::CObservationImage& obs,
                            const mrpt::img::TCamera* expected, int max_width_px,
                            std::string& problem);

}  // namespace lookup::survey

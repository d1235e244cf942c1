#pragma once
// What stays on a ceiling camera's lens: dust, dried mud, spray. Out of focus, each speck is a
// soft dark blotch that stays where it is in the image while the ceiling moves past, and the
// matcher locks onto it: frame to frame it says the vehicle stood still, against a reference it
// votes for no place. Averaged over frames taken a travel apart, the ceiling's own texture
// blurs out and what is left is the lamp's light times the lens's transmission. The light is
// smooth, and the lens only takes light away, so the light is the mean's upper envelope (a grey
// closing wider than a blotch, smoothed) and the transmission is the mean over it. Where part
// of the lens lets clearly less through, each image is divided by the transmission (a
// flat-field correction): the matcher sees the ceiling behind a blotch, at its noise.
//
// A clean lens leaves images untouched, bit for bit. Drops (which defocus rather than darken)
// are not corrected.

#include <mrpt/img/TCamera.h>
#include <mrpt/poses/CPose3D.h>

#include <opencv2/core.hpp>

#include <cstddef>
#include <string>

#include "lookup/common/config.h"
#include "lookup/common/options_table.h"

namespace lookup::refine {

struct LensShadingOptions {
    bool enabled = true;
    /// Images averaged (the mean's horizon), and added before the lens is judged.
    int frames = 40;
    /// Travel between the images added [m]: the ceiling has moved on by more than its texture's
    /// size (the caller measures it).
    double min_travel_m = 0.2;
    /// A lens is dirty where at least `min_dirty_share` of the image lets less than
    /// `dirty_transmission` of the light through.
    double dirty_transmission = 0.85;
    double min_dirty_share = 0.005;
    /// Darkening under this share is left alone (what is left of the ceiling in the mean).
    double tolerance = 0.05;
    /// At most this gain: a nearly opaque speck is not stretched into noise.
    double max_gain = 4.0;

    /// The lens_* keys (lens_correction, lens_frames, ...) of the section that holds them.
    void declareKeys(common::OptionsTable& t);
    /// What the ranges of declareKeys do not say: the tolerance under what counts as dirt.
    void check(common::OptionsCheck& c) const;
};

/// The way the ceiling moves through a camera's image as the vehicle drives: the vehicle's x
/// axis in the camera's frame, projected.
cv::Point2d driveInImage(const mrpt::poses::CPose3D& camera_on_vehicle,
                         const mrpt::img::TCamera& camera);

/// The warning for a dirty lens: how much of the image lies behind dirt and how dark, that it
/// was divided out of `corrected` ("each image", "the references"), and to clean it.
std::string dirtyLensWarning(double dirty_share, double least_transmission,
                             const LensShadingOptions& options, const std::string& corrected);

class LensShading {
  public:
    explicit LensShading(LensShadingOptions options = {}) : options_(options) {}

    /// One image (grey or BGR; others are left out) taken `min_travel_m` on from the last added;
    /// `drive_direction`: the way the ceiling moves through the image as the vehicle drives
    /// (any length, either sign). Another image size or direction starts the mean over.
    void add(const cv::Mat& image, cv::Point2d drive_direction);
    /// `image` divided by the lens's transmission where the lens is dirty; else `image` itself.
    cv::Mat correct(const cv::Mat& image) const;

    bool dirty() const { return dirty_; }
    std::size_t imagesAdded() const { return added_; }
    /// The share of the image behind dirt (transmission under dirty_transmission).
    double dirtyShare() const { return dirty_share_; }
    /// The least transmission found (1 for a lens not judged yet).
    double leastTransmission() const { return least_; }
    const LensShadingOptions& options() const { return options_; }

  private:
    void judge();
    /// The light (log) fitted down each column of `log_mean` over its pixels `inside`.
    cv::Mat lightAlongColumns(const cv::Mat& log_mean, const cv::Mat& inside) const;
    /// Directions closer than this (|cos|) are one mount.
    static constexpr double kSameDirection = 0.999;

    LensShadingOptions options_;
    cv::Mat mean_;  ///< the images' running mean, CV_32F, about 80 pixels wide
    cv::Mat gain_;  ///< full resolution CV_32F, once dirty
    cv::Size size_;
    cv::Point2d direction_;  ///< unit, in the image
    std::size_t added_ = 0;
    bool dirty_ = false;
    double dirty_share_ = 0.0;
    double least_ = 1.0;
};

}  // namespace lookup::refine

#pragma once
// Data handed between the refinement stages: image pyramids, references, the coarse hint and
// per-point matches.
//
// Images are cv::Mat (8-bit grey) rather than mrpt::img::CImage in the reference set: the
// database loads a reference once and the matcher then reads raw rows many times per second,
// so a plain, always-loaded, contiguous buffer avoids CImage's lazy loading of external files
// (not thread-safe) and its per-access checks. CImage wraps the same cv::Mat, so conversion is
// free (ReferenceImage::fromObservation). The query stays an mrpt::obs::CObservationImage.

#include <mrpt/img/TCamera.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/poses/CPose3D.h>

#include <cstdint>
#include <memory>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "lookup/refine/options.h"
#include "lookup/refine/rolling_shutter.h"

namespace lookup::refine {

/// Grey image pyramid for the coarse-to-fine matcher. levels[0] is full resolution, each
/// further level is cv::pyrDown of the previous. Every level is CV_8UC1 and has at least
/// 32 readable bytes after the end of each row (SIMD loads may overrun a patch row).
struct ImagePyramid {
    std::vector<cv::Mat> levels;
    bool normalized = false;           ///< brightness normalised (see build)
    double max_contrast_gain = 0;      ///< the normalisation's gain cap (see build)
    double illumination_sigma_px = 0;  ///< illumination removed at this scale (see build)

    /// `grey` must be CV_8UC1 (CV_8UC3 is converted); `extra_levels` coarser levels are added.
    /// `illumination_sigma_px` > 0: a Gaussian blur of that sigma (the illumination) is
    /// subtracted first, keeping the texture. `normalize`: linear stretch of the whole image to
    /// mean 128, standard deviation 48 (gain capped at `max_contrast_gain`) so SAD ignores global
    /// gain and offset changes (exposure).
    static ImagePyramid build(const cv::Mat& grey, int extra_levels, bool normalize = false,
                              double illumination_sigma_px = 0,
                              double max_contrast_gain = MatcherOptions().max_contrast_gain);
    /// With the preprocessing `matcher` asks for (normalize_brightness, max_contrast_gain,
    /// illumination_sigma_px).
    static ImagePyramid build(const cv::Mat& grey, int extra_levels, const MatcherOptions& matcher);
    /// Whether this pyramid was preprocessed as `matcher` asks.
    bool preprocessedFor(const MatcherOptions& matcher) const {
        return normalized == matcher.normalize_brightness &&
               (!normalized || max_contrast_gain == matcher.max_contrast_gain) &&
               illumination_sigma_px == matcher.illumination_sigma_px;
    }
    bool empty() const { return levels.empty() || levels[0].empty(); }
};

/// `grey` (CV_8UC1, or CV_32FC1) less a Gaussian blur of sigma `sigma` (its illumination), as
/// CV_16S (CV_32F for a float image); `grey` itself when `sigma` <= 0.
cv::Mat removeIllumination(const cv::Mat& grey, double sigma);

/// `texture` stretched linearly to mean 128 and standard deviation 48, as CV_8U. The gain is
/// capped: a flat, noisy image must not be stretched into fake texture.
cv::Mat stretchContrast(const cv::Mat& texture, double max_gain = 4.0);

/// One surveyed reference image as the refiner sees it: image, camera and poses (paper
/// Sec. III: "database of images with known camera poses"). The localiser makes it from a
/// database record, lookup::database::Reference.
struct ReferenceImage {
    std::int64_t id = -1;
    mrpt::Clock::time_point timestamp{};
    cv::Mat image;                           ///< CV_8UC1 ceiling image
    mrpt::img::TCamera camera;               ///< intrinsics of `image` (rectified pinhole)
    mrpt::poses::CPose3D vehicle_in_map;     ///< surveyed vehicle (base) pose
    mrpt::poses::CPose3D camera_on_vehicle;  ///< as CObservationImage::cameraPose
    cv::Mat heat_map;  ///< optional CV_32FC1 sample-quality map, same size as `image`, >= 0
    /// Its rolling shutter and the survey vehicle's velocity at its stamp (rows 0: the image's
    /// height); readout 0 = a global shutter.
    RowTiming timing;

    /// Optional cache built by prepare(); built on the fly per query when absent.
    std::shared_ptr<const ImagePyramid> pyramid;

    /// Builds the matcher's pyramid once so queries do not rebuild it (the Refiner rebuilds it
    /// per query if levels or preprocessing differ from its MatcherOptions).
    void prepare(const MatcherOptions& matcher);

    /// Optional cache of the sample points, built by prepareSamplePoints(): heat-map selection
    /// (damped maxima) costs about 0.4 ms per reference and gives the same points for every
    /// query. The Refiner uses it only when built with the sampler options it runs with.
    struct SamplePoints {
        SamplerOptions options;
        std::vector<cv::Point2f> points;
    };
    std::shared_ptr<const SamplePoints> sample_points;
    /// Leaves `sample_points` empty when the heat map is not a finite CV_32FC1 map of the
    /// image's size (the Refiner then refuses the reference, saying why).
    void prepareSamplePoints(const SamplerOptions& options);

    mrpt::poses::CPose3D cameraInMap() const { return vehicle_in_map + camera_on_vehicle; }

    /// From a ceiling-camera observation (image converted to grey, loaded if external).
    static ReferenceImage fromObservation(std::int64_t id, const mrpt::obs::CObservationImage& obs,
                                          const mrpt::poses::CPose3D& vehicle_in_map);
};

/// What the coarse stage tells the refiner (paper Sec. III-E: the matched reference time
/// stamp; here reference ids and/or a pose).
/// Outcome of one refinement (RefineResult::status).
enum class RefineStatus {
    Accepted,         ///< refined pose
    InvalidQuery,     ///< query image missing/unreadable, or its intrinsics invalid
    NoReferences,     ///< no usable reference (none given, ids not found, bad intrinsics)
    TooFewMatches,    ///< not enough matched / inlier points to estimate a pose
    LowInlierShare,   ///< inliers / sample points < N_th
    OffsetTooLarge,   ///< |refined - coarse (or reference)| > d_th
    EstimationFailed  ///< solver or covariance failed
};
const char* toString(RefineStatus s);

struct CoarseHint {
    std::vector<std::int64_t> reference_ids;  ///< references to use; empty = all given
    /// Coarse query vehicle pose in the map: x, y and yaw are used (the query's height and tilt
    /// prior come from its references, which stood on the same floor).
    std::optional<mrpt::poses::CPose3D> vehicle_pose;
    std::optional<double> ceiling_height_m;  ///< overrides EstimatorOptions::ceiling_height_m
    /// A quick look before the full match (acquisition tries dozens of places, nearly all
    /// wrong): with the SAD matcher, `probe_points` sample points spread over each reference
    /// are matched first; when fewer than `probe_min_matched` of them match, the refinement
    /// stops there (TooFewMatches). 0 = no probe.
    int probe_points = 0;
    int probe_min_matched = 0;
    /// The query vehicle's velocity at the frame (odometry): with
    /// RefinerOptions::rolling_shutter, each query point's row time moves it.
    std::optional<VehicleMotion> vehicle_motion;
    /// The pose is the track's prediction, not a coarse match: AcceptanceOptions'
    /// min_inlier_share_tracked applies.
    bool tracked = false;
};

/// Why the matcher kept or dropped a point.
enum class MatchStatus {
    Matched,
    LowTexture,      ///< reference patch too flat to match
    NotDistinctive,  ///< second-best SAD too close to the best (repetitive texture)
    BorderPeak,      ///< best SAD on the border of the search window (true match may be outside)
    OutOfImage       ///< patch or search window outside the image
};
const char* toString(MatchStatus s);

/// One sample point and its correspondence (paper Sec. III-A "optical flow" vector).
struct PointMatch {
    cv::Point2f reference_px;  ///< sample point in the reference image [px]
    cv::Point2f query_px;      ///< sub-pixel match in the query image [px] (valid if Matched)
    float quality = 0.f;       ///< 1 - best/second-best SAD at the coarsest level, in [0, 1]
    float sad_per_px = 0.f;    ///< best SAD / patch area at full resolution [grey levels]
    MatchStatus status = MatchStatus::OutOfImage;
    bool inlier = false;  ///< set by the homography RANSAC

    bool matched() const { return status == MatchStatus::Matched; }
};

}  // namespace lookup::refine

#pragma once
// Options of the refinement stages (paper Sec. III, Table I). Each struct is an MRPT
// CLoadableOptions read strictly (unknown keys and malformed values are refused, naming the
// file, section and key) and validated by check(), which names every failing field.
// Defaults are the paper's Mine A values (share/lookup/refiner.ini); mineB() its Mine B sizes.
// What lookup-localize runs with, measured on the mines, is share/lookup/localize.ini.

#include <mrpt/config/CLoadableOptions.h>

#include <algorithm>
#include <string>
#include <vector>

#include "lookup/common/options_table.h"
#include "lookup/common/stamp_row.h"

namespace lookup::refine {

/// Where the sample points of a reference come from (paper Sec. III-B).
enum class SamplingMode {
    Grid,  ///< regular grid of grid_points points
    /// Greedy selection on the reference's quality heat map (FCN); the localiser requires the
    /// database to have them. A reference without one (added during a run by the online
    /// refresh) gets the grid.
    HeatMap,
    Auto  ///< heat map when the reference has one, grid otherwise
};

/// Sample Point Selector (paper Sec. III-B).
struct SamplerOptions : public common::TableOptions<SamplerOptions> {
    SamplingMode mode = SamplingMode::Auto;
    int grid_points = 24;        ///< points on the regular grid (paper: 24)
    int heat_map_points = 12;    ///< points taken from a heat map (paper: 12, FCN)
    double damping_ratio = 0.5;  ///< rho: factor applied around a chosen point, in (0, 1)
    int damping_side_px = 10;    ///< l_n: side of the damped neighbourhood [px] (Mine B: 20)
    int border_margin_px = 20;   ///< points stay this far from the image border [px];
                                 ///< at least l_patch / 2 (checked by RefinerOptions)
    /// Heat-map points keep the larger of this and border_margin_px from the border [px].
    /// Grid points sit half a cell inside border_margin_px; a heat-map point can sit on it,
    /// and there the motion-compensated patch leaves the reference at the least offset.
    int heat_map_margin_px = 0;

    /// The border margin heat-map points keep.
    int heatMapMargin() const { return std::max(border_margin_px, heat_map_margin_px); }

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    /// Throws common::ConfigError naming every invalid field.
    void check() const;
};

/// Sub-pixel interpolation of the SAD minimum.
enum class SubpixelMethod {
    None,        ///< integer peak
    Parabola,    ///< 1-D parabola through the minimum and its two neighbours, per axis
    Equiangular  ///< V-shaped (equiangular line) fit, less biased for SAD (Shimizu 2005)
};

/// Pixel Correspondence Matcher (paper Sec. III-A).
struct MatcherOptions : public common::TableOptions<MatcherOptions> {
    int search_range_px = 40;  ///< L_SR: side of the square query search window [px]
                               ///< (offsets -L_SR/2 .. +L_SR/2 inclusive); Mine B: 70
    int patch_px = 40;         ///< l_patch: side of the square reference patch [px]; Mine B: 60
    int pyramid_levels = 2;    ///< coarse-to-fine: exhaustive search at 1/2^levels resolution,
                               ///< then +-refine_radius_px per finer level; 0 = exhaustive
    int min_top_patch_px = 8;  ///< levels are dropped while the coarsest patch would be smaller
    int refine_radius_px = 2;  ///< half side of the local search at each finer level [px]
    double min_texture = 2.0;  ///< minimum mean absolute deviation of the reference patch
                               ///< [grey levels]; flatter patches are rejected
    double min_distinctiveness = 0.02;  ///< minimum 1 - best/second-best SAD (second best
                                        ///< outside exclusion_radius_px, coarsest level)
    int exclusion_radius_px = 2;        ///< exclusion radius around the best, at the coarsest level
    SubpixelMethod subpixel = SubpixelMethod::Equiangular;
    bool use_simd = true;              ///< false forces the scalar SAD (verification)
    bool normalize_brightness = true;  ///< per-image gain/offset normalisation before SAD
    /// The normalisation's gain at most: a flat, noisy image is not stretched into texture.
    double max_contrast_gain = 4.0;
    /// Gaussian sigma [px] of the illumination subtracted from both images before SAD (a
    /// high-pass; 0 = off, the paper's raw SAD). The vehicle carries its lights, so a query and
    /// a reference taken a metre apart see the same ceiling lit differently; on smooth
    /// shotcrete that gradient outweighs the texture and drags the SAD minimum to the border.
    double illumination_sigma_px = 8.0;
    /// With a coarse pose: warp the reference by the predicted plane-induced homography into
    /// the query frame before SAD, so rotated or tilted views compare aligned patches (an
    /// extension of the paper, whose SAD assumes pure image translation); false = the paper's
    /// plain search centred on the predicted offset.
    bool compensate_motion = true;

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

/// What relates a reference to the query (the paper's SAD, or a baseline in its place).
enum class CorrespondenceMethod {
    Sad,  ///< the paper's SAD matcher at the sample points (MatcherOptions)
    Orb,  ///< cv::ORB features + ratio test (correspondence_methods.h)
    Ecc   ///< cv::findTransformECC homography sampled at the sample points
};

/// Correspondence method and the baselines' parameters, section `<prefix>.correspondence`
/// (load, save and check in correspondence_methods.cpp).
struct CorrespondenceOptions : public common::TableOptions<CorrespondenceOptions> {
    CorrespondenceMethod method = CorrespondenceMethod::Sad;  ///< sad | orb | ecc (paper: sad)
    int orb_features = 500;                                   ///< cv::ORB nfeatures per image
    double orb_ratio = 0.8;       ///< Lowe ratio: best / second-best Hamming distance below it
    int orb_min_matches = 20;     ///< fewer ratio-test matches: none at all (a handful of chance
                                  ///< matches would otherwise pass as a least-squares fit)
    int ecc_pyramid_levels = 2;   ///< ECC runs at 1/2^levels resolution first, then finer
    int ecc_max_iterations = 50;  ///< ECC iterations per pyramid level
    double ecc_epsilon = 1e-4;    ///< ECC stop: correlation increment below this
    double ecc_min_correlation = 0.6;  ///< accepted warp: correlation coefficient >= this
    int ecc_gauss_filter_px = 5;       ///< ECC Gaussian pre-filter side [px] (odd; 1 = none)

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

/// Homography Estimator (paper Sec. III-C).
struct HomographyOptions : public common::TableOptions<HomographyOptions> {
    int ransac_min_points = 10;        ///< RANSAC only when more points than this (paper: 10)
    double ransac_threshold_px = 2.0;  ///< inlier reprojection threshold [px]
    int ransac_max_iterations = 2000;
    double ransac_confidence = 0.995;

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

/// Joint pose-and-scale estimate (paper Sec. III-D, done jointly with Ceres here).
struct EstimatorOptions : public common::TableOptions<EstimatorOptions> {
    double ceiling_height_m = 5.0;        ///< h prior: ceiling plane height above the map z = 0 [m]
                                          ///< (datasets: dataset.ini ceiling_height_m)
    double ceiling_height_sigma_m = 0.5;  ///< h prior standard deviation [m]
    double tilt_sigma_deg = 2.0;          ///< prior sigma of the query's roll and pitch about the
                                          ///< coarse (or zero) attitude [deg]
    double pixel_sigma_px = 0.5;          ///< matched-pixel noise used to scale residuals [px]
    double huber_loss_px = 2.0;           ///< Huber loss threshold on pixel residuals [px]
    int max_iterations = 50;              ///< Ceres iterations
    int min_inliers = 6;                  ///< fewer inliers over all references: no estimate

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

/// Acceptance filters (paper Sec. III-E).
struct AcceptanceOptions : public common::TableOptions<AcceptanceOptions> {
    double min_inlier_share = 0.6;  ///< N_th: inliers / testable sample points (window in
                                    ///< the query image), over all references
    /// N_th for a frame refined around the track's prediction (a fix moments ago and the
    /// odometry since), never above min_inlier_share (1: the same): the wrong place N_th guards
    /// against comes from coarse matches and acquisition, which keep min_inlier_share; a
    /// tracked frame over a changed ceiling has fewer testable points that still match.
    double min_inlier_share_tracked = 1.0;
    double max_offset_m = 2.0;         ///< d_th: max |refined - coarse (or reference)| in x, y [m]
    double fallback_sigma_xy_m = 2.0;  ///< sigma of a failed result's coarse pose [m]
    double fallback_sigma_yaw_deg = 10.0;  ///< sigma of a failed result's coarse pose [deg]
    /// Sigma of a pose dead-reckoned from the last fix: this much [m] plus `_per_m` of the
    /// odometry's distance since the fix (wheel odometry drifts by a few percent).
    double dead_reckoning_sigma_xy_m = 0.05;
    double dead_reckoning_sigma_xy_per_m = 0.05;
    double dead_reckoning_sigma_yaw_deg = 1.0;        ///< ... in heading [deg]
    double dead_reckoning_sigma_yaw_deg_per_m = 2.0;  ///< [deg per m]
    /// Where odometry readings stop (a dropout, a reading late against the image) the pose is
    /// extrapolated at the last odometry velocity; a vehicle braking or speeding up meanwhile
    /// leaves it off by half its acceleration times the time squared [m/s^2], [deg/s^2].
    double extrapolation_accel_mps2 = 2.5;
    double extrapolation_yaw_accel_deg_s2 = 30.0;
    /// Without any odometry velocity the vehicle may have driven at up to this speed since the
    /// last fix [m/s], [deg/s].
    double unknown_motion_speed_mps = 10.0;
    double unknown_motion_yaw_rate_deg_s = 30.0;

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

/// The row the query camera's stamp (after the localiser's [time_offsets]) refers to.
using StampRow = common::StampRow;

/// The query ceiling camera's rolling shutter (rolling_shutter.h), section
/// `<prefix>.rolling_shutter`. With a readout and the vehicle's velocity in the hint, every
/// query point is seen from the vehicle moved to its row's exposure.
struct RollingShutterOptions : public common::TableOptions<RollingShutterOptions> {
    double readout_ms = 0.0;  ///< first row to last row [ms]; 0 = global shutter
    StampRow stamp_row = StampRow::First;

    /// Row exposed at the stamp in an image of `rows` rows.
    double stampRow(int rows) const {
        return stamp_row == StampRow::Middle ? 0.5 * (rows - 1) : 0.0;
    }
    void declareKeys(common::OptionsTable& t);
    /// readout_ms in [0, 1000); the localiser also refuses one not shorter than the frame
    /// period it sees.
    void check() const;
};

/// Everything the Refiner uses. Sections are `<prefix>.sampler`, `<prefix>.matcher`,
/// `<prefix>.homography`, `<prefix>.estimator`, `<prefix>.acceptance`,
/// `<prefix>.correspondence`, `<prefix>.rolling_shutter`.
struct RefinerOptions : public mrpt::config::CLoadableOptions {
    SamplerOptions sampler;
    MatcherOptions matcher;
    HomographyOptions homography;
    EstimatorOptions estimator;
    AcceptanceOptions acceptance;
    CorrespondenceOptions correspondence;   ///< `<prefix>.correspondence`: sad | orb | ecc
    RollingShutterOptions rolling_shutter;  ///< `<prefix>.rolling_shutter`: the query camera

    /// `section` is the prefix (e.g. "refine" reads [refine.sampler] ...).
    void loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                            const std::string& section) override;
    void saveToConfigFile(mrpt::config::CConfigFileBase& target,
                          const std::string& section) const override;
    /// Checks every stage and the cross-stage constraints.
    void check() const;
    /// The sections loadFromConfigFile reads for `prefix` (apps refuse any other).
    static std::vector<std::string> sectionNames(const std::string& prefix);

    /// Table I, Mine B: L_SR 70, l_patch 60, l_n 20, border margin 30.
    static RefinerOptions mineB();
};

}  // namespace lookup::refine

#include "lookup/refine/options.h"

#include <cmath>

#include "lookup/common/config.h"
#include "lookup/common/options_table.h"

namespace lookup::refine {

using common::OptionsCheck;
using common::OptionsTable;

namespace {

const common::EnumNames<SamplingMode> kSamplingModes = {{"grid", SamplingMode::Grid},
                                                        {"heat_map", SamplingMode::HeatMap},
                                                        {"auto", SamplingMode::Auto}};

const common::EnumNames<SubpixelMethod> kSubpixelMethods = {
    {"none", SubpixelMethod::None},
    {"parabola", SubpixelMethod::Parabola},
    {"equiangular", SubpixelMethod::Equiangular}};

}  // namespace

// The keys of each section, in file order; checks below.
void SamplerOptions::declareKeys(OptionsTable& t) {
    t.add("mode", mode, kSamplingModes);  // point counts: a homography needs 4
    t.add("grid_points", grid_points, 4, 1024);
    t.add("heat_map_points", heat_map_points, 4, 1024);
    t.add("damping_ratio", damping_ratio);
    t.add("damping_side_px", damping_side_px, 1, 4096);
    t.add("border_margin_px", border_margin_px, 0, 4096);
    t.add("heat_map_margin_px", heat_map_margin_px, 0, 4096);
}

void MatcherOptions::declareKeys(OptionsTable& t) {
    t.add("search_range_px", search_range_px, 2, 512);
    t.add("patch_px", patch_px, 4, 256);
    t.add("pyramid_levels", pyramid_levels, 0, 4);
    t.add("min_top_patch_px", min_top_patch_px, 3, 256);
    t.add("refine_radius_px", refine_radius_px, 1, 8);
    t.add("min_texture", min_texture, 0.0);
    t.add("min_distinctiveness", min_distinctiveness);
    t.add("exclusion_radius_px", exclusion_radius_px, 1, 4096);
    t.add("subpixel", subpixel, kSubpixelMethods);
    t.add("use_simd", use_simd);
    t.add("normalize_brightness", normalize_brightness);
    t.add("max_contrast_gain", max_contrast_gain, 1.0, 256.0);
    t.add("illumination_sigma_px", illumination_sigma_px);
    t.add("compensate_motion", compensate_motion);
}

void HomographyOptions::declareKeys(OptionsTable& t) {
    t.add("ransac_min_points", ransac_min_points, 4, 1024);
    t.add("ransac_threshold_px", ransac_threshold_px, common::kPositive);
    t.add("ransac_max_iterations", ransac_max_iterations, 1, 1000000);
    t.add("ransac_confidence", ransac_confidence);
}

void EstimatorOptions::declareKeys(OptionsTable& t) {
    t.add("ceiling_height_m", ceiling_height_m);
    t.add("ceiling_height_sigma_m", ceiling_height_sigma_m, common::kPositive);
    t.add("tilt_sigma_deg", tilt_sigma_deg, common::kPositive);
    t.add("pixel_sigma_px", pixel_sigma_px, common::kPositive);
    t.add("huber_loss_px", huber_loss_px, common::kPositive);
    t.add("max_iterations", max_iterations, 1, 100000);
    t.add("min_inliers", min_inliers, 3, 1024);
}

void AcceptanceOptions::declareKeys(OptionsTable& t) {
    t.add("min_inlier_share", min_inlier_share, 0.0, 1.0);
    t.add("min_inlier_share_tracked", min_inlier_share_tracked, 0.0, 1.0);
    t.add("max_offset_m", max_offset_m, common::kPositive);
    t.add("fallback_sigma_xy_m", fallback_sigma_xy_m, common::kPositive);
    t.add("fallback_sigma_yaw_deg", fallback_sigma_yaw_deg, common::kPositive);
    t.add("dead_reckoning_sigma_xy_m", dead_reckoning_sigma_xy_m, common::kPositive);
    t.add("dead_reckoning_sigma_xy_per_m", dead_reckoning_sigma_xy_per_m, 0.0);
    t.add("dead_reckoning_sigma_yaw_deg", dead_reckoning_sigma_yaw_deg, common::kPositive);
    t.add("dead_reckoning_sigma_yaw_deg_per_m", dead_reckoning_sigma_yaw_deg_per_m, 0.0);
    t.add("extrapolation_accel_mps2", extrapolation_accel_mps2, 0.0);
    t.add("extrapolation_yaw_accel_deg_s2", extrapolation_yaw_accel_deg_s2, 0.0);
    t.add("unknown_motion_speed_mps", unknown_motion_speed_mps, common::kPositive);
    t.add("unknown_motion_yaw_rate_deg_s", unknown_motion_yaw_rate_deg_s, common::kPositive);
}

void RollingShutterOptions::declareKeys(OptionsTable& t) {
    t.add("readout_ms", readout_ms);
    t.add("stamp_row", stamp_row, common::stampRowNames());
}

// ---------------------------------------------------------------- checks
void SamplerOptions::check() const {
    OptionsCheck c("refine.sampler");
    checkRanges(c);
    c.require(damping_ratio > 0.0 && damping_ratio < 1.0, "damping_ratio", "in (0, 1)");
    c.throwIfFailed();
}

void MatcherOptions::check() const {
    OptionsCheck c("refine.matcher");
    checkRanges(c);
    c.require(min_distinctiveness >= 0.0 && min_distinctiveness < 1.0, "min_distinctiveness",
              "in [0, 1)");
    c.require(illumination_sigma_px == 0.0 ||
                  (illumination_sigma_px >= 1.0 && illumination_sigma_px <= 256.0),
              "illumination_sigma_px", "0 (off) or in [1, 256]");
    c.throwIfFailed();
}

void HomographyOptions::check() const {
    OptionsCheck c("refine.homography");
    checkRanges(c);
    c.require(ransac_confidence > 0.0 && ransac_confidence < 1.0, "ransac_confidence", "in (0, 1)");
    c.throwIfFailed();
}

void EstimatorOptions::check() const {
    OptionsCheck c("refine.estimator");
    c.require(std::isfinite(ceiling_height_m), "ceiling_height_m", "finite");
    checkRanges(c);
    c.throwIfFailed();
}

void AcceptanceOptions::check() const {
    OptionsCheck c("refine.acceptance");
    checkRanges(c);
    c.throwIfFailed();
}

void RollingShutterOptions::check() const {
    OptionsCheck c("refine.rolling_shutter");
    checkRanges(c);
    c.require(std::isfinite(readout_ms) && readout_ms >= 0.0 && readout_ms < 1000.0, "readout_ms",
              "in [0, 1000) (shorter than a frame period)");
    c.throwIfFailed();
}

// ---------------------------------------------------------------- all
void RefinerOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                        const std::string& prefix) {
    sampler.loadFromConfigFile(source, prefix + ".sampler");
    matcher.loadFromConfigFile(source, prefix + ".matcher");
    homography.loadFromConfigFile(source, prefix + ".homography");
    estimator.loadFromConfigFile(source, prefix + ".estimator");
    acceptance.loadFromConfigFile(source, prefix + ".acceptance");
    correspondence.loadFromConfigFile(source, prefix + ".correspondence");
    rolling_shutter.loadFromConfigFile(source, prefix + ".rolling_shutter");
}

void RefinerOptions::saveToConfigFile(mrpt::config::CConfigFileBase& target,
                                      const std::string& prefix) const {
    sampler.saveToConfigFile(target, prefix + ".sampler");
    matcher.saveToConfigFile(target, prefix + ".matcher");
    homography.saveToConfigFile(target, prefix + ".homography");
    estimator.saveToConfigFile(target, prefix + ".estimator");
    acceptance.saveToConfigFile(target, prefix + ".acceptance");
    correspondence.saveToConfigFile(target, prefix + ".correspondence");
    rolling_shutter.saveToConfigFile(target, prefix + ".rolling_shutter");
}

std::vector<std::string> RefinerOptions::sectionNames(const std::string& prefix) {
    std::vector<std::string> out;
    for (const char* stage : {"sampler", "matcher", "homography", "estimator", "acceptance",
                              "correspondence", "rolling_shutter"}) {
        out.push_back(prefix + "." + stage);
    }
    return out;
}

void RefinerOptions::check() const {
    sampler.check();
    matcher.check();
    homography.check();
    estimator.check();
    acceptance.check();
    correspondence.check();
    rolling_shutter.check();
    OptionsCheck c("refine");
    c.require(sampler.border_margin_px >= matcher.patch_px / 2, "sampler.border_margin_px",
              ">= matcher.patch_px / 2 (patches must lie inside the reference image)");
    c.throwIfFailed();
}

RefinerOptions RefinerOptions::mineB() {
    RefinerOptions o;
    o.matcher.search_range_px = 70;
    o.matcher.patch_px = 60;
    o.sampler.damping_side_px = 20;
    o.sampler.border_margin_px = 30;
    return o;
}

}  // namespace lookup::refine

#include "lookup/refine/options.h"

#include <mrpt/config/CConfigFile.h>

#include <cmath>

#include "lookup/common/config.h"

namespace lookup::refine {
namespace {

using common::IniSection;
using common::OptionsCheck;

std::string sourceName(const mrpt::config::CConfigFileBase& source) {
    return common::configSourceName(source);
}

const char* toString(SamplingMode m) {
    switch (m) {
        case SamplingMode::Grid:
            return "grid";
        case SamplingMode::HeatMap:
            return "heat_map";
        default:
            return "auto";
    }
}

const char* toString(SubpixelMethod m) {
    switch (m) {
        case SubpixelMethod::None:
            return "none";
        case SubpixelMethod::Parabola:
            return "parabola";
        default:
            return "equiangular";
    }
}

SamplingMode parseSamplingMode(const IniSection& s, const std::string& key, SamplingMode dflt) {
    const std::string v = s.getString(key, toString(dflt));
    if (v == "grid") return SamplingMode::Grid;
    if (v == "heat_map") return SamplingMode::HeatMap;
    if (v == "auto") return SamplingMode::Auto;
    throw common::ConfigError(s.where(key) + "'" + v + "' is not one of grid, heat_map, auto");
}

SubpixelMethod parseSubpixel(const IniSection& s, const std::string& key, SubpixelMethod dflt) {
    const std::string v = s.getString(key, toString(dflt));
    if (v == "none") return SubpixelMethod::None;
    if (v == "parabola") return SubpixelMethod::Parabola;
    if (v == "equiangular") return SubpixelMethod::Equiangular;
    throw common::ConfigError(s.where(key) + "'" + v +
                              "' is not one of none, parabola, equiangular");
}

void write(mrpt::config::CConfigFileBase& t, const std::string& s, const std::string& key,
           double v) {
    t.write(s, key, v, 0, 0, "");
}
void write(mrpt::config::CConfigFileBase& t, const std::string& s, const std::string& key, int v) {
    t.write(s, key, v, 0, 0, "");
}
void write(mrpt::config::CConfigFileBase& t, const std::string& s, const std::string& key,
           const std::string& v) {
    t.write(s, key, v, 0, 0, "");
}

}  // namespace

// ---------------------------------------------------------------- sampler
void SamplerOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                        const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys({"mode", "grid_points", "heat_map_points", "damping_ratio",
                         "damping_side_px", "border_margin_px", "heat_map_margin_px"});
    mode = parseSamplingMode(s, "mode", mode);
    grid_points = s.getInt("grid_points", grid_points, 4, 1024);
    heat_map_points = s.getInt("heat_map_points", heat_map_points, 4, 1024);
    damping_ratio = s.getDouble("damping_ratio", damping_ratio);
    damping_side_px = s.getInt("damping_side_px", damping_side_px, 1, 4096);
    border_margin_px = s.getInt("border_margin_px", border_margin_px, 0, 4096);
    heat_map_margin_px = s.getInt("heat_map_margin_px", heat_map_margin_px, 0, 4096);
}

void SamplerOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                      const std::string& s) const {
    write(t, s, "mode", std::string(toString(mode)));
    write(t, s, "grid_points", grid_points);
    write(t, s, "heat_map_points", heat_map_points);
    write(t, s, "damping_ratio", damping_ratio);
    write(t, s, "damping_side_px", damping_side_px);
    write(t, s, "border_margin_px", border_margin_px);
    write(t, s, "heat_map_margin_px", heat_map_margin_px);
}

void SamplerOptions::check() const {
    OptionsCheck c("refine.sampler");
    c.require(grid_points >= 4 && grid_points <= 1024, "grid_points",
              "in [4, 1024] (a homography needs 4 points)");
    c.require(heat_map_points >= 4 && heat_map_points <= 1024, "heat_map_points",
              "in [4, 1024] (a homography needs 4 points)");
    c.require(damping_ratio > 0.0 && damping_ratio < 1.0, "damping_ratio", "in (0, 1)");
    c.require(damping_side_px >= 1, "damping_side_px", ">= 1");
    c.require(border_margin_px >= 0, "border_margin_px", ">= 0");
    c.require(heat_map_margin_px >= 0, "heat_map_margin_px", ">= 0");
    c.throwIfFailed();
}

// ---------------------------------------------------------------- matcher
void MatcherOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                        const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys({"search_range_px", "patch_px", "pyramid_levels", "min_top_patch_px",
                         "refine_radius_px", "min_texture", "min_distinctiveness",
                         "exclusion_radius_px", "subpixel", "use_simd", "normalize_brightness",
                         "illumination_sigma_px", "compensate_motion"});
    search_range_px = s.getInt("search_range_px", search_range_px, 2, 512);
    patch_px = s.getInt("patch_px", patch_px, 4, 256);
    pyramid_levels = s.getInt("pyramid_levels", pyramid_levels, 0, 4);
    min_top_patch_px = s.getInt("min_top_patch_px", min_top_patch_px, 3, 256);
    refine_radius_px = s.getInt("refine_radius_px", refine_radius_px, 1, 8);
    min_texture = s.getDouble("min_texture", min_texture);
    min_distinctiveness = s.getDouble("min_distinctiveness", min_distinctiveness);
    exclusion_radius_px = s.getInt("exclusion_radius_px", exclusion_radius_px, 1, 4096);
    subpixel = parseSubpixel(s, "subpixel", subpixel);
    use_simd = s.getBool("use_simd", use_simd);
    normalize_brightness = s.getBool("normalize_brightness", normalize_brightness);
    illumination_sigma_px = s.getDouble("illumination_sigma_px", illumination_sigma_px);
    compensate_motion = s.getBool("compensate_motion", compensate_motion);
}

void MatcherOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                      const std::string& s) const {
    write(t, s, "search_range_px", search_range_px);
    write(t, s, "patch_px", patch_px);
    write(t, s, "pyramid_levels", pyramid_levels);
    write(t, s, "min_top_patch_px", min_top_patch_px);
    write(t, s, "refine_radius_px", refine_radius_px);
    write(t, s, "min_texture", min_texture);
    write(t, s, "min_distinctiveness", min_distinctiveness);
    write(t, s, "exclusion_radius_px", exclusion_radius_px);
    write(t, s, "subpixel", std::string(toString(subpixel)));
    write(t, s, "use_simd", std::string(use_simd ? "true" : "false"));
    write(t, s, "normalize_brightness", std::string(normalize_brightness ? "true" : "false"));
    write(t, s, "illumination_sigma_px", illumination_sigma_px);
    write(t, s, "compensate_motion", std::string(compensate_motion ? "true" : "false"));
}

void MatcherOptions::check() const {
    OptionsCheck c("refine.matcher");
    c.require(search_range_px >= 2 && search_range_px <= 512, "search_range_px", "in [2, 512]");
    c.require(patch_px >= 4 && patch_px <= 256, "patch_px", "in [4, 256]");
    c.require(pyramid_levels >= 0 && pyramid_levels <= 4, "pyramid_levels", "in [0, 4]");
    c.require(min_top_patch_px >= 3, "min_top_patch_px", ">= 3");
    c.require(refine_radius_px >= 1 && refine_radius_px <= 8, "refine_radius_px", "in [1, 8]");
    c.require(min_texture >= 0.0, "min_texture", ">= 0");
    c.require(min_distinctiveness >= 0.0 && min_distinctiveness < 1.0, "min_distinctiveness",
              "in [0, 1)");
    c.require(exclusion_radius_px >= 1, "exclusion_radius_px", ">= 1");
    c.require(illumination_sigma_px == 0.0 ||
                  (illumination_sigma_px >= 1.0 && illumination_sigma_px <= 256.0),
              "illumination_sigma_px", "0 (off) or in [1, 256]");
    c.throwIfFailed();
}

// ---------------------------------------------------------------- homography
void HomographyOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                           const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys(
        {"ransac_min_points", "ransac_threshold_px", "ransac_max_iterations", "ransac_confidence"});
    ransac_min_points = s.getInt("ransac_min_points", ransac_min_points, 4, 1024);
    ransac_threshold_px = s.getDouble("ransac_threshold_px", ransac_threshold_px);
    ransac_max_iterations = s.getInt("ransac_max_iterations", ransac_max_iterations, 1, 1000000);
    ransac_confidence = s.getDouble("ransac_confidence", ransac_confidence);
}

void HomographyOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                         const std::string& s) const {
    write(t, s, "ransac_min_points", ransac_min_points);
    write(t, s, "ransac_threshold_px", ransac_threshold_px);
    write(t, s, "ransac_max_iterations", ransac_max_iterations);
    write(t, s, "ransac_confidence", ransac_confidence);
}

void HomographyOptions::check() const {
    OptionsCheck c("refine.homography");
    c.require(ransac_min_points >= 4, "ransac_min_points", ">= 4");
    c.require(ransac_threshold_px > 0.0, "ransac_threshold_px", "> 0");
    c.require(ransac_max_iterations >= 1, "ransac_max_iterations", ">= 1");
    c.require(ransac_confidence > 0.0 && ransac_confidence < 1.0, "ransac_confidence", "in (0, 1)");
    c.throwIfFailed();
}

// ---------------------------------------------------------------- estimator
void EstimatorOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                          const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys({"ceiling_height_m", "ceiling_height_sigma_m", "tilt_sigma_deg",
                         "pixel_sigma_px", "huber_loss_px", "max_iterations", "min_inliers"});
    ceiling_height_m = s.getDouble("ceiling_height_m", ceiling_height_m);
    ceiling_height_sigma_m = s.getDouble("ceiling_height_sigma_m", ceiling_height_sigma_m);
    tilt_sigma_deg = s.getDouble("tilt_sigma_deg", tilt_sigma_deg);
    pixel_sigma_px = s.getDouble("pixel_sigma_px", pixel_sigma_px);
    huber_loss_px = s.getDouble("huber_loss_px", huber_loss_px);
    max_iterations = s.getInt("max_iterations", max_iterations, 1, 100000);
    min_inliers = s.getInt("min_inliers", min_inliers, 3, 1024);
}

void EstimatorOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                        const std::string& s) const {
    write(t, s, "ceiling_height_m", ceiling_height_m);
    write(t, s, "ceiling_height_sigma_m", ceiling_height_sigma_m);
    write(t, s, "tilt_sigma_deg", tilt_sigma_deg);
    write(t, s, "pixel_sigma_px", pixel_sigma_px);
    write(t, s, "huber_loss_px", huber_loss_px);
    write(t, s, "max_iterations", max_iterations);
    write(t, s, "min_inliers", min_inliers);
}

void EstimatorOptions::check() const {
    OptionsCheck c("refine.estimator");
    c.require(std::isfinite(ceiling_height_m), "ceiling_height_m", "finite");
    c.require(ceiling_height_sigma_m > 0.0, "ceiling_height_sigma_m", "> 0");
    c.require(tilt_sigma_deg > 0.0, "tilt_sigma_deg", "> 0");
    c.require(pixel_sigma_px > 0.0, "pixel_sigma_px", "> 0");
    c.require(huber_loss_px > 0.0, "huber_loss_px", "> 0");
    c.require(max_iterations >= 1, "max_iterations", ">= 1");
    c.require(min_inliers >= 3, "min_inliers", ">= 3");
    c.throwIfFailed();
}

// ---------------------------------------------------------------- acceptance
void AcceptanceOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                           const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys(
        {"min_inlier_share", "max_offset_m", "fallback_sigma_xy_m", "fallback_sigma_yaw_deg",
         "dead_reckoning_sigma_xy_m", "dead_reckoning_sigma_xy_per_m",
         "dead_reckoning_sigma_yaw_deg", "dead_reckoning_sigma_yaw_deg_per_m"});
    min_inlier_share = s.getDouble("min_inlier_share", min_inlier_share);
    max_offset_m = s.getDouble("max_offset_m", max_offset_m);
    fallback_sigma_xy_m = s.getDouble("fallback_sigma_xy_m", fallback_sigma_xy_m);
    fallback_sigma_yaw_deg = s.getDouble("fallback_sigma_yaw_deg", fallback_sigma_yaw_deg);
    dead_reckoning_sigma_xy_m = s.getDouble("dead_reckoning_sigma_xy_m", dead_reckoning_sigma_xy_m);
    dead_reckoning_sigma_xy_per_m =
        s.getDouble("dead_reckoning_sigma_xy_per_m", dead_reckoning_sigma_xy_per_m);
    dead_reckoning_sigma_yaw_deg =
        s.getDouble("dead_reckoning_sigma_yaw_deg", dead_reckoning_sigma_yaw_deg);
    dead_reckoning_sigma_yaw_deg_per_m =
        s.getDouble("dead_reckoning_sigma_yaw_deg_per_m", dead_reckoning_sigma_yaw_deg_per_m);
}

void AcceptanceOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                         const std::string& s) const {
    write(t, s, "min_inlier_share", min_inlier_share);
    write(t, s, "max_offset_m", max_offset_m);
    write(t, s, "fallback_sigma_xy_m", fallback_sigma_xy_m);
    write(t, s, "fallback_sigma_yaw_deg", fallback_sigma_yaw_deg);
    write(t, s, "dead_reckoning_sigma_xy_m", dead_reckoning_sigma_xy_m);
    write(t, s, "dead_reckoning_sigma_xy_per_m", dead_reckoning_sigma_xy_per_m);
    write(t, s, "dead_reckoning_sigma_yaw_deg", dead_reckoning_sigma_yaw_deg);
    write(t, s, "dead_reckoning_sigma_yaw_deg_per_m", dead_reckoning_sigma_yaw_deg_per_m);
}

void AcceptanceOptions::check() const {
    OptionsCheck c("refine.acceptance");
    c.require(min_inlier_share >= 0.0 && min_inlier_share <= 1.0, "min_inlier_share", "in [0, 1]");
    c.require(max_offset_m > 0.0, "max_offset_m", "> 0");
    c.require(fallback_sigma_xy_m > 0.0, "fallback_sigma_xy_m", "> 0");
    c.require(fallback_sigma_yaw_deg > 0.0, "fallback_sigma_yaw_deg", "> 0");
    c.require(dead_reckoning_sigma_xy_m > 0.0, "dead_reckoning_sigma_xy_m", "> 0");
    c.require(dead_reckoning_sigma_xy_per_m >= 0.0, "dead_reckoning_sigma_xy_per_m", ">= 0");
    c.require(dead_reckoning_sigma_yaw_deg > 0.0, "dead_reckoning_sigma_yaw_deg", "> 0");
    c.require(dead_reckoning_sigma_yaw_deg_per_m >= 0.0, "dead_reckoning_sigma_yaw_deg_per_m",
              ">= 0");
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
}

void RefinerOptions::saveToConfigFile(mrpt::config::CConfigFileBase& target,
                                      const std::string& prefix) const {
    sampler.saveToConfigFile(target, prefix + ".sampler");
    matcher.saveToConfigFile(target, prefix + ".matcher");
    homography.saveToConfigFile(target, prefix + ".homography");
    estimator.saveToConfigFile(target, prefix + ".estimator");
    acceptance.saveToConfigFile(target, prefix + ".acceptance");
    correspondence.saveToConfigFile(target, prefix + ".correspondence");
}

void RefinerOptions::check() const {
    sampler.check();
    matcher.check();
    homography.check();
    estimator.check();
    acceptance.check();
    correspondence.check();
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

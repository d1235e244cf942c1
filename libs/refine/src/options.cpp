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
    t.add("mode", mode, kSamplingModes);
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
    t.add("min_texture", min_texture);
    t.add("min_distinctiveness", min_distinctiveness);
    t.add("exclusion_radius_px", exclusion_radius_px, 1, 4096);
    t.add("subpixel", subpixel, kSubpixelMethods);
    t.add("use_simd", use_simd);
    t.add("normalize_brightness", normalize_brightness);
    t.add("illumination_sigma_px", illumination_sigma_px);
    t.add("compensate_motion", compensate_motion);
}

void HomographyOptions::declareKeys(OptionsTable& t) {
    t.add("ransac_min_points", ransac_min_points, 4, 1024);
    t.add("ransac_threshold_px", ransac_threshold_px);
    t.add("ransac_max_iterations", ransac_max_iterations, 1, 1000000);
    t.add("ransac_confidence", ransac_confidence);
}

void EstimatorOptions::declareKeys(OptionsTable& t) {
    t.add("ceiling_height_m", ceiling_height_m);
    t.add("ceiling_height_sigma_m", ceiling_height_sigma_m);
    t.add("tilt_sigma_deg", tilt_sigma_deg);
    t.add("pixel_sigma_px", pixel_sigma_px);
    t.add("huber_loss_px", huber_loss_px);
    t.add("max_iterations", max_iterations, 1, 100000);
    t.add("min_inliers", min_inliers, 3, 1024);
}

void AcceptanceOptions::declareKeys(OptionsTable& t) {
    t.add("min_inlier_share", min_inlier_share);
    t.add("max_offset_m", max_offset_m);
    t.add("fallback_sigma_xy_m", fallback_sigma_xy_m);
    t.add("fallback_sigma_yaw_deg", fallback_sigma_yaw_deg);
}

// ---------------------------------------------------------------- checks
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

void HomographyOptions::check() const {
    OptionsCheck c("refine.homography");
    c.require(ransac_min_points >= 4, "ransac_min_points", ">= 4");
    c.require(ransac_threshold_px > 0.0, "ransac_threshold_px", "> 0");
    c.require(ransac_max_iterations >= 1, "ransac_max_iterations", ">= 1");
    c.require(ransac_confidence > 0.0 && ransac_confidence < 1.0, "ransac_confidence", "in (0, 1)");
    c.throwIfFailed();
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

void AcceptanceOptions::check() const {
    OptionsCheck c("refine.acceptance");
    c.require(min_inlier_share >= 0.0 && min_inlier_share <= 1.0, "min_inlier_share", "in [0, 1]");
    c.require(max_offset_m > 0.0, "max_offset_m", "> 0");
    c.require(fallback_sigma_xy_m > 0.0, "fallback_sigma_xy_m", "> 0");
    c.require(fallback_sigma_yaw_deg > 0.0, "fallback_sigma_yaw_deg", "> 0");
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

std::vector<std::string> RefinerOptions::sectionNames(const std::string& prefix) {
    std::vector<std::string> out;
    for (const char* stage :
         {"sampler", "matcher", "homography", "estimator", "acceptance", "correspondence"}) {
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

#include "lookup/survey/survey_options.h"

#include "lookup/common/config.h"

#include <mrpt/core/bits_math.h>

#include <cmath>
#include <sstream>

namespace lookup::survey {

std::optional<mrpt::poses::CPose2D> parseStartPose(const std::string& text) {
    std::istringstream in(text);
    double x, y, yaw_deg;
    std::string rest;
    if (!(in >> x >> y >> yaw_deg) || (in >> rest)) return std::nullopt;
    if (!std::isfinite(x) || !std::isfinite(y) || !std::isfinite(yaw_deg)) return std::nullopt;
    return mrpt::poses::CPose2D(x, y, mrpt::DEG2RAD(yaw_deg));
}

void SurveyOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                       const std::string& section) {
    common::IniSection s(source, section);
    s.rejectUnknownKeys({"ceiling_camera_label",
                         "forward_camera_label",
                         "lidar_label",
                         "odometry_label",
                         "keyframe_spacing_m",
                         "min_sharpness",
                         "min_mean_intensity",
                         "max_mean_intensity",
                         "max_clipped_fraction",
                         "forward_max_dt_s",
                         "max_pose_gap_s",
                         "max_outside_fraction",
                         "ceiling_height_m",
                         "mcl_particles",
                         "mcl_init_std_xy_m",
                         "mcl_init_std_yaw_deg",
                         "odometry_min_std_xy_m",
                         "odometry_min_std_yaw_deg",
                         "start_at_ground_truth",
                         "icp_max_range_m", "lidar_sweep_ms",
                         "map_std_xy_m",
                         "map_std_yaw_deg",
                         "pose_file_std_xy_m",
                         "pose_file_std_yaw_deg",
                         "ceiling_estimate",
                         "ceiling_sample_spacing_m",
                         "ceiling_baseline_m",
                         "ceiling_prior_sigma_m",
                         "ceiling_min_pairs",
                         "use_dataset_ceiling_height",
                         "start_pose",
                         "start_search_spacing_m",
                         "start_match_travel_m",
                         "start_min_goodness",
                         "ceiling_time_offset_s",
                         "forward_time_offset_s",
                         "time_offset_estimate",
                         "time_offset_max_s",
                         "time_offset_baseline_m",
                         "time_offset_max_pairs",
                         "time_offset_min_pairs",
                         "time_offset_max_sigma_s"});
    ceiling_camera_label = s.getString("ceiling_camera_label", ceiling_camera_label);
    forward_camera_label = s.getString("forward_camera_label", forward_camera_label);
    lidar_label = s.getString("lidar_label", lidar_label);
    odometry_label = s.getString("odometry_label", odometry_label);
    keyframe_spacing_m = s.getDouble("keyframe_spacing_m", keyframe_spacing_m);
    min_sharpness = s.getDouble("min_sharpness", min_sharpness);
    min_mean_intensity = s.getDouble("min_mean_intensity", min_mean_intensity);
    max_mean_intensity = s.getDouble("max_mean_intensity", max_mean_intensity);
    max_clipped_fraction = s.getDouble("max_clipped_fraction", max_clipped_fraction);
    forward_max_dt_s = s.getDouble("forward_max_dt_s", forward_max_dt_s);
    max_pose_gap_s = s.getDouble("max_pose_gap_s", max_pose_gap_s);
    max_outside_fraction = s.getDouble("max_outside_fraction", max_outside_fraction);
    ceiling_height_m = s.getDouble("ceiling_height_m", ceiling_height_m);
    ceiling_estimate = s.getBool("ceiling_estimate", ceiling_estimate);
    ceiling_sample_spacing_m = s.getDouble("ceiling_sample_spacing_m", ceiling_sample_spacing_m);
    ceiling_baseline_m = s.getDouble("ceiling_baseline_m", ceiling_baseline_m);
    ceiling_prior_sigma_m = s.getDouble("ceiling_prior_sigma_m", ceiling_prior_sigma_m);
    ceiling_min_pairs = s.getInt("ceiling_min_pairs", ceiling_min_pairs, 1, 1000000);
    use_dataset_ceiling_height =
        s.getBool("use_dataset_ceiling_height", use_dataset_ceiling_height);
    ceiling_time_offset_s = s.getDouble("ceiling_time_offset_s", ceiling_time_offset_s);
    forward_time_offset_s = s.getDouble("forward_time_offset_s", forward_time_offset_s);
    time_offset_estimate = s.getBool("time_offset_estimate", time_offset_estimate);
    time_offset_max_s = s.getDouble("time_offset_max_s", time_offset_max_s);
    time_offset_baseline_m = s.getDouble("time_offset_baseline_m", time_offset_baseline_m);
    time_offset_max_pairs = s.getInt("time_offset_max_pairs", time_offset_max_pairs, 1, 1000000);
    time_offset_min_pairs = s.getInt("time_offset_min_pairs", time_offset_min_pairs, 1, 1000000);
    time_offset_max_sigma_s = s.getDouble("time_offset_max_sigma_s", time_offset_max_sigma_s);
    start_pose = s.getString("start_pose", start_pose);
    start_search_spacing_m = s.getDouble("start_search_spacing_m", start_search_spacing_m);
    start_match_travel_m = s.getDouble("start_match_travel_m", start_match_travel_m);
    start_min_goodness = s.getDouble("start_min_goodness", start_min_goodness);
    mcl_particles = s.getInt("mcl_particles", mcl_particles, 10, 10000000);
    mcl_init_std_xy_m = s.getDouble("mcl_init_std_xy_m", mcl_init_std_xy_m);
    mcl_init_std_yaw_deg = s.getDouble("mcl_init_std_yaw_deg", mcl_init_std_yaw_deg);
    odometry_min_std_xy_m = s.getDouble("odometry_min_std_xy_m", odometry_min_std_xy_m);
    odometry_min_std_yaw_deg = s.getDouble("odometry_min_std_yaw_deg", odometry_min_std_yaw_deg);
    start_at_ground_truth = s.getBool("start_at_ground_truth", start_at_ground_truth);
    icp_max_range_m = s.getDouble("icp_max_range_m", icp_max_range_m);
    lidar_sweep_ms = s.getDouble("lidar_sweep_ms", lidar_sweep_ms, 0.0, 1000.0);
    map_std_xy_m = s.getDouble("map_std_xy_m", map_std_xy_m);
    map_std_yaw_deg = s.getDouble("map_std_yaw_deg", map_std_yaw_deg);
    pose_file_std_xy_m = s.getDouble("pose_file_std_xy_m", pose_file_std_xy_m);
    pose_file_std_yaw_deg = s.getDouble("pose_file_std_yaw_deg", pose_file_std_yaw_deg);
    s.validate([&] { check(); });
}

void SurveyOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                     const std::string& section) const {
    c.write(section, "ceiling_camera_label", ceiling_camera_label);
    c.write(section, "forward_camera_label", forward_camera_label);
    c.write(section, "lidar_label", lidar_label);
    c.write(section, "odometry_label", odometry_label);
    c.write(section, "keyframe_spacing_m", keyframe_spacing_m);
    c.write(section, "min_sharpness", min_sharpness);
    c.write(section, "min_mean_intensity", min_mean_intensity);
    c.write(section, "max_mean_intensity", max_mean_intensity);
    c.write(section, "max_clipped_fraction", max_clipped_fraction);
    c.write(section, "forward_max_dt_s", forward_max_dt_s);
    c.write(section, "max_pose_gap_s", max_pose_gap_s);
    c.write(section, "max_outside_fraction", max_outside_fraction);
    c.write(section, "ceiling_height_m", ceiling_height_m);
    c.write(section, "ceiling_estimate", ceiling_estimate);
    c.write(section, "ceiling_sample_spacing_m", ceiling_sample_spacing_m);
    c.write(section, "ceiling_baseline_m", ceiling_baseline_m);
    c.write(section, "ceiling_prior_sigma_m", ceiling_prior_sigma_m);
    c.write(section, "ceiling_min_pairs", ceiling_min_pairs);
    c.write(section, "use_dataset_ceiling_height", use_dataset_ceiling_height);
    c.write(section, "ceiling_time_offset_s", ceiling_time_offset_s);
    c.write(section, "forward_time_offset_s", forward_time_offset_s);
    c.write(section, "time_offset_estimate", time_offset_estimate);
    c.write(section, "time_offset_max_s", time_offset_max_s);
    c.write(section, "time_offset_baseline_m", time_offset_baseline_m);
    c.write(section, "time_offset_max_pairs", time_offset_max_pairs);
    c.write(section, "time_offset_min_pairs", time_offset_min_pairs);
    c.write(section, "time_offset_max_sigma_s", time_offset_max_sigma_s);
    c.write(section, "start_pose", start_pose);
    c.write(section, "start_search_spacing_m", start_search_spacing_m);
    c.write(section, "start_match_travel_m", start_match_travel_m);
    c.write(section, "start_min_goodness", start_min_goodness);
    c.write(section, "mcl_particles", mcl_particles);
    c.write(section, "mcl_init_std_xy_m", mcl_init_std_xy_m);
    c.write(section, "mcl_init_std_yaw_deg", mcl_init_std_yaw_deg);
    c.write(section, "odometry_min_std_xy_m", odometry_min_std_xy_m);
    c.write(section, "odometry_min_std_yaw_deg", odometry_min_std_yaw_deg);
    c.write(section, "start_at_ground_truth", start_at_ground_truth);
    c.write(section, "icp_max_range_m", icp_max_range_m);
    c.write(section, "lidar_sweep_ms", lidar_sweep_ms);
    c.write(section, "map_std_xy_m", map_std_xy_m);
    c.write(section, "map_std_yaw_deg", map_std_yaw_deg);
    c.write(section, "pose_file_std_xy_m", pose_file_std_xy_m);
    c.write(section, "pose_file_std_yaw_deg", pose_file_std_yaw_deg);
}

void SurveyOptions::check() const {
    common::OptionsCheck c("survey");
    c.require(!ceiling_camera_label.empty(), "ceiling_camera_label", "not empty");
    c.require(keyframe_spacing_m > 0, "keyframe_spacing_m", "> 0");
    c.require(min_sharpness >= 0, "min_sharpness", ">= 0");
    c.require(min_mean_intensity >= 0 && min_mean_intensity < max_mean_intensity,
              "min_mean_intensity", ">= 0 and < max_mean_intensity");
    c.require(max_mean_intensity <= 255, "max_mean_intensity", "<= 255");
    c.require(max_clipped_fraction >= 0 && max_clipped_fraction <= 1, "max_clipped_fraction",
              "in [0, 1]");
    c.require(forward_max_dt_s > 0, "forward_max_dt_s", "> 0");
    c.require(max_pose_gap_s > 0, "max_pose_gap_s", "> 0");
    c.require(max_outside_fraction >= 0 && max_outside_fraction <= 1, "max_outside_fraction",
              "in [0, 1]");
    c.require(ceiling_height_m > 0, "ceiling_height_m", "> 0");
    c.require(ceiling_sample_spacing_m > 0, "ceiling_sample_spacing_m", "> 0");
    c.require(ceiling_baseline_m > 0 && ceiling_baseline_m <= 5, "ceiling_baseline_m", "in (0, 5]");
    c.require(ceiling_prior_sigma_m > 0, "ceiling_prior_sigma_m", "> 0");
    c.require(ceiling_min_pairs >= 1, "ceiling_min_pairs", ">= 1");
    c.require(std::isfinite(ceiling_time_offset_s) && std::abs(ceiling_time_offset_s) <= 1,
              "ceiling_time_offset_s", "in [-1, 1]");
    c.require(std::isfinite(forward_time_offset_s) && std::abs(forward_time_offset_s) <= 1,
              "forward_time_offset_s", "in [-1, 1]");
    c.require(time_offset_max_s > 0 && time_offset_max_s <= 1, "time_offset_max_s", "in (0, 1]");
    c.require(time_offset_baseline_m > 0 && time_offset_baseline_m <= 5, "time_offset_baseline_m",
              "in (0, 5]");
    c.require(time_offset_max_pairs >= time_offset_min_pairs, "time_offset_max_pairs",
              ">= time_offset_min_pairs");
    c.require(time_offset_max_sigma_s > 0, "time_offset_max_sigma_s", "> 0");
    c.require(start_pose.empty() || parseStartPose(start_pose).has_value(), "start_pose",
              "three numbers: x y yaw_deg");
    c.require(start_search_spacing_m > 0, "start_search_spacing_m", "> 0");
    c.require(start_match_travel_m >= 0, "start_match_travel_m", ">= 0");
    c.require(start_min_goodness >= 0 && start_min_goodness <= 1, "start_min_goodness",
              "in [0, 1]");
    c.require(mcl_particles >= 10, "mcl_particles", ">= 10");
    c.require(mcl_init_std_xy_m >= 0, "mcl_init_std_xy_m", ">= 0");
    c.require(mcl_init_std_yaw_deg >= 0, "mcl_init_std_yaw_deg", ">= 0");
    c.require(odometry_min_std_xy_m > 0, "odometry_min_std_xy_m", "> 0");
    c.require(odometry_min_std_yaw_deg > 0, "odometry_min_std_yaw_deg", "> 0");
    c.require(icp_max_range_m >= 0, "icp_max_range_m", ">= 0 (0 = no limit)");
    c.require(lidar_sweep_ms >= 0 && lidar_sweep_ms <= 1000, "lidar_sweep_ms",
              "in [0, 1000] (0 = scans taken at one instant)");
    c.require(map_std_xy_m >= 0, "map_std_xy_m", ">= 0");
    c.require(map_std_yaw_deg >= 0, "map_std_yaw_deg", ">= 0");
    c.require(pose_file_std_xy_m >= 0, "pose_file_std_xy_m", ">= 0");
    c.require(pose_file_std_yaw_deg >= 0, "pose_file_std_yaw_deg", ">= 0");
    c.throwIfFailed();
}

}  // namespace lookup::survey

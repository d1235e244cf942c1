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

std::optional<std::vector<TimedMark>> parseMarks(const std::string& text) {
    std::vector<TimedMark> marks;
    std::istringstream list(text);
    std::string item;
    while (std::getline(list, item, ';')) {
        std::istringstream in(item);
        TimedMark m;
        if (!(in >> m.time_s) || !std::isfinite(m.time_s)) {
            if (item.find_first_not_of(" \t") == std::string::npos) continue;  // "a;;b", "a;"
            return std::nullopt;
        }
        std::string pose;
        std::getline(in, pose);
        const auto p = parseStartPose(pose);
        if (!p) return std::nullopt;
        m.pose = *p;
        marks.push_back(m);
    }
    return marks;
}

void SurveyOptions::declareKeys(common::OptionsTable& t) {
    t.add("ceiling_camera_label", ceiling_camera_label);
    t.add("forward_camera_label", forward_camera_label);
    t.add("lidar_label", lidar_label);
    t.add("odometry_label", odometry_label);
    t.add("imu_label", imu_label);
    t.add("floor_return_margin_m", floor_return_margin_m, 0.0, 5.0);
    t.add("roof_return_margin_m", roof_return_margin_m, 0.0, 20.0);
    t.add("keyframe_spacing_m", keyframe_spacing_m, common::kPositive);
    lens.declareKeys(t);
    t.add("min_sharpness", min_sharpness, 0.0);
    t.add("min_mean_intensity", min_mean_intensity);
    t.add("max_mean_intensity", max_mean_intensity);
    t.add("max_clipped_fraction", max_clipped_fraction, 0.0, 1.0);
    t.add("warn_dim_mean_intensity", warn_dim_mean_intensity, 0.0, 255.0);
    t.add("warn_clipped_fraction", warn_clipped_fraction, 0.0, 1.0);
    t.add("ceiling_max_width_px", ceiling_max_width_px, 0, 100000);
    t.add("forward_max_dt_s", forward_max_dt_s, common::kPositive);
    t.add("max_pose_gap_s", max_pose_gap_s, common::kPositive);
    t.add("max_outside_fraction", max_outside_fraction, 0.0, 1.0);
    t.add("ceiling_height_m", ceiling_height_m, common::kPositive);
    t.add("ceiling_estimate", ceiling_estimate);
    t.add("ceiling_sample_spacing_m", ceiling_sample_spacing_m, common::kPositive);
    t.add("ceiling_baseline_m", ceiling_baseline_m, common::kPositive, 5.0);
    t.add("ceiling_prior_sigma_m", ceiling_prior_sigma_m, common::kPositive);
    t.add("ceiling_min_pairs", ceiling_min_pairs, 1, 1000000);
    t.add("use_dataset_ceiling_height", use_dataset_ceiling_height);
    t.add("ceiling_time_offset_s", ceiling_time_offset_s, -1.0, 1.0);
    t.add("forward_time_offset_s", forward_time_offset_s, -1.0, 1.0);
    t.add("ceiling_time_offset_sigma_s", ceiling_time_offset_sigma_s, 0.0, 1.0);
    t.add("ceiling_readout_ms", ceiling_readout_ms, 0.0, 999.999);
    t.add("ceiling_stamp_row", ceiling_stamp_row, common::stampRowNames());
    t.add("time_offset_estimate", time_offset_estimate);
    t.add("time_offset_max_s", time_offset_max_s, common::kPositive, 1.0);
    t.add("time_offset_contradiction_s", time_offset_contradiction_s, common::kPositive);
    t.add("time_offset_baseline_m", time_offset_baseline_m, common::kPositive, 5.0);
    t.add("time_offset_max_pairs", time_offset_max_pairs, 1, 1000000);
    t.add("time_offset_min_pairs", time_offset_min_pairs, 1, 1000000);
    t.add("time_offset_max_sigma_s", time_offset_max_sigma_s, common::kPositive);
    t.add("time_offset_min_velocity_difference_mps", time_offset_min_velocity_difference_mps, 0.0,
          100.0);
    t.add("pose_audit", pose_audit);
    t.add("pose_audit_spacing_m", pose_audit_spacing_m, common::kPositive);
    t.add("pose_audit_view_distance_m", pose_audit_view_distance_m, common::kPositive);
    t.add("pose_audit_search_m", pose_audit_search_m, 0.0, 100.0);
    t.add("pose_audit_max_disagreement_m", pose_audit_max_disagreement_m, common::kPositive);
    t.add("start_pose", start_pose);
    t.add("start_pose_std_xy_m", start_pose_std_xy_m, 0.0);
    t.add("start_pose_std_yaw_deg", start_pose_std_yaw_deg, 0.0, 180.0);
    t.add("end_pose", end_pose);
    t.add("end_pose_std_xy_m", end_pose_std_xy_m, common::kPositive);
    t.add("end_pose_std_yaw_deg", end_pose_std_yaw_deg, common::kPositive, 180.0);
    t.add("marks", marks);
    t.add("marks_std_xy_m", marks_std_xy_m, common::kPositive);
    t.add("marks_std_yaw_deg", marks_std_yaw_deg, common::kPositive, 180.0);
    t.add("start_search_spacing_m", start_search_spacing_m, common::kPositive);
    t.add("start_match_travel_m", start_match_travel_m, 0.0);
    t.add("start_min_goodness", start_min_goodness, 0.0, 1.0);
    t.add("start_by_ceiling", start_by_ceiling);
    t.add("mcl_particles", mcl_particles, 10, 10000000);
    t.add("mcl_init_std_xy_m", mcl_init_std_xy_m, 0.0);
    t.add("mcl_init_std_yaw_deg", mcl_init_std_yaw_deg, 0.0);
    t.add("odometry_min_std_xy_m", odometry_min_std_xy_m, common::kPositive);
    t.add("odometry_min_std_yaw_deg", odometry_min_std_yaw_deg, common::kPositive);
    t.add("start_at_ground_truth", start_at_ground_truth);
    t.add("icp_max_range_m", icp_max_range_m);
    t.add("lidar_sweep_ms", lidar_sweep_ms, 0.0, 1000.0);
    t.add("lidar_sweep_estimate", lidar_sweep_estimate);
    t.add("lidar_sweep_estimate_m", lidar_sweep_estimate_m, common::kPositive);
    t.add("map_std_xy_m", map_std_xy_m, 0.0);
    t.add("map_std_yaw_deg", map_std_yaw_deg, 0.0);
    t.add("pose_file_std_xy_m", pose_file_std_xy_m, 0.0);
    t.add("pose_file_std_yaw_deg", pose_file_std_yaw_deg, 0.0);
    refresh.declareKeys(t);
}

void SurveyOptions::check() const {
    common::OptionsCheck c("survey");
    checkRanges(c);
    c.require(!ceiling_camera_label.empty(), "ceiling_camera_label", "not empty");
    lens.check(c);
    c.require(min_mean_intensity >= 0 && min_mean_intensity < max_mean_intensity,
              "min_mean_intensity", ">= 0 and < max_mean_intensity");
    c.require(max_mean_intensity <= 255, "max_mean_intensity", "<= 255");
    c.require(time_offset_max_pairs >= time_offset_min_pairs, "time_offset_max_pairs",
              ">= time_offset_min_pairs");
    c.require(start_pose.empty() || parseStartPose(start_pose).has_value(), "start_pose",
              "three numbers: x y yaw_deg");
    c.require(end_pose.empty() || parseStartPose(end_pose).has_value(), "end_pose",
              "three numbers: x y yaw_deg");
    c.require(parseMarks(marks).has_value(), "marks",
              "\"t x y yaw_deg\" groups of four numbers separated by ';'");
    c.require(icp_max_range_m >= 0, "icp_max_range_m", ">= 0 (0 = no limit)");
    c.throwIfFailed();
}

}  // namespace lookup::survey

#include "lookup/localize/localizer_options.h"

#include "lookup/common/config.h"

namespace lookup::localize {

namespace {
const common::EnumNames<CoarseMode> kCoarseModes = {{"sequence", CoarseMode::Sequence},
                                                    {"ceiling", CoarseMode::Ceiling},
                                                    {"none", CoarseMode::None}};
const common::EnumNames<CameraClockApply> kCameraClockApply = {{"auto", CameraClockApply::Auto},
                                                               {"always", CameraClockApply::Always},
                                                               {"never", CameraClockApply::Never}};
}  // namespace

void LocalizerOptions::declareKeys(common::OptionsTable& t) {
    t.add("ceiling_camera_label", ceiling_camera_label);
    t.add("forward_camera_label", forward_camera_label);
    t.add("odometry_label", odometry_label);
    t.add("references_per_query", references_per_query, 1, 1000);
    t.add("use_tracking", use_tracking);
    t.add("max_tracking_gap_s", max_tracking_gap_s, common::kPositive);
    t.add("max_dead_reckoning_s", max_dead_reckoning_s, 0.0);
    t.add("ceiling_odometry", ceiling_odometry);
    t.add("ceiling_odometry_min_slip", ceiling_odometry_min_slip, 0.0, 10.0);
    t.add("ceiling_odometry_max_slip", ceiling_odometry_max_slip, 0.0, 10.0);
    t.add("online_refresh", online_refresh);
    t.add("online_refresh_spacing_m", online_refresh_spacing_m, common::kPositive);
    t.add("online_refresh_max_references", online_refresh_max_references, 0, 100000000);
    refresh.declareKeys(t);
    t.add("odometry_timeout_s", odometry_timeout_s, common::kPositive);
    t.add("image_time_sigma_s", image_time_sigma_s, 0.0, 1.0);
    t.add("uncalibrated_image_time_sigma_s", uncalibrated_image_time_sigma_s, 0.0, 1.0);
    t.add("estimate_camera_time_offset", camera_clock.enabled);
    t.add("apply_camera_time_offset", apply_camera_time_offset, kCameraClockApply);
    t.add("survey_clock_max_sigma_s", survey_clock_max_sigma_s, 0.0, 1.0);
    t.add("camera_time_offset_min_pairs", camera_clock.min_pairs, 3, 100000000);
    t.add("camera_time_offset_max_sigma_s", camera_clock.max_sigma_s, common::kPositive);
    t.add("camera_time_offset_significance", camera_clock.significance, 0.0, 100.0);
    t.add("estimate_readout", readout.enabled);
    t.add("apply_estimated_readout", readout.apply);
    t.add("readout_min_frames", readout.min_frames, 10, 100000000);
    t.add("readout_max_sigma_s", readout.max_sigma_s, common::kPositive);
    t.add("readout_significance", readout.significance, 0.0, 100.0);
    t.add("readout_min_s", readout.min_readout_s, 0.0, 1.0);
    lens.declareKeys(t);
    t.add("acquisition_radius_m", acquisition_radius_m, 0.0);
    t.add("acquisition_step_m", acquisition_step_m, common::kPositive);
    t.add("tracking_acquisition_sigmas", tracking_acquisition_sigmas, 0.0, 100.0);
    t.add("acquisition_ambiguity_margin", acquisition_ambiguity_margin);
    t.add("acquisition_ambiguity_distance_m", acquisition_ambiguity_distance_m, common::kPositive);
    t.add("acquisition_probe_points", acquisition_probe_points, 0, 100000);
    t.add("acquisition_probe_min_matched", acquisition_probe_min_matched, 0, 100000);
    t.add("startup_acquisition_frames", startup_acquisition_frames, 0, 100000000);
    t.add("coarse", coarse, kCoarseModes);
    t.add("place_search", place_search);
    t.add("place_candidates", place_candidates, 1, 100);
    t.add("place_check_every", place_check_every, 0, 100000000);
    t.add("track_disagreement_m", track_disagreement_m, 0.0);
    t.add("track_disagreement_per_m", track_disagreement_per_m, 0.0);
    t.add("track_disagreeing_fixes", track_disagreeing_fixes, 1, 100000000);
    t.add("track_heading_sigmas", track_heading_sigmas, common::kPositive);
    t.add("track_heading_floor_deg", track_heading_floor_deg, 0.0, 180.0);
    t.add("place_check_rival_share", place_check_rival_share, 0.0, 1.0);
    t.add("coarse_reject_after_frames", coarse_reject_after_frames, 1, 100000000);
    t.add("coarse_exclusion_m", coarse_exclusion_m, common::kPositive);
    t.add("coarse_traverse", coarse_traverse);
    t.add("coarse_while_tracking", coarse_while_tracking);
    t.add("realtime", realtime);
    t.add("max_latency_s", max_latency_s, common::kPositive);
    t.add("write_debug_images", write_debug_images);
    t.add("debug_image_every", debug_image_every, 1, 100000000);
    t.add("image_cache_capacity", image_cache_capacity, 1, 100000000);
    t.add("health_interval_s", health_interval_s, 0.0);
    t.add("camera_timeout_s", camera_timeout_s, 0.0);
    t.add("persist_fix_file", persist_fix_file);
    t.add("persist_interval_s", persist_interval_s, common::kPositive);
    t.add("camera_clock_file", camera_clock_file);
}

void LocalizerOptions::check() const {
    common::OptionsCheck c("localizer");
    checkRanges(c);
    c.require(!ceiling_camera_label.empty(), "ceiling_camera_label", "non-empty");
    c.require(acquisition_ambiguity_margin >= 0 && acquisition_ambiguity_margin < 1,
              "acquisition_ambiguity_margin", "in [0, 1)");
    c.require(acquisition_probe_min_matched <= acquisition_probe_points,
              "acquisition_probe_min_matched", "in [0, acquisition_probe_points]");
    c.require(ceiling_odometry_max_slip > ceiling_odometry_min_slip, "ceiling_odometry_max_slip",
              "> ceiling_odometry_min_slip");
    lens.check(c);
    c.require(image_cache_capacity >= static_cast<std::size_t>(references_per_query),
              "image_cache_capacity", ">= references_per_query");
    c.throwIfFailed();
}

}  // namespace lookup::localize

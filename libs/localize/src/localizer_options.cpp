#include "lookup/localize/localizer_options.h"

#include "lookup/common/config.h"

namespace lookup::localize {

void LocalizerOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                          const std::string& section) {
    const common::IniSection s(source, section);
    s.rejectUnknownKeys({"ceiling_camera_label",
                         "forward_camera_label",
                         "odometry_label",
                         "references_per_query",
                         "use_tracking",
                         "max_tracking_gap_s",
                         "acquisition_radius_m",
                         "acquisition_step_m",
                         "acquisition_ambiguity_margin",
                         "acquisition_ambiguity_distance_m",
                         "acquisition_probe_points",
                         "acquisition_probe_min_matched",
                         "startup_acquisition_frames",
                         "coarse",
                         "place_search",
                         "place_candidates",
                         "place_check_every",
                         "coarse_traverse",
                         "coarse_while_tracking",
                         "realtime",
                         "max_latency_s",
                         "write_debug_images",
                         "debug_image_every",
                         "image_cache_capacity",
                         "health_interval_s",
                         "camera_timeout_s",
                         "persist_fix_file",
                         "persist_interval_s"});
    ceiling_camera_label = s.getString("ceiling_camera_label", ceiling_camera_label);
    forward_camera_label = s.getString("forward_camera_label", forward_camera_label);
    odometry_label = s.getString("odometry_label", odometry_label);
    references_per_query = s.getInt("references_per_query", references_per_query, 1, 1000);
    use_tracking = s.getBool("use_tracking", use_tracking);
    max_tracking_gap_s = s.getDouble("max_tracking_gap_s", max_tracking_gap_s);
    acquisition_radius_m = s.getDouble("acquisition_radius_m", acquisition_radius_m);
    acquisition_step_m = s.getDouble("acquisition_step_m", acquisition_step_m);
    acquisition_ambiguity_margin =
        s.getDouble("acquisition_ambiguity_margin", acquisition_ambiguity_margin);
    acquisition_ambiguity_distance_m =
        s.getDouble("acquisition_ambiguity_distance_m", acquisition_ambiguity_distance_m);
    acquisition_probe_points =
        s.getInt("acquisition_probe_points", acquisition_probe_points, 0, 100000);
    acquisition_probe_min_matched =
        s.getInt("acquisition_probe_min_matched", acquisition_probe_min_matched, 0, 100000);
    startup_acquisition_frames =
        s.getInt("startup_acquisition_frames", startup_acquisition_frames, 0, 100000000);
    coarse = s.getString("coarse", coarse);
    place_search = s.getBool("place_search", place_search);
    place_candidates = s.getInt("place_candidates", place_candidates, 1, 100);
    place_check_every = s.getInt("place_check_every", place_check_every, 0, 100000000);
    coarse_traverse = s.getString("coarse_traverse", coarse_traverse);
    coarse_while_tracking = s.getBool("coarse_while_tracking", coarse_while_tracking);
    realtime = s.getBool("realtime", realtime);
    max_latency_s = s.getDouble("max_latency_s", max_latency_s);
    write_debug_images = s.getBool("write_debug_images", write_debug_images);
    debug_image_every = s.getInt("debug_image_every", debug_image_every, 1, 100000000);
    image_cache_capacity = static_cast<std::size_t>(
        s.getInt("image_cache_capacity", static_cast<int>(image_cache_capacity), 1, 100000000));
    health_interval_s = s.getDouble("health_interval_s", health_interval_s);
    camera_timeout_s = s.getDouble("camera_timeout_s", camera_timeout_s);
    persist_fix_file = s.getString("persist_fix_file", persist_fix_file);
    persist_interval_s = s.getDouble("persist_interval_s", persist_interval_s);
    s.validate([&] { check(); });
}

void LocalizerOptions::saveToConfigFile(mrpt::config::CConfigFileBase& target,
                                        const std::string& section) const {
    target.write(section, "ceiling_camera_label", ceiling_camera_label);
    target.write(section, "forward_camera_label", forward_camera_label);
    target.write(section, "odometry_label", odometry_label);
    target.write(section, "references_per_query", references_per_query);
    target.write(section, "use_tracking", use_tracking);
    target.write(section, "max_tracking_gap_s", max_tracking_gap_s);
    target.write(section, "acquisition_radius_m", acquisition_radius_m);
    target.write(section, "acquisition_step_m", acquisition_step_m);
    target.write(section, "acquisition_ambiguity_margin", acquisition_ambiguity_margin);
    target.write(section, "acquisition_ambiguity_distance_m", acquisition_ambiguity_distance_m);
    target.write(section, "acquisition_probe_points", acquisition_probe_points);
    target.write(section, "acquisition_probe_min_matched", acquisition_probe_min_matched);
    target.write(section, "startup_acquisition_frames", startup_acquisition_frames);
    target.write(section, "coarse", coarse);
    target.write(section, "place_search", place_search);
    target.write(section, "place_candidates", place_candidates);
    target.write(section, "place_check_every", place_check_every);
    target.write(section, "coarse_traverse", coarse_traverse);
    target.write(section, "coarse_while_tracking", coarse_while_tracking);
    target.write(section, "realtime", realtime);
    target.write(section, "max_latency_s", max_latency_s);
    target.write(section, "write_debug_images", write_debug_images);
    target.write(section, "debug_image_every", debug_image_every);
    target.write(section, "image_cache_capacity", static_cast<int>(image_cache_capacity));
    target.write(section, "health_interval_s", health_interval_s);
    target.write(section, "camera_timeout_s", camera_timeout_s);
    target.write(section, "persist_fix_file", persist_fix_file);
    target.write(section, "persist_interval_s", persist_interval_s);
}

void LocalizerOptions::check() const {
    common::OptionsCheck c("localizer");
    c.require(!ceiling_camera_label.empty(), "ceiling_camera_label", "non-empty");
    c.require(references_per_query >= 1, "references_per_query", ">= 1");
    c.require(coarse == "sequence" || coarse == "ceiling" || coarse == "none", "coarse",
              "one of sequence, ceiling, none");
    c.require(place_candidates >= 1, "place_candidates", ">= 1");
    c.require(place_check_every >= 0, "place_check_every", ">= 0");
    c.require(max_tracking_gap_s > 0, "max_tracking_gap_s", "> 0");
    c.require(acquisition_radius_m >= 0, "acquisition_radius_m", ">= 0");
    c.require(acquisition_step_m > 0, "acquisition_step_m", "> 0");
    c.require(acquisition_ambiguity_margin >= 0 && acquisition_ambiguity_margin < 1,
              "acquisition_ambiguity_margin", "in [0, 1)");
    c.require(acquisition_ambiguity_distance_m > 0, "acquisition_ambiguity_distance_m", "> 0");
    c.require(acquisition_probe_points >= 0, "acquisition_probe_points", ">= 0");
    c.require(acquisition_probe_min_matched >= 0 &&
                  acquisition_probe_min_matched <= acquisition_probe_points,
              "acquisition_probe_min_matched", "in [0, acquisition_probe_points]");
    c.require(startup_acquisition_frames >= 0, "startup_acquisition_frames", ">= 0");
    c.require(max_latency_s > 0, "max_latency_s", "> 0");
    c.require(debug_image_every >= 1, "debug_image_every", ">= 1");
    c.require(image_cache_capacity >= static_cast<std::size_t>(references_per_query),
              "image_cache_capacity", ">= references_per_query");
    c.require(health_interval_s >= 0, "health_interval_s", ">= 0");
    c.require(camera_timeout_s >= 0, "camera_timeout_s", ">= 0");
    c.require(persist_interval_s > 0, "persist_interval_s", "> 0");
    c.throwIfFailed();
}

}  // namespace lookup::localize

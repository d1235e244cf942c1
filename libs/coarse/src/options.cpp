#include "lookup/coarse/options.h"

#include <mrpt/config/CConfigFile.h>

#include "lookup/common/config.h"

namespace lookup::coarse {
namespace {
std::string sourceName(const mrpt::config::CConfigFileBase& source) {
    return common::configSourceName(source);
}
}  // namespace

void CoarseOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                       const std::string& section) {
    const common::IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys({"camera_label",
                         "thumb_width_px",
                         "thumb_height_px",
                         "patch_size_px",
                         "sequence_length",
                         "velocity_min",
                         "velocity_max",
                         "velocity_steps",
                         "contrast_window_refs",
                         "exclusion_half_window_refs",
                         "tracking_half_window_refs",
                         "min_confidence",
                         "global_index_min_references",
                         "global_index_neighbours",
                         "global_index_windows",
                         "global_index_full_search_every",
                         "use_odometry",
                         "odometry_scale_tolerance",
                         "odometry_scale_steps",
                         "odometry_sequence_length",
                         "max_coast_m",
                         "confirm_global",
                         "odometry_tolerance_m",
                         "odometry_tolerance_per_m"});
    camera_label = s.getString("camera_label", camera_label);
    thumb_width_px = s.getInt("thumb_width_px", thumb_width_px, 4, 1024);
    thumb_height_px = s.getInt("thumb_height_px", thumb_height_px, 4, 1024);
    patch_size_px = s.getInt("patch_size_px", patch_size_px, 2, 1024);
    sequence_length = s.getInt("sequence_length", sequence_length, 2, 100000);
    velocity_min = s.getDouble("velocity_min", velocity_min);
    velocity_max = s.getDouble("velocity_max", velocity_max);
    velocity_steps = s.getInt("velocity_steps", velocity_steps, 1, 1000);
    contrast_window_refs = s.getInt("contrast_window_refs", contrast_window_refs, 1, 100000);
    exclusion_half_window_refs =
        s.getInt("exclusion_half_window_refs", exclusion_half_window_refs, 0, 100000);
    tracking_half_window_refs =
        s.getInt("tracking_half_window_refs", tracking_half_window_refs, 1, 100000);
    min_confidence = s.getDouble("min_confidence", min_confidence);
    global_index_min_references =
        s.getInt("global_index_min_references", global_index_min_references, 0, 100000000);
    global_index_neighbours =
        s.getInt("global_index_neighbours", global_index_neighbours, 1, 100000);
    global_index_windows = s.getInt("global_index_windows", global_index_windows, 1, 100000);
    global_index_full_search_every =
        s.getInt("global_index_full_search_every", global_index_full_search_every, 0, 100000000);
    use_odometry = s.getBool("use_odometry", use_odometry);
    odometry_scale_tolerance = s.getDouble("odometry_scale_tolerance", odometry_scale_tolerance);
    odometry_scale_steps = s.getInt("odometry_scale_steps", odometry_scale_steps, 1, 1000);
    odometry_sequence_length =
        s.getInt("odometry_sequence_length", odometry_sequence_length, 2, 100000);
    max_coast_m = s.getDouble("max_coast_m", max_coast_m);
    confirm_global = s.getBool("confirm_global", confirm_global);
    odometry_tolerance_m = s.getDouble("odometry_tolerance_m", odometry_tolerance_m);
    odometry_tolerance_per_m = s.getDouble("odometry_tolerance_per_m", odometry_tolerance_per_m);
    try {
        check();
    } catch (const common::ConfigError& e) {
        throw common::ConfigError(s.sourceName() + " [" + section + "]: " + e.what());
    }
}

void CoarseOptions::saveToConfigFile(mrpt::config::CConfigFileBase& c,
                                     const std::string& section) const {
    c.write(section, "camera_label", camera_label);
    c.write(section, "thumb_width_px", thumb_width_px);
    c.write(section, "thumb_height_px", thumb_height_px);
    c.write(section, "patch_size_px", patch_size_px);
    c.write(section, "sequence_length", sequence_length);
    c.write(section, "velocity_min", velocity_min);
    c.write(section, "velocity_max", velocity_max);
    c.write(section, "velocity_steps", velocity_steps);
    c.write(section, "contrast_window_refs", contrast_window_refs);
    c.write(section, "exclusion_half_window_refs", exclusion_half_window_refs);
    c.write(section, "tracking_half_window_refs", tracking_half_window_refs);
    c.write(section, "min_confidence", min_confidence);
    c.write(section, "global_index_min_references", global_index_min_references);
    c.write(section, "global_index_neighbours", global_index_neighbours);
    c.write(section, "global_index_windows", global_index_windows);
    c.write(section, "global_index_full_search_every", global_index_full_search_every);
    c.write(section, "use_odometry", use_odometry ? "true" : "false");
    c.write(section, "odometry_scale_tolerance", odometry_scale_tolerance);
    c.write(section, "odometry_scale_steps", odometry_scale_steps);
    c.write(section, "odometry_sequence_length", odometry_sequence_length);
    c.write(section, "max_coast_m", max_coast_m);
    c.write(section, "confirm_global", confirm_global ? "true" : "false");
    c.write(section, "odometry_tolerance_m", odometry_tolerance_m);
    c.write(section, "odometry_tolerance_per_m", odometry_tolerance_per_m);
}

void CoarseOptions::check() const {
    common::OptionsCheck c("coarse");
    c.require(!camera_label.empty(), "camera_label", "non-empty");
    c.require(thumb_width_px >= 4 && thumb_width_px <= 1024, "thumb_width_px", "in [4, 1024]");
    c.require(thumb_height_px >= 4 && thumb_height_px <= 1024, "thumb_height_px", "in [4, 1024]");
    c.require(patch_size_px >= 2, "patch_size_px", ">= 2");
    if (patch_size_px >= 2) {
        c.require(thumb_width_px % patch_size_px == 0 && thumb_height_px % patch_size_px == 0,
                  "patch_size_px", "a divisor of thumb_width_px and thumb_height_px");
    }
    c.require(sequence_length >= 2, "sequence_length", ">= 2");
    c.require(velocity_min >= 0, "velocity_min", ">= 0");
    c.require(velocity_max >= velocity_min, "velocity_max", ">= velocity_min");
    c.require(velocity_steps >= 1, "velocity_steps", ">= 1");
    c.require(contrast_window_refs >= 1, "contrast_window_refs", ">= 1");
    c.require(exclusion_half_window_refs >= 0, "exclusion_half_window_refs", ">= 0");
    c.require(tracking_half_window_refs > exclusion_half_window_refs, "tracking_half_window_refs",
              "> exclusion_half_window_refs");
    c.require(min_confidence >= 0, "min_confidence", ">= 0");
    c.require(global_index_min_references >= 0, "global_index_min_references", ">= 0");
    c.require(global_index_neighbours >= 1, "global_index_neighbours", ">= 1");
    c.require(global_index_windows >= 1, "global_index_windows", ">= 1");
    c.require(global_index_full_search_every >= 0, "global_index_full_search_every", ">= 0");
    c.require(odometry_scale_tolerance >= 0 && odometry_scale_tolerance < 1,
              "odometry_scale_tolerance", "in [0, 1)");
    c.require(odometry_scale_steps >= 1, "odometry_scale_steps", ">= 1");
    c.require(odometry_sequence_length >= sequence_length, "odometry_sequence_length",
              ">= sequence_length");
    c.require(max_coast_m >= 0, "max_coast_m", ">= 0");
    c.require(odometry_tolerance_m > 0, "odometry_tolerance_m", "> 0");
    c.require(odometry_tolerance_per_m >= 0 && odometry_tolerance_per_m < 1,
              "odometry_tolerance_per_m", "in [0, 1)");
    c.throwIfFailed();
}

bool CoarseOptions::sameDescriptor(const CoarseOptions& o) const {
    return thumb_width_px == o.thumb_width_px && thumb_height_px == o.thumb_height_px &&
           patch_size_px == o.patch_size_px;
}

}  // namespace lookup::coarse

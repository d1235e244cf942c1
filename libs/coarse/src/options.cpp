#include "lookup/coarse/options.h"

#include "lookup/common/config.h"

namespace lookup::coarse {
void CoarseOptions::declareKeys(common::OptionsTable& t) {
    t.add("camera_label", camera_label);
    t.add("thumb_width_px", thumb_width_px, 4, 1024);
    t.add("thumb_height_px", thumb_height_px, 4, 1024);
    t.add("patch_size_px", patch_size_px, 2, 1024);
    t.add("sequence_length", sequence_length, 2, 100000);
    t.add("velocity_min", velocity_min, 0.0);
    t.add("velocity_max", velocity_max);
    t.add("velocity_steps", velocity_steps, 1, 1000);
    t.add("contrast_window_refs", contrast_window_refs, 1, 100000);
    t.add("exclusion_half_window_refs", exclusion_half_window_refs, 0, 100000);
    t.add("tracking_half_window_refs", tracking_half_window_refs, 1, 100000);
    t.add("min_confidence", min_confidence, 0.0);
    t.add("global_index_min_references", global_index_min_references, 0,
          std::numeric_limits<int>::max());
    t.add("global_index_neighbours", global_index_neighbours, 1, 100000);
    t.add("global_index_windows", global_index_windows, 1, 100000);
    t.add("global_index_full_search_every", global_index_full_search_every, 0, 100000000);
    t.add("use_odometry", use_odometry);
    t.add("odometry_scale_tolerance", odometry_scale_tolerance);
    t.add("odometry_scale_steps", odometry_scale_steps, 1, 1000);
    t.add("odometry_sequence_length", odometry_sequence_length, 2, 100000);
    t.add("max_coast_m", max_coast_m, 0.0);
    t.add("confirm_global", confirm_global);
    t.add("odometry_tolerance_m", odometry_tolerance_m, common::kPositive);
    t.add("odometry_tolerance_per_m", odometry_tolerance_per_m);
}

void CoarseOptions::check() const {
    common::OptionsCheck c("coarse");
    checkRanges(c);
    c.require(!camera_label.empty(), "camera_label", "non-empty");
    if (patch_size_px >= 2) {
        c.require(thumb_width_px % patch_size_px == 0 && thumb_height_px % patch_size_px == 0,
                  "patch_size_px", "a divisor of thumb_width_px and thumb_height_px");
    }
    c.require(velocity_max >= velocity_min, "velocity_max", ">= velocity_min");
    c.require(tracking_half_window_refs > exclusion_half_window_refs, "tracking_half_window_refs",
              "> exclusion_half_window_refs");
    c.require(odometry_scale_tolerance >= 0 && odometry_scale_tolerance < 1,
              "odometry_scale_tolerance", "in [0, 1)");
    c.require(odometry_sequence_length >= sequence_length, "odometry_sequence_length",
              ">= sequence_length");
    c.require(odometry_tolerance_per_m >= 0 && odometry_tolerance_per_m < 1,
              "odometry_tolerance_per_m", "in [0, 1)");
    c.throwIfFailed();
}

bool CoarseOptions::sameDescriptor(const CoarseOptions& o) const {
    return thumb_width_px == o.thumb_width_px && thumb_height_px == o.thumb_height_px &&
           patch_size_px == o.patch_size_px;
}

}  // namespace lookup::coarse

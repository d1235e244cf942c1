#pragma once
// Options of the coarse stage: SeqSLAM-family whole-image sequence matching on the forward
// camera (Milford & Wyeth, ICRA 2012), the "coarse localisation unit" of the LookUP paper
// (Sec. III-D: its interface is the time stamp of the matched reference image).

#include <mrpt/config/CLoadableOptions.h>

#include <string>

#include "lookup/common/options_table.h"

namespace lookup::coarse {

/// Every parameter of descriptor extraction and sequence search. The paper's Table I has no
/// coarse-stage entries, so defaults follow SeqSLAM and were tuned on the lookup-sim presets.
/// Loaded strictly from an .ini section (default "coarse"); unknown keys are refused.
struct CoarseOptions : public common::TableOptions<CoarseOptions> {
    // --- Input -----------------------------------------------------------------------------
    std::string camera_label = "FORWARD_CAM";  ///< sensorLabel of the forward camera images

    // --- Descriptor (SeqSLAM: downsampled, patch-normalised thumbnail) ----------------------
    int thumb_width_px = 64;   ///< thumbnail width after area down-sampling [px]
    int thumb_height_px = 48;  ///< thumbnail height [px]
    int patch_size_px = 8;     ///< P: side of the non-overlapping normalisation patches [px];
                               ///< must divide both thumbnail sides

    // --- Sequence search ---------------------------------------------------------------------
    int sequence_length = 30;   ///< d_s: query frames in one sequence hypothesis [frames]
    double velocity_min = 0.4;  ///< V_min: slowest relative speed [reference frames / query frame]
    double velocity_max = 2.5;  ///< V_max: fastest relative speed [reference frames / query frame]
    int velocity_steps = 22;    ///< number of speeds tried, evenly spaced in [V_min, V_max]
    int contrast_window_refs = 10;  ///< R_window: half-width of the local contrast enhancement
                                    ///< of each confusion-matrix column [references]
    int exclusion_half_window_refs = 10;  ///< second-best match is sought outside this
                                          ///< half-width around the best [references]

    // --- Online behaviour ----------------------------------------------------------------------
    int tracking_half_window_refs = 25;  ///< while tracking, candidates lie within this
                                         ///< half-width of the predicted reference [references]
    double min_confidence = 0.2;         ///< below this margin (see CoarseResult::confidence) the
                                         ///< match is not trusted: a global search follows

    // --- Global search over a long reference (DescriptorIndex) -------------------------------
    /// References of at least this many frames are searched through an approximate
    /// nearest-neighbour index of their descriptors: only windows of
    /// +/- tracking_half_window_refs around the places the index finds for the buffered query
    /// frames are scored, so a global search costs about the same on any reference length.
    /// Shorter references are searched whole (exact, and no dearer than the windows).
    int global_index_min_references = 1000;
    int global_index_neighbours = 8;  ///< places the index returns per buffered query frame
    int global_index_windows = 16;    ///< most windows one indexed search scores (the most voted)
    /// While indexed global searches stay unconfident, every this many frames one scores the
    /// whole reference instead (0: never): a safety net where single thumbnails say little
    /// about the place, at 1/this of a whole-reference search per lost frame.
    int global_index_full_search_every = 150;

    // --- Odometry (optional) -------------------------------------------------------------------
    bool use_odometry = true;  ///< use travelled distance when the caller gives it and the
                               ///< references carry positions (replaces the speed range)
    double odometry_scale_tolerance = 0.15;  ///< odometry scale error hypotheses span
                                             ///< 1 +/- this [fraction]
    int odometry_scale_steps = 7;            ///< number of scale hypotheses
    /// With odometry, global searches score paths over up to this many frames (tracking keeps
    /// sequence_length); min_confidence, given for sequence_length frames, is scaled by
    /// sqrt(sequence_length / frames) for them (the margin is a mean over the frames).
    int odometry_sequence_length = 150;
    /// While tracking with odometry, a window match below min_confidence does not end the
    /// track: it is held at the reference the travelled distance predicts (status "odometry")
    /// for up to this distance since the last confident match [m]; 0 ends it at once (a global
    /// search follows). Long uniform drives alias every forward view, odometry does not.
    double max_coast_m = 100;
    /// With odometry, a confident global match starts tracking only when a later global
    /// match, from a sequence that does not overlap it, lies where the travelled distance
    /// carries the first one (aliased places rarely agree twice); until then it is
    /// "unconfirmed" (not usable).
    bool confirm_global = true;
    /// How far a match may lie from where odometry puts it [m] ... : the confirming global
    /// match, and window matches while tracking (a farther one is taken for aliasing and the
    /// track is held by odometry instead).
    double odometry_tolerance_m = 4;
    double odometry_tolerance_per_m = 0.05;  ///< ... plus this share of the distance travelled
                                             ///< since the match odometry starts from

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);

    /// Throws common::ConfigError naming every field out of range ("coarse.<field> must be").
    void check() const;

    /// True when descriptors made with `other` can be compared with descriptors made with
    /// these options (same thumbnail and patch).
    bool sameDescriptor(const CoarseOptions& other) const;
};

}  // namespace lookup::coarse

#pragma once
// Options of the coarse stage: SeqSLAM-family whole-image sequence matching on the forward
// camera (Milford & Wyeth, ICRA 2012), the "coarse localisation unit" of the LookUP paper
// (Sec. III-D: its interface is the time stamp of the matched reference image).

#include <mrpt/config/CLoadableOptions.h>

#include <string>

namespace lookup::coarse {

/// Every parameter of descriptor extraction and sequence search. The paper's Table I has no
/// coarse-stage entries, so defaults follow SeqSLAM and were tuned on the lookup-sim presets.
/// Loaded strictly from an .ini section (default "coarse"); unknown keys are refused.
struct CoarseOptions : public mrpt::config::CLoadableOptions {
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

    // --- Odometry (optional) -------------------------------------------------------------------
    bool use_odometry = true;  ///< use travelled distance when the caller gives it and the
                               ///< references carry positions (replaces the speed range)
    double odometry_scale_tolerance = 0.15;  ///< odometry scale error hypotheses span
                                             ///< 1 +/- this [fraction]
    int odometry_scale_steps = 7;            ///< number of scale hypotheses

    void loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                            const std::string& section) override;
    void saveToConfigFile(mrpt::config::CConfigFileBase& target,
                          const std::string& section) const override;

    /// Throws common::ConfigError naming every field out of range ("coarse.<field> must be").
    void check() const;

    /// True when descriptors made with `other` can be compared with descriptors made with
    /// these options (same thumbnail and patch).
    bool sameDescriptor(const CoarseOptions& other) const;
};

}  // namespace lookup::coarse

#pragma once
// A camera's time offset against the laser / odometry pose track. A camera whose stamps are
// late or early puts every reference (speed x offset) along the track from where its image was
// taken. The offset shows where the motion changes (accelerating, braking, turning): for pairs
// of ceiling images `time_offset_baseline_m` apart, the vehicle's motion between the two is
// measured from the images alone (ceiling features tracked by pyramidal Lucas-Kanade,
// back-projected onto the ceiling plane at the survey's measured height, the planar motion
// between the two point sets fitted robustly) and compared with the pose track's motion
// between the two image times shifted by dt. The dt that fits best (least squares over the
// pairs, with a free scale absorbing an error of the ceiling height) is the offset; its
// standard deviation comes from the fit's curvature. At constant speed and heading the offset
// is not observable: the fit is flat, its deviation large, and the configured offset is kept
// with a warning.

#include <mrpt/obs/CObservationImage.h>

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

#include "lookup/survey/ceiling_distance.h"
#include "lookup/survey/survey_options.h"

namespace lookup::survey {

struct TimeOffsetEstimate {
    std::string label;                    ///< the camera's sensor label
    std::string source;                   ///< "estimated" or "configured"
    std::string method = "image motion";  ///< of the estimate: or "across traverses"
    double offset_s = 0;                  ///< applied: added to the camera's stamps [s]
    double configured_s = 0;              ///< the [survey] option [s]
    bool tried = false;                   ///< an estimate was attempted
    double fitted_s = 0;                  ///< the fit's total offset, used or not (when tried) [s]
    double sigma_s = 0;                   ///< its standard deviation (when tried) [s]
    /// The applied offset's standard deviation: the fit's when estimated, else the configured
    /// one's, or what the fit allows of the configured offset if tighter [s].
    double applied_sigma_s = 0;
    double scale = 1;                ///< fitted image-to-track scale (1 = ceiling height right)
    double rms_m = 0;                ///< residual of the used pairs at the fit [m]
    std::size_t pairs_tried = 0;     ///< image pairs measured
    std::size_t pairs_measured = 0;  ///< pairs with enough tracked ceiling points
    std::size_t pairs_used = 0;      ///< measured pairs inside the outlier gate
    std::string warning;             ///< why the configured offset is used ("" = estimated)
    /// The refused fit contradicts the configured offset (SurveyOptions::
    /// time_offset_contradiction_s): applied_sigma_s was widened to cover the fit.
    bool contradicted = false;
    double time_s = 0;  ///< wall time [s]
};

/// Estimates the ceiling camera's offset from the traverses' images, whose stamps already carry
/// the configured [survey] ceiling_time_offset_s, and pose tracks; `ceiling_height_m` is the
/// plane's height above the vehicle base. `offset_s` of the result is the total (configured +
/// what the images add), the configured one when not estimated (then `warning` says why).
/// Never throws for bad images: unreadable pairs count as not measured.
TimeOffsetEstimate estimateTimeOffset(const std::vector<CeilingTraverse>& traverses,
                                      double ceiling_height_m, const SurveyOptions& options);

struct PoseAudit;

/// The same offset from the pose audit's fixes across traverses (pose_audit.h), for when the
/// image motion does not pin it down. A frame refined against another traverse's images lands
/// where those images are placed: with stamps late by L (after `applied_s`, the offset the
/// stamps already carry) every reference sits speed x L along its own motion, so the fix lies
/// (v_other - v_own) x L from the frame's laser pose. Observable where the traverses' velocities
/// differ: driven in opposite directions, at other speeds. `offset_s` of the result is the total
/// to apply (`applied_s` when not estimated; then `warning` says why).
TimeOffsetEstimate estimateTimeOffsetAcrossTraverses(const PoseAudit& audit,
                                                     const std::vector<CeilingTraverse>& traverses,
                                                     double applied_s,
                                                     const SurveyOptions& options);

/// Adds `offset_s` to every image's time stamp.
void shiftStamps(std::vector<mrpt::obs::CObservationImage::Ptr>& images, double offset_s);

/// survey_report.json's object for one camera.
nlohmann::ordered_json timeOffsetJson(const TimeOffsetEstimate& e);

}  // namespace lookup::survey

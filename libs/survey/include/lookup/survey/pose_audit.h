#pragma once
// The survey's check of its own laser poses by the ceiling images. Where two reference
// traverses passed under the same ceiling, an image of one, refined by the localiser's own
// refiner against the other's images placed by their laser poses, must land where its own laser
// pose puts it. A laser pose that ICP-SLAM or MCL got wrong (a featureless drive, an odometry
// dropout) would otherwise become references that give confident wrong fixes.
//
// Frames are sampled every pose_audit_spacing_m along each traverse. Each is refined against
// every other traverse whose cameras passed near its camera: first at its laser pose, and when
// that finds nothing, from poses shifted along its heading up to pose_audit_search_m (a
// tunnel's laser error runs along the drive). A sample agrees with a traverse when the fix lies
// within pose_audit_max_disagreement_m of its laser pose, and disagrees when a fix lies farther
// and no other shift explains the image nearly as well (a repeating ceiling is inconclusive).
// A sample that disagrees with some traverse and agrees with none is suspect: the survey keeps
// no reference between the audited samples on either side of it. With three traverses the
// wrong one is found; with two, both sides of a disagreement are dropped.

#include <nlohmann/json.hpp>

#include <mrpt/poses/CPose2D.h>

#include <optional>
#include <string>
#include <vector>

#include "lookup/survey/ceiling_distance.h"
#include "lookup/survey/survey_options.h"

namespace lookup::survey {

/// A stretch of one traverse whose laser poses the images contradict.
struct SuspectStretch {
    std::string traverse;  ///< its name
    double from_s = 0;     ///< no reference strictly between these times is kept [s]
    double to_s = 0;
    double sample_s = 0;        ///< the suspect sample's image time [s]
    double disagreement_m = 0;  ///< |fix - laser pose| of that sample [m]
    std::string against;        ///< the traverse whose images placed it there
    /// Non-zero when the whole traverse is suspect: this many comparisons, none agreeing
    /// (its poses put it where no other traverse's ceiling matches its images).
    std::size_t whole_traverse_compared = 0;
};

/// One frame's fix against another traverse's images: what the camera's time offset is fitted
/// from across traverses (time_offset.h).
struct AuditFix {
    std::string traverse;     ///< the frame's
    std::string other;        ///< the traverse whose images placed it
    double time_s = 0;        ///< the frame's image time [s]
    double other_time_s = 0;  ///< the other traverse's nearest image time [s]
    double dx_m = 0;          ///< fix - laser pose, map frame [m]
    double dy_m = 0;
};

struct PoseAudit {
    bool ran = false;
    std::string note;  ///< why nothing was audited (off, one traverse, no overlap); else empty
    std::size_t sampled = 0;       ///< frames sampled
    std::size_t compared = 0;      ///< (sample, other traverse) pairs whose cameras passed near
    std::size_t agreed = 0;        ///< pairs whose fix lies within the limit
    std::size_t disagreed = 0;     ///< pairs whose fix lies beyond it
    std::size_t inconclusive = 0;  ///< no fix, or a repeating ceiling's rival
    std::size_t suspect = 0;       ///< samples that disagree and agree with no traverse
    std::size_t traverses_discarded = 0;  ///< whole traverses whose ceiling matched nowhere
    double median_m = 0;                  ///< |fix - laser pose| over the agreeing pairs [m]
    double p95_m = 0;
    double max_agreed_m = 0;
    std::vector<SuspectStretch> stretches;
    std::vector<AuditFix> fixes;  ///< every agreeing or disagreeing comparison's fix
    double time_s = 0;

    /// Whether an image of traverse `traverse` at `time_s` lies in a suspect stretch.
    bool excludes(const std::string& traverse, double time_s) const;
};

/// Audits the laser poses of `traverses` (named uniquely) (options pose_audit_* of SurveyOptions)
/// at the database's ceiling height. Never throws for bad images: an unreadable one is
/// inconclusive.
PoseAudit auditLaserPoses(const std::vector<CeilingTraverse>& traverses, double ceiling_height_m,
                          const SurveyOptions& options);

/// Dead reckoning over a traverse's first metres may be off by this share of the travel (wheel
/// slip on a wet floor).
constexpr double kOdometrySlipShare = 0.25;

/// Where the ceiling puts a traverse tried at each of `trial_starts` (map poses of its vehicle at
/// the origin of `traverse.poses`, which are relative to it): its frames every
/// pose_audit_spacing_m within its first `travel_m`, each placed by the trial, refined against
/// `mapped`'s images near there, from that pose and shifted along the heading up to `reach_m`.
/// Per trial, the start the first fix implies when at least two samples found one and the later
/// ones agree within pose_audit_max_disagreement_m and the odometry's slip; else none. A trial
/// stops once two fixes are out of reach, so a wrong place costs all but one sample's refinements.
std::vector<std::optional<mrpt::poses::CPose2D>> startsFromCeiling(
    const CeilingTraverse& traverse, const std::vector<mrpt::poses::CPose2D>& trial_starts,
    const CeilingTraverse& mapped, double ceiling_height_m, double travel_m, double reach_m,
    const SurveyOptions& o);

/// survey_report.json's "pose_audit" object.
nlohmann::ordered_json poseAuditJson(const PoseAudit& a);

}  // namespace lookup::survey

#pragma once
// Where the ceiling changed, an operating drive's frames become references: the frames between
// two refined fixes are posed on the drive's odometry, run forward from one fix and back from
// the other and blended by travel, so both fixes are met. Shared by lookup-survey --refresh
// (after a drive) and the localiser's online refresh (during one); docs/survey.md, "Refreshing
// from an operating drive".

#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/poses/CPose2D.h>

#include <string>
#include <vector>

#include "lookup/common/options_table.h"

namespace lookup::database {

/// The refresh_* keys of [survey] and [localizer].
struct RefreshOptions {
    /// A stretch the localiser did not refine, between two refined fixes, shorter than this is
    /// a bad view (dust, blur, a pipe), not a changed ceiling: left alone [m].
    double min_stretch_m = 1.0;
    /// Longer stretches are not bridged: the odometry between the fixes drifts too far [m].
    double max_stretch_m = 40.0;
    /// The odometry run from one fix must meet the other within this plus 2 % of the stretch;
    /// otherwise a fix or the odometry is wrong and the stretch is left alone [m].
    double max_closure_m = 0.3;
    /// Odometry error per metre from the nearer fix: the bridged references' added sigma.
    double odometry_drift = 0.02;
    /// The drive's refined frames this far on each side of a stretch are added too, so that
    /// the changed ceiling's edges have references of today [m].
    double margin_m = 1.0;
    /// Survey references whose ceiling cameras stood this near a bridged reference's camera are
    /// superseded: their ceiling did not match the drive's [m].
    double supersede_radius_m = 2.0;

    void declareKeys(common::OptionsTable& t);
};

/// A frame of the drive: the odometry's pose and path length at its time, and for the two
/// fixes that bound a stretch their refined pose and covariance (x, y, yaw).
struct DriveFramePose {
    mrpt::poses::CPose2D odometry;
    double travelled_m = 0;
    mrpt::poses::CPose2D pose;
    mrpt::math::CMatrixDouble33 cov = mrpt::math::CMatrixDouble33::Zero();
};

/// The frames strictly between two fixes, posed.
struct Bridge {
    double length_m = 0;   ///< odometry travel from fix to fix
    double closure_m = 0;  ///< how far the odometry from the first fix misses the second
    std::string refused;   ///< why the stretch is left alone ("" = bridged)
    std::vector<mrpt::poses::CPose2D> poses;        ///< one per frame between
    std::vector<mrpt::math::CMatrixDouble33> covs;  ///< the fix's plus drift and closure
};

/// Poses `between` (in drive order) from the fixes `a` before and `b` after them. Refused when
/// the stretch is longer than max_stretch_m or the odometry does not join the fixes.
Bridge bridgeStretch(const DriveFramePose& a, const DriveFramePose& b,
                     const std::vector<DriveFramePose>& between, const RefreshOptions& o);

}  // namespace lookup::database

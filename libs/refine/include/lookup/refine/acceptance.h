#pragma once
// The one acceptance policy (paper Sec. III-E) and the uncertainty of every pose that is not a
// fix: when the Refiner accepts a refined pose, the covariance it reports with a coarse or
// reference pose instead, and the one the localiser reports with a pose dead-reckoned from its
// last fix. All of it is read from `[refine.acceptance]`.

#include <mrpt/poses/CPose2D.h>
#include <mrpt/poses/CPosePDFGaussian.h>

#include <optional>
#include <string>

#include "lookup/refine/options.h"
#include "lookup/refine/types.h"

namespace lookup::refine {

/// What a pose dead-reckoned from the last fix rests on.
struct DeadReckoning {
    double travelled_m = 0;      ///< odometry distance since the fix (extrapolation included)
    double extrapolated_s = 0;   ///< time not covered by odometry readings
    bool velocity_known = true;  ///< false: no odometry at all, the vehicle's motion unknown
    /// An odometry pose interpolated inside a dropout lies on the straight line between the
    /// readings around it: through a turn its heading is off by about the turn between them
    /// times its share s of the dropout from the nearer reading [rad], its place by the arc's
    /// sagitta there, s (1 - s) / 2 times that turn times the distance between them [m]; the
    /// heading error turns all the travel after it.
    double dropout_yaw_rad = 0;
    double dropout_xy_m = 0;
};

class AcceptancePolicy {
  public:
    struct Rejection {
        RefineStatus status;  ///< LowInlierShare or OffsetTooLarge
        std::string reason;   ///< "(share 0.30 < N_th 0.45)", "refined pose is ... (d_th ...)"
    };

    /// Throws common::ConfigError when the options are invalid.
    explicit AcceptancePolicy(AcceptanceOptions options = {});

    /// nullopt when a refined pose with this inlier share and this offset from the coarse pose
    /// (`from_coarse`) or from the nearest reference is accepted; `tracked`: the coarse pose is
    /// the track's prediction.
    std::optional<Rejection> judge(double inlier_share, double offset_m, bool from_coarse,
                                   bool tracked = false) const;

    /// A coarse or reference pose reported in place of a fix.
    mrpt::poses::CPosePDFGaussian fallback(const mrpt::poses::CPose2D& pose) const;

    /// A pose dead-reckoned from the last fix: the uncertainty grows by a share of the
    /// distance, and with the time that odometry did not cover.
    mrpt::poses::CPosePDFGaussian deadReckoned(const mrpt::poses::CPose2D& pose,
                                               const DeadReckoning& d) const;
    /// The part of deadReckoned's position sigma that the time without odometry adds [m].
    double extrapolationSigmaXy(const DeadReckoning& d) const;

    const AcceptanceOptions& options() const { return options_; }

  private:
    AcceptanceOptions options_;
};

}  // namespace lookup::refine

#include "lookup/refine/acceptance.h"

#include <mrpt/core/bits_math.h>

#include <algorithm>

namespace lookup::refine {
namespace {

mrpt::poses::CPosePDFGaussian gaussian(const mrpt::poses::CPose2D& mean, double sigma_xy_m,
                                       double sigma_yaw_deg) {
    mrpt::math::CMatrixDouble33 cov;
    cov.setZero();
    cov(0, 0) = cov(1, 1) = sigma_xy_m * sigma_xy_m;
    const double yaw = mrpt::DEG2RAD(sigma_yaw_deg);
    cov(2, 2) = yaw * yaw;
    return mrpt::poses::CPosePDFGaussian(mean, cov);
}

}  // namespace

AcceptancePolicy::AcceptancePolicy(AcceptanceOptions options) : options_(std::move(options)) {
    options_.check();
}

std::optional<AcceptancePolicy::Rejection> AcceptancePolicy::judge(double inlier_share,
                                                                   double offset_m,
                                                                   bool from_coarse,
                                                                   bool tracked) const {
    const double min_share =
        tracked ? std::min(options_.min_inlier_share_tracked, options_.min_inlier_share)
                : options_.min_inlier_share;
    if (inlier_share < min_share) {
        return Rejection{RefineStatus::LowInlierShare, " (share " + std::to_string(inlier_share) +
                                                           " < N_th " + std::to_string(min_share) +
                                                           (tracked ? ", tracked)" : ")")};
    }
    if (offset_m > options_.max_offset_m) {
        return Rejection{RefineStatus::OffsetTooLarge,
                         "refined pose is " + std::to_string(offset_m) + " m from the " +
                             (from_coarse ? "coarse pose" : "nearest reference") + " (d_th " +
                             std::to_string(options_.max_offset_m) + " m)"};
    }
    return std::nullopt;
}

mrpt::poses::CPosePDFGaussian AcceptancePolicy::fallback(const mrpt::poses::CPose2D& pose) const {
    return gaussian(pose, options_.fallback_sigma_xy_m, options_.fallback_sigma_yaw_deg);
}

double AcceptancePolicy::extrapolationSigmaXy(const DeadReckoning& d) const {
    const double t = d.extrapolated_s;
    return d.velocity_known ? 0.5 * options_.extrapolation_accel_mps2 * t * t
                            : options_.unknown_motion_speed_mps * t;
}

mrpt::poses::CPosePDFGaussian AcceptancePolicy::deadReckoned(const mrpt::poses::CPose2D& pose,
                                                             const DeadReckoning& d) const {
    const AcceptanceOptions& o = options_;
    const double t = d.extrapolated_s;
    const double yaw_extrapolation = d.velocity_known
                                         ? 0.5 * o.extrapolation_yaw_accel_deg_s2 * t * t
                                         : o.unknown_motion_yaw_rate_deg_s * t;
    const double dropout_xy = d.dropout_xy_m + d.dropout_yaw_rad * d.travelled_m;
    return gaussian(pose,
                    o.dead_reckoning_sigma_xy_m + o.dead_reckoning_sigma_xy_per_m * d.travelled_m +
                        extrapolationSigmaXy(d) + dropout_xy,
                    o.dead_reckoning_sigma_yaw_deg +
                        o.dead_reckoning_sigma_yaw_deg_per_m * d.travelled_m + yaw_extrapolation +
                        mrpt::RAD2DEG(d.dropout_yaw_rad));
}

}  // namespace lookup::refine

#include "lookup/database/refresh_bridge.h"

#include <mrpt/math/wrap2pi.h>

#include <algorithm>

namespace lookup::database {

void RefreshOptions::declareKeys(common::OptionsTable& t) {
    t.add("refresh_min_stretch_m", min_stretch_m, 0.0);
    t.add("refresh_max_stretch_m", max_stretch_m, common::kPositive);
    t.add("refresh_max_closure_m", max_closure_m, common::kPositive);
    t.add("refresh_odometry_drift", odometry_drift, 0.0, 1.0);
    t.add("refresh_margin_m", margin_m, 0.0, 50.0);
    t.add("refresh_supersede_radius_m", supersede_radius_m, 0.0, 50.0);
}

Bridge bridgeStretch(const DriveFramePose& a, const DriveFramePose& b,
                     const std::vector<DriveFramePose>& between, const RefreshOptions& o) {
    Bridge s;
    s.length_m = b.travelled_m - a.travelled_m;
    if (s.length_m > o.max_stretch_m) {
        s.refused = "longer than refresh_max_stretch_m";
        return s;
    }
    const auto forward = [&](const DriveFramePose& f) {
        return a.pose + (f.odometry - a.odometry);
    };
    const auto backward = [&](const DriveFramePose& f) {
        return b.pose + (f.odometry - b.odometry);
    };
    const mrpt::poses::CPose2D arrived = forward(b);
    s.closure_m = arrived.distanceTo(b.pose);
    const double closure_yaw = mrpt::math::wrapToPi(arrived.phi() - b.pose.phi());
    if (s.closure_m > o.max_closure_m + 0.02 * s.length_m) {
        s.refused =
            "the odometry from one fix misses the other by " + std::to_string(s.closure_m) + " m";
        return s;
    }
    for (const auto& f : between) {
        const double from_a = f.travelled_m - a.travelled_m;
        const double w = s.length_m > 0 ? std::clamp(from_a / s.length_m, 0.0, 1.0) : 0.5;
        const auto p = forward(f), q = backward(f);
        s.poses.emplace_back((1 - w) * p.x() + w * q.x(), (1 - w) * p.y() + w * q.y(),
                             p.phi() + w * mrpt::math::wrapToPi(q.phi() - p.phi()));
        const double drift = o.odometry_drift * std::min(from_a, s.length_m - from_a);
        auto cov = w < 0.5 ? a.cov : b.cov;
        cov(0, 0) += drift * drift + 0.25 * s.closure_m * s.closure_m;
        cov(1, 1) += drift * drift + 0.25 * s.closure_m * s.closure_m;
        cov(2, 2) += 0.25 * closure_yaw * closure_yaw;
        s.covs.push_back(cov);
    }
    return s;
}

}  // namespace lookup::database

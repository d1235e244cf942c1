#include "lookup/common/odometry_track.h"

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <iterator>

namespace lookup::common {
namespace {

/// `p0 + a · (p1 - p0)` in p0's frame: a fraction (or, past p1, a multiple) of one motion.
mrpt::poses::CPose2D along(const mrpt::poses::CPose2D& p0, const mrpt::poses::CPose2D& p1,
                           double a) {
    const mrpt::poses::CPose2D d = p1 - p0;
    return p0 + mrpt::poses::CPose2D(a * d.x(), a * d.y(), a * d.phi());
}

/// V(phi) of the planar exponential map: a twist (u, phi) moves the origin to V(phi) u.
Eigen::Matrix2d twistMatrix(double phi) {
    const bool small = std::abs(phi) < 1e-6;
    const double s = small ? 1 - phi * phi / 6 : std::sin(phi) / phi;
    const double c = small ? phi / 2 : (1 - std::cos(phi)) / phi;
    Eigen::Matrix2d v;
    v << s, -c, c, s;
    return v;
}

/// `a` times the constant twist that moves p0 to p1 (a turning vehicle keeps turning).
mrpt::poses::CPose2D repeated(const mrpt::poses::CPose2D& p0, const mrpt::poses::CPose2D& p1,
                              double a) {
    const mrpt::poses::CPose2D d = p1 - p0;
    const Eigen::Vector2d u = twistMatrix(d.phi()).inverse() * Eigen::Vector2d(d.x(), d.y());
    const Eigen::Vector2d moved = twistMatrix(a * d.phi()) * (a * u);
    return p0 + mrpt::poses::CPose2D(moved.x(), moved.y(), a * d.phi());
}

}  // namespace

bool OdometryTrack::add(double time_s, const mrpt::poses::CPose2D& pose) {
    if (!readings_.empty() && !(time_s > readings_.back().first)) return false;
    readings_.emplace_back(time_s, pose);
    return true;
}

std::optional<OdometryTrack::Pose> OdometryTrack::at(double t, double max_extrapolation_s) const {
    if (readings_.empty() || t < readings_.front().first ||
        t > readings_.back().first + max_extrapolation_s) {
        return std::nullopt;
    }
    if (t > readings_.back().first) return extrapolated(t);
    const auto it = std::lower_bound(readings_.begin(), readings_.end(), t,
                                     [](const auto& e, double v) { return e.first < v; });
    if (it == readings_.begin()) return Pose{it->second};
    const auto& [t1, p1] = *it;
    const auto& [t0, p0] = *std::prev(it);
    const mrpt::poses::CPose2D d = p1 - p0;
    return Pose{along(p0, p1, (t - t0) / (t1 - t0)),
                0,
                t1 - t0,
                std::min(t - t0, t1 - t),
                std::abs(d.phi()),
                d.norm()};
}

OdometryTrack::Pose OdometryTrack::extrapolated(double t) const {
    // Holding the last pose instead would leave the vehicle behind by all it drove since.
    const auto& [t1, p1] = readings_.back();
    auto first = readings_.rbegin();
    while (std::next(first) != readings_.rend() && t1 - first->first < kVelocitySpanS) ++first;
    if (!(first->first < t1)) return Pose{p1, t - t1};
    return Pose{repeated(first->second, p1, (t - first->first) / (t1 - first->first)), t - t1};
}

void OdometryTrack::forgetBefore(double time_s) {
    while (readings_.size() > 2 && readings_[1].first < time_s) readings_.pop_front();
}

double signedTravel(const mrpt::poses::CPose2D& from, const mrpt::poses::CPose2D& to) {
    const mrpt::poses::CPose2D step = to - from;  // in the frame of `from`
    const double d = step.norm();
    return step.x() < 0 ? -d : d;
}

}  // namespace lookup::common

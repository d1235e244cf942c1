#include "lookup/localize/camera_clock.h"

#include <mrpt/math/wrap2pi.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "robust_fit.h"

namespace lookup::localize {

namespace {
using detail::robustFit;
// The yaw rate is taken over the odometry's velocity span, centred on the fix.
constexpr double kRateHalfSpan_s = 0.5 * common::OdometryTrack::kVelocitySpanS;
// A reading gap longer than this (a dropout) leaves the heading between unknown.
constexpr double kMaxReadingGap_s = 0.1;
// A lateness widens the poses' covariance as soon as a few pairs show it significant; it is
// applied only once min_pairs pairs rest on it.
constexpr std::size_t kMinPairsToWiden = 10;
// The speed changes' fit only widens: it may speak from fewer pairs, as a vehicle starting
// from rest speeds up most in its first second.
constexpr std::size_t kMinSpeedPairs = 6;

}  // namespace

void CameraClock::addFix(double stamp_s, const mrpt::poses::CPose2D& pose) {
    if (!options_.enabled || !std::isfinite(stamp_s) ||
        !std::isfinite(pose.x() + pose.y() + pose.phi())) {
        return;
    }
    // Without odometry (none recorded, a dropout) fixes would wait here for ever. One still
    // waiting a pair's span later lies in a gap of the readings, which sampleAt() refuses.
    while (!pending_.empty() && stamp_s - pending_.front().first > options_.max_pair_s) {
        pending_.pop_front();
    }
    pending_.emplace_back(stamp_s, pose);
}

std::optional<CameraClock::Reading> CameraClock::readAt(double t,
                                                        const common::OdometryTrack& odometry) {
    const auto at = odometry.at(t), before = odometry.at(t - kRateHalfSpan_s),
               after = odometry.at(t + kRateHalfSpan_s);
    for (const auto& p : {at, before, after}) {
        if (!p || p->extrapolated_s > 0 || p->gap_s > kMaxReadingGap_s) return std::nullopt;
    }
    const double turned = mrpt::math::wrapToPi(after->pose.phi() - before->pose.phi());
    const double ahead = (after->pose - before->pose).x();  // signed: reversing is negative
    return Reading{at->pose, turned / (2 * kRateHalfSpan_s), ahead / (2 * kRateHalfSpan_s)};
}

std::optional<CameraClock::Sample> CameraClock::sampleAt(
    double t, const mrpt::poses::CPose2D& fix, double shift,
    const common::OdometryTrack& odometry) const {
    const auto at_stamp = readAt(t, odometry);
    const auto shifted = shift == 0 ? at_stamp : readAt(t + shift, odometry);
    if (!at_stamp || !shifted) return std::nullopt;
    return Sample{t, fix, *shifted, *at_stamp, shift};
}

double CameraClock::shift() const {
    // The fit at the stamps alone, never the shifted one: read around its own estimate, a fit
    // whose pairs show little of the offset returns the shift it was read at, however wrong.
    const auto& e = stamp_estimate_;
    if (!significant(e) || e->pairs < options_.min_pairs) return 0.0;
    return std::clamp(e->offset_s, -options_.max_offset_s, options_.max_offset_s);
}

void CameraClock::update(const common::OdometryTrack& odometry) {
    if (odometry.empty()) return;
    bool added = false;
    const double shift = this->shift();
    while (!pending_.empty() &&
           pending_.front().first + std::max(shift, 0.0) + kRateHalfSpan_s <= odometry.lastTime()) {
        const auto [t, fix] = pending_.front();
        pending_.pop_front();
        if (const auto s = sampleAt(t, fix, shift, odometry)) {
            addPair(*s);
            added = true;
        }
    }
    if (added) fit();
}

void CameraClock::addPair(const Sample& s) {
    while (!samples_.empty() && s.t - samples_.front().t > options_.max_pair_s) {
        samples_.pop_front();
    }
    // The newest earlier fix at least min_pair_s before: one pair per fix.
    for (auto it = samples_.rbegin(); it != samples_.rend(); ++it) {
        const double dt = s.t - it->t;
        if (dt < options_.min_pair_s) continue;
        const double fix_turn = mrpt::math::wrapToPi(s.fix.phi() - it->fix.phi());
        const auto turn = [](const Reading& a, const Reading& b) {
            return mrpt::math::wrapToPi(a.pose.phi() - b.pose.phi());
        };
        // Read at t + shift, a fix's heading less the odometry's is (offset - shift) x the yaw
        // rate: adding shift x rate brings every pair back to the offset itself. Likewise its
        // place, by (offset - shift) x the speed.
        const double shifted = s.shift * s.odo.rate - it->shift * it->odo.rate;
        // Both travels along the vehicle's heading at the earlier fix, each in its own frame.
        const double fix_travel = (s.fix - it->fix).x();
        const double odo_travel = (s.odo.pose - it->odo.pose).x();
        const double shifted_travel = s.shift * s.odo.speed - it->shift * it->odo.speed;
        Pair p;
        p.residual = fix_turn - turn(s.odo, it->odo) + shifted;
        p.rate_change = -(s.odo.rate - it->odo.rate);
        p.stamp_residual = fix_turn - turn(s.at_stamp, it->at_stamp);
        p.stamp_rate_change = -(s.at_stamp.rate - it->at_stamp.rate);
        p.dt = dt;
        p.travel_residual = fix_travel - odo_travel + shifted_travel;
        p.speed_change = s.odo.speed - it->odo.speed;
        p.travel = odo_travel;
        pairs_.push_back(p);
        if (pairs_.size() > options_.max_pairs) pairs_.pop_front();
        break;
    }
    samples_.push_back(s);
}

void CameraClock::fit() {
    if (pairs_.size() >= kMinSpeedPairs) fitSpeedChanges();
    if (pairs_.size() < std::min(options_.min_pairs, kMinPairsToWiden)) return;
    // residual = tau x rate_change + drift x dt (the odometry's heading drift).
    const auto headingFit = [this](double Pair::*rate_change,
                                   double Pair::*residual) -> std::optional<Estimate> {
        const auto tau = robustFit(
            pairs_, [&](const Pair& p) { return p.*rate_change; },
            [](const Pair& p) { return p.dt; }, [&](const Pair& p) { return p.*residual; });
        if (!tau) return std::nullopt;  // the yaw rate never changed: nothing to see
        return Estimate{-tau->slope, tau->sigma, pairs_.size()};
    };
    if (auto at_stamps = headingFit(&Pair::stamp_rate_change, &Pair::stamp_residual)) {
        stamp_estimate_ = at_stamps;
    }
    const auto shifted = headingFit(&Pair::rate_change, &Pair::residual);
    if (!shifted) return;
    estimate_ = withCarried(*shifted);
    if (pairs_.size() >= options_.min_pairs) consider(*estimate_);
}

void CameraClock::fitSpeedChanges() {
    // travel_residual = offset x speed_change + scale x travel (the odometry's scale error).
    const auto offset = robustFit(
        pairs_, [](const Pair& p) { return p.speed_change; },
        [](const Pair& p) { return p.travel; }, [](const Pair& p) { return p.travel_residual; });
    if (offset) speed_estimate_ = Estimate{offset->slope, offset->sigma, pairs_.size()};
}

void CameraClock::carry(const Estimate& earlier) {
    if (!options_.enabled || !(earlier.sigma_s > 0) || !std::isfinite(earlier.offset_s)) return;
    carried_ = earlier;
    carried_dropped_ = false;
    estimate_ = earlier;
    consider(earlier);
}

CameraClock::Estimate CameraClock::withCarried(const Estimate& fitted) {
    if (!carried_) return fitted;
    const Estimate& c = *carried_;
    const double apart = std::abs(fitted.offset_s - c.offset_s);
    if (fitted.sigma_s <= options_.max_sigma_s &&
        apart > options_.significance * std::hypot(fitted.sigma_s, c.sigma_s)) {
        carried_.reset();
        carried_dropped_ = true;
        return fitted;
    }
    const double wf = 1 / (fitted.sigma_s * fitted.sigma_s), wc = 1 / (c.sigma_s * c.sigma_s);
    return {(wf * fitted.offset_s + wc * c.offset_s) / (wf + wc), 1 / std::sqrt(wf + wc),
            fitted.pairs + c.pairs};
}

void CameraClock::consider(const Estimate& e) {
    // Against a contaminated estimate (an uncalibrated survey's lateness in it) the estimate
    // must stand out of the contamination, whose size its sigma then carries. And only a
    // camera later than the odometry is corrected there: stamped on one host clock every
    // sensor is late, so an odometry later than the camera is the odometry's own lateness,
    // which the camera's stamp does not share (it stays in the covariance, unapplied).
    const double sigma = std::hypot(e.sigma_s, options_.contamination_s);
    const bool contaminated = options_.contamination_s > 0;
    const bool precise =
        e.sigma_s <= std::max(options_.max_sigma_s, options_.contamination_s) &&
        std::abs(e.offset_s) <= options_.max_offset_s && !odometryLater(e) &&
        (!contaminated || std::abs(e.offset_s) >= options_.min_contaminated_offset_s);
    if (options_.apply && precise &&
        (applied_ || std::abs(e.offset_s) >= options_.significance * sigma)) {
        applied_ = Estimate{e.offset_s, sigma, e.pairs};
    }
}

double CameraClock::unappliedOffset() const {
    if (applied_) return 0.0;
    if (significant(estimate_)) return std::abs(estimate_->offset_s);
    return significant(speed_estimate_) ? std::abs(speed_estimate_->offset_s) : 0.0;
}

}  // namespace lookup::localize

#pragma once
// The ceiling camera's time offset against the odometry, estimated from the drive itself.
//
// A camera whose stamps are late by tau against the odometry shows, between two fixes, the
// heading change the odometry made tau earlier: the fixes' heading change minus the odometry's
// over the same stamps is -tau x the change of the yaw rate between them. A weave or a bend
// changes the yaw rate; a straight drive does not, and then nothing is estimated. Headings,
// not positions: wheel slip swamps the few centimetres a speed change would show, while the
// odometry's heading drifts slowly and the references' heading errors are nearly rigid, so
// both cancel in the differences over a second.
//
// A speed change shows it too: between two fixes the fixes' travel less the odometry's is
// -tau x the change of speed. Wheel slip and the odometry's scale error blur it, so it only
// widens the poses' covariance where it stands significant and the heading's estimate does not
// yet (a camera buffering frames while the vehicle accelerates from rest, before any bend);
// it is never applied.
//
// Only the offset against the odometry is observable; a latency common to every sensor of the
// vehicle is not (docs/vehicle.md, "Time offset"). Estimated on every run and reported;
// applied to the stamps where LocalizerOptions::apply_camera_time_offset says. An estimate
// carried from the vehicle's earlier runs (carry()) is where a run starts: a straight drive,
// which shows nothing of its own, keeps it, and a weave refines it.

#include <deque>
#include <optional>

#include "lookup/common/odometry_track.h"

namespace lookup::localize {

struct CameraClockOptions {
    bool enabled = true;  ///< estimate (and report)
    bool apply = false;   ///< also apply it to the stamps (LocalizerOptions: when)
    /// Two fixes are paired when this far apart in time: long enough for the yaw rate to
    /// change, short enough for the odometry's heading drift to stay small [s].
    double min_pair_s = 0.3, max_pair_s = 1.0;
    std::size_t min_pairs = 50;    ///< before anything is estimated
    std::size_t max_pairs = 1000;  ///< the newest kept (the offset is the vehicle's, fixed)
    double max_sigma_s = 0.005;    ///< an estimate more uncertain is not applied [s]
    double significance = 3.0;     ///< nor one within this many sigmas of zero
    double max_offset_s = 1.0;     ///< nor one larger (a broken clock, not an offset) [s]
    /// A lateness the estimate may hold that is not the camera's own: an uncalibrated survey
    /// camera's, which its references' headings carry through every bend [s]. An estimate is
    /// then applied only when it stands `significance` sigmas out of it, with it in its sigma.
    double contamination_s = 0;
    /// Nor, against such an estimate, one smaller than this, or one that says the camera is
    /// earlier than the odometry (that is the odometry's own lateness, which the camera's stamp
    /// does not carry): on straight and reversing drives the estimate itself strays by tens of
    /// ms, where the partial cancellation of the two lateness serves better; a camera
    /// buffering frames is later than this [s].
    double min_contaminated_offset_s = 0.1;
};

class CameraClock {
  public:
    struct Estimate {
        double offset_s = 0;  ///< to add to the camera's stamps (a late camera: negative) [s]
        double sigma_s = 0;   ///< its standard deviation (residual scatter, formal) [s]
        std::size_t pairs = 0;
    };

    explicit CameraClock(const CameraClockOptions& options = {}) : options_(options) {}

    /// The offset as earlier runs of the same camera left it: the estimate from the start (and
    /// applied as a fit would be); this run's pairs are then weighed with it by their
    /// variances. Dropped (carriedDropped()) when this run's own precise fit lies more than
    /// `significance` sigmas of the two away from it: the camera's clock has changed.
    void carry(const Estimate& earlier);
    const std::optional<Estimate>& carried() const { return carried_; }
    bool carriedDropped() const { return carried_dropped_; }

    /// A refined frame: its stamp as the camera gave it (before applied()) and its pose.
    void addFix(double stamp_s, const mrpt::poses::CPose2D& pose);
    /// Starts again from nothing (fixes, estimates, what was applied or carried): the fixes so
    /// far were made under another model of the image's time (a readout applied since).
    void forget() { *this = CameraClock(options_); }
    /// Pairs the fixes the odometry now covers (it must reach a little past them for the yaw
    /// rate) and refits; then, with CameraClockOptions::apply, applies the fit when it is
    /// precise and significant, or follows it once applied.
    void update(const common::OdometryTrack& odometry);

    /// The latest fit (from a few pairs on; applied from min_pairs on).
    const std::optional<Estimate>& estimate() const { return estimate_; }
    /// The latest fit of the fixes' travel against the odometry's over speed changes (never
    /// applied; its sigma is the scatter's, which wheel slip widens).
    const std::optional<Estimate>& speedEstimate() const { return speed_estimate_; }
    /// The offset the localiser adds to the camera's stamps now (0 until one is applied) [s].
    double applied() const { return applied_ ? applied_->offset_s : 0.0; }
    double appliedSigma() const { return applied_ ? applied_->sigma_s : 0.0; }
    bool isApplied() const { return applied_.has_value(); }
    /// A significant estimate that is not applied (0 if none or applied): the lateness left in
    /// the stamps, which every pose's covariance must then carry [s]. The heading's estimate,
    /// or the speed changes' where the heading's is not significant.
    double unappliedOffset() const;
    /// Whether that unapplied estimate is held back for saying the odometry is the later (only
    /// against a contaminated estimate: min_contaminated_offset_s).
    bool unappliedAsOdometryLateness() const {
        return !applied_ && significant(estimate_) && odometryLater(*estimate_);
    }
    /// The lateness the estimate may hold that is not the camera's own (options) [s].
    double contamination() const { return options_.contamination_s; }
    /// Whether an estimate will be applied once precise and significant.
    bool applies() const { return options_.enabled && options_.apply; }

  private:
    /// The odometry's pose, yaw rate and speed (signed, along its heading) at one time.
    struct Reading {
        mrpt::poses::CPose2D pose;
        double rate = 0, speed = 0;
    };
    /// A fix with the odometry read at its stamp plus the shift, and at its stamp.
    struct Sample {
        double t = 0;
        mrpt::poses::CPose2D fix;
        Reading odo, at_stamp;
        double shift = 0;  ///< the odometry read at t + shift (the estimate then)
    };
    /// Fixes' heading change minus the odometry's, against minus the change of yaw rate; and
    /// the fixes' travel along the first fix's heading minus the odometry's, against the
    /// change of speed and the odometry's travel (its scale error).
    struct Pair {
        double residual = 0, rate_change = 0, dt = 0;
        double stamp_residual = 0, stamp_rate_change = 0;  ///< the same read at the stamps
        double travel_residual = 0, speed_change = 0, travel = 0;
    };
    static std::optional<Reading> readAt(double t, const common::OdometryTrack& odometry);
    std::optional<Sample> sampleAt(double t, const mrpt::poses::CPose2D& fix, double shift,
                                   const common::OdometryTrack& odometry) const;
    /// Where the odometry is read for a fix: at its stamp plus the latest estimate of the fit
    /// at the stamps where that is significant, so that a large offset is measured as a small
    /// one around it.
    double shift() const;
    /// `e` exists and stands `significance` sigmas out of zero.
    bool significant(const std::optional<Estimate>& e) const {
        return e && std::abs(e->offset_s) >= options_.significance * e->sigma_s;
    }
    /// Against a contaminated estimate, `e` says the odometry is later than the camera: the
    /// odometry's own lateness, not corrected on the camera's stamps.
    bool odometryLater(const Estimate& e) const {
        return options_.contamination_s > 0 && e.offset_s > 0;
    }
    void addPair(const Sample& s);
    void fit();
    void fitSpeedChanges();
    /// This run's fit weighed with the carried estimate (or alone once that is dropped).
    Estimate withCarried(const Estimate& fitted);
    /// The latest estimate; applied when precise and significant, or followed once applied.
    void consider(const Estimate& e);

    CameraClockOptions options_;
    /// Fixes awaiting odometry (stamp, pose), the last max_pair_s of them.
    std::deque<std::pair<double, mrpt::poses::CPose2D>> pending_;
    std::deque<Sample> samples_;  ///< the last max_pair_s of fixes
    std::deque<Pair> pairs_;
    std::optional<Estimate> estimate_, applied_, carried_, speed_estimate_;
    std::optional<Estimate> stamp_estimate_;  ///< the heading's fit read at the stamps
    bool carried_dropped_ = false;
};

}  // namespace lookup::localize

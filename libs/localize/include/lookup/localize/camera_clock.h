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

    /// A refined frame: its stamp as the camera gave it (before applied()) and its heading.
    void addFix(double stamp_s, double yaw);
    /// Pairs the fixes the odometry now covers (it must reach a little past them for the yaw
    /// rate) and refits; then, with CameraClockOptions::apply, applies the fit when it is
    /// precise and significant, or follows it once applied.
    void update(const common::OdometryTrack& odometry);

    /// The latest fit (from a few pairs on; applied from min_pairs on).
    const std::optional<Estimate>& estimate() const { return estimate_; }
    /// The offset the localiser adds to the camera's stamps now (0 until one is applied) [s].
    double applied() const { return applied_ ? applied_->offset_s : 0.0; }
    double appliedSigma() const { return applied_ ? applied_->sigma_s : 0.0; }
    bool isApplied() const { return applied_.has_value(); }
    /// A significant estimate that is not applied (0 if none or applied): the lateness left in
    /// the stamps, which every pose's covariance must then carry [s].
    double unappliedOffset() const;
    /// Whether that unapplied estimate is held back for saying the odometry is the later (only
    /// against a contaminated estimate: min_contaminated_offset_s).
    bool unappliedAsOdometryLateness() const {
        return unappliedOffset() > 0 && odometryLater(*estimate_);
    }
    /// The lateness the estimate may hold that is not the camera's own (options) [s].
    double contamination() const { return options_.contamination_s; }
    /// Whether an estimate will be applied once precise and significant.
    bool applies() const { return options_.enabled && options_.apply; }

  private:
    /// A fix with the odometry's heading and yaw rate at its stamp.
    struct Sample {
        double t = 0, yaw = 0, odo_yaw = 0, odo_rate = 0;
        double shift = 0;  ///< the odometry read at t + shift (the estimate then)
    };
    /// Fixes' heading change minus the odometry's, against minus the change of yaw rate.
    struct Pair {
        double residual = 0, rate_change = 0, dt = 0;
    };
    std::optional<Sample> sampleAt(double t, double yaw, double shift,
                                   const common::OdometryTrack& odometry) const;
    /// Where the odometry is read for a fix: at its stamp plus the latest estimate, so that a
    /// large offset is measured as a small one around it.
    double shift() const;
    /// Against a contaminated estimate, `e` says the odometry is later than the camera: the
    /// odometry's own lateness, not corrected on the camera's stamps.
    bool odometryLater(const Estimate& e) const {
        return options_.contamination_s > 0 && e.offset_s > 0;
    }
    void addPair(const Sample& s);
    void fit();
    /// This run's fit weighed with the carried estimate (or alone once that is dropped).
    Estimate withCarried(const Estimate& fitted);
    /// The latest estimate; applied when precise and significant, or followed once applied.
    void consider(const Estimate& e);

    CameraClockOptions options_;
    /// Fixes awaiting odometry (stamp, yaw), the last max_pair_s of them.
    std::deque<std::pair<double, double>> pending_;
    std::deque<Sample> samples_;  ///< the last max_pair_s of fixes
    std::deque<Pair> pairs_;
    std::optional<Estimate> estimate_, applied_, carried_;
    bool carried_dropped_ = false;
};

}  // namespace lookup::localize

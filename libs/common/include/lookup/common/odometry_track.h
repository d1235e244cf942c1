#pragma once
// A vehicle's odometry as a motion: its pose at any time, interpolated between readings and,
// past the last one (a reading late against an image, a dropout), extrapolated at the velocity
// of the last readings.

#include <mrpt/poses/CPose2D.h>

#include <deque>
#include <optional>
#include <utility>

namespace lookup::common {

class OdometryTrack {
  public:
    /// Velocities are taken over readings spanning at least this long: a single step's
    /// time-stamp jitter would dominate them [s].
    static constexpr double kVelocitySpanS = 0.1;

    struct Pose {
        mrpt::poses::CPose2D pose;
        double extrapolated_s = 0;  ///< time past the last reading (0: between readings)
        /// Between readings: their spacing, and the time to the nearer of them (a dropout's
        /// readings bracket a motion of which only the end points are known) [s].
        double gap_s = 0, inside_gap_s = 0;
        /// Between readings: the turn [rad] and the distance [m] from one to the other.
        double gap_turn_rad = 0, gap_distance_m = 0;
    };

    /// Appends a reading; false (and ignored) when it is not later than the last one.
    bool add(double time_s, const mrpt::poses::CPose2D& pose);
    /// The pose at `time_s`; nullopt before the first reading, or more than
    /// `max_extrapolation_s` past the last one.
    std::optional<Pose> at(double time_s, double max_extrapolation_s = 0) const;
    /// Forgets readings before `time_s`, keeping the one before it that interpolation needs.
    void forgetBefore(double time_s);
    void clear() { readings_.clear(); }

    bool empty() const { return readings_.empty(); }
    std::size_t size() const { return readings_.size(); }
    double lastTime() const { return readings_.back().first; }
    const mrpt::poses::CPose2D& lastPose() const { return readings_.back().second; }

  private:
    Pose extrapolated(double time_s) const;

    std::deque<std::pair<double, mrpt::poses::CPose2D>> readings_;
};

/// The distance from odometry pose `from` to `to` [m], negative when the vehicle moved backwards
/// (along -x of `from`).
double signedTravel(const mrpt::poses::CPose2D& from, const mrpt::poses::CPose2D& to);

}  // namespace lookup::common

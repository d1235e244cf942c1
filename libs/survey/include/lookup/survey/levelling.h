#pragma once
// A survey on a grade. Wheel odometry rolls the distance along the slope and a 2-D scanner
// tilted with the vehicle cuts the tunnel in a tilted plane: both see 1 / cos(pitch) more than
// the plan distance (1.0 % on a 1:7 decline), every registration agrees on it, and the laser
// map comes out stretched along the ramp. With an inclinometer (the vehicle IMU's pitch and
// roll against gravity, CObservationIMU) each odometry step and each scan is projected onto
// the horizontal before the laser stage sees it.

#include <optional>
#include <string>
#include <vector>

namespace lookup::survey {

struct TraverseData;

/// The vehicle's pitch and roll (MRPT's convention: positive pitch lowers the nose) [rad].
struct Attitude {
    double pitch = 0, roll = 0;
};

/// Inclinometer readings by time, interpolated linearly.
class AttitudeTrack {
  public:
    /// Appends a reading; false (and ignored) when it is not later than the last one.
    bool add(double time_s, const Attitude& a);
    /// The attitude at `time_s`; nullopt outside the readings or across a gap over `max_gap_s`.
    std::optional<Attitude> at(double time_s, double max_gap_s) const;
    double maxAbsPitch() const;  ///< largest |pitch| read [rad]
    bool empty() const { return time_.empty(); }
    std::size_t size() const { return time_.size(); }

  private:
    std::vector<double> time_;
    std::vector<Attitude> attitude_;
};

/// What levelling did to one traverse, for survey_report.json.
struct LevellingReport {
    std::size_t imu_records = 0;        ///< inclinometer readings in the rawlog
    std::size_t scans_levelled = 0;     ///< scans projected onto the horizontal
    std::size_t odometry_levelled = 0;  ///< odometry steps projected onto the horizontal
    double max_pitch_deg = 0;           ///< largest |pitch| read
    double odometry_m = 0;              ///< odometry distance as recorded [m]
    double levelled_m = 0;              ///< ... after projection (plan distance) [m]
    std::size_t floor_returns = 0;      ///< lidar returns from the floor ahead, dropped
    std::size_t roof_returns = 0;       ///< ... from the roof ahead, dropped
};

/// Projects `traverse`'s odometry steps and scans onto the horizontal with `attitude` (each at
/// its time; where the inclinometer has no reading within `max_gap_s` they stay as they are).
/// Scans are redrawn as by deskewScan, each ray rotated by the vehicle's attitude before its
/// plan position is taken. Where the grade changes, the tilted scan plane meets the floor (at
/// the foot of a decline) or the roof (past the crest of an incline) ahead and draws a wall
/// across the tunnel: returns less than `floor_margin_m` above the floor where they lie (the
/// vehicle's own ground heights along its drive, from the odometry and the pitch; 0 = keep
/// them), or more than `roof_margin_m` above the scanner's own height over the floor (0 = keep
/// them), are dropped first.
LevellingReport levelTraverse(TraverseData& traverse, const AttitudeTrack& attitude,
                              double max_gap_s, double floor_margin_m, double roof_margin_m);

}  // namespace lookup::survey

#pragma once
// Pose trajectories as text: MRPT's ground-truth form (`t x y z yaw pitch roll`, 7 columns,
// angles in radians, as pf-localization and the rawlog simulators use) and TUM
// (`t x y z qx qy qz qw`, 8 columns). Readers detect the form from the column count.

#include <mrpt/poses/CPose3D.h>
#include <mrpt/poses/CPose3DInterpolator.h>

#include <string>
#include <vector>

namespace lookup::common {

struct StampedPose {
    double time_s = 0;          ///< seconds (UNIX epoch, as mrpt::Clock::toDouble)
    mrpt::poses::CPose3D pose;  ///< pose in the map frame
};
using PoseTrack = std::vector<StampedPose>;

/// Reads a 7-column MRPT or 8-column TUM file ('#' comments and blank lines skipped). Throws
/// ConfigError naming the file and line for a malformed row, mixed forms or decreasing times.
PoseTrack readPoseFile(const std::string& path);

/// Writes `t x y z yaw pitch roll` rows (MRPT ground-truth form). Throws WriteError.
void writeMrptPoseFile(const std::string& path, const PoseTrack& track);

/// Writes TUM rows `t x y z qx qy qz qw`. Throws WriteError.
void writeTumPoseFile(const std::string& path, const PoseTrack& track);

/// An MRPT interpolator over the track (linear position, slerp rotation) that refuses to
/// interpolate across gaps longer than `max_gap_s`.
mrpt::poses::CPose3DInterpolator makeInterpolator(const PoseTrack& track, double max_gap_s);

}  // namespace lookup::common

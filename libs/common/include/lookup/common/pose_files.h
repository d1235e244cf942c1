#pragma once
// Pose trajectories as text: MRPT's ground-truth form (`t x y z yaw pitch roll`, 7 columns,
// angles in radians, as pf-localization and the rawlog simulators use) and TUM
// (`t x y z qx qy qz qw`, 8 columns). Readers detect the form from the column count.

#include <mrpt/poses/CPose3D.h>
#include <mrpt/poses/CPose3DInterpolator.h>

#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace lookup::common {

/// A pose file that cannot be read or holds a bad row: bad input data (exit code 2), the
/// message names the file and line.
class PoseFileError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

struct StampedPose {
    double time_s = 0;          ///< seconds (UNIX epoch, as mrpt::Clock::toDouble)
    mrpt::poses::CPose3D pose;  ///< pose in the map frame
};
using PoseTrack = std::vector<StampedPose>;

/// Reads a 7-column MRPT or 8-column TUM file ('#' comments and blank lines skipped); TUM
/// quaternions are normalised. Throws PoseFileError naming the file and line for a malformed
/// or non-finite row, a time or coordinate out of range, mixed forms or decreasing times.
PoseTrack readPoseFile(const std::string& path);

/// Writes `t x y z yaw pitch roll` rows (MRPT ground-truth form). Throws WriteError.
void writeMrptPoseFile(const std::string& path, const PoseTrack& track);

/// Writes TUM rows `t x y z qx qy qz qw`. Throws WriteError.
void writeTumPoseFile(const std::string& path, const PoseTrack& track);

/// An MRPT interpolator over the track (linear position, slerp rotation) that refuses to
/// interpolate across gaps longer than `max_gap_s`.
mrpt::poses::CPose3DInterpolator makeInterpolator(const PoseTrack& track, double max_gap_s);

/// The interpolator's pose at `time_s`; nullopt outside its track or across a gap.
std::optional<mrpt::poses::CPose3D> poseAt(const mrpt::poses::CPose3DInterpolator& interp,
                                           double time_s);

}  // namespace lookup::common

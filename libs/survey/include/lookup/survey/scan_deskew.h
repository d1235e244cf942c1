#pragma once
// A spinning 2-D scanner takes its rays one after another over the sweep (a 270° aperture at
// 10 Hz: 75 ms), while the vehicle moves: at 5 m/s the last ray is taken 0.4 m further on than
// the first. Every scan here is redrawn as seen from the pose of its first ray (the ray its
// time stamp refers to), with the vehicle's motion over the sweep taken from odometry, before
// ICP-SLAM, the pose graph and the grid see it.

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/poses/CPose2D.h>

#include "lookup/survey/traverse.h"

namespace lookup::survey {

/// Redraws `scan` from the pose of its first ray, given the vehicle's pose at the last ray
/// relative to the first (`motion`, vehicle frame), interpolated linearly over the rays. Each
/// corrected point goes to the ray of its new bearing (the nearest return wins); rays left
/// without a point become invalid returns; points outside the aperture are dropped. A non-zero
/// `attitude` (the vehicle's pitch and roll during the scan) first rotates each ray's point to
/// the horizontal about the vehicle's origin, so the scan shows plan distances (levelling.h).
void deskewScan(mrpt::obs::CObservation2DRangeScan& scan, const mrpt::poses::CPose2D& motion,
                const Attitude& attitude = {});

/// De-skews every scan of `traverse` with a sweep of `sweep_s` from its first ray to its last,
/// the motion from the traverse's odometry interpolated at the two ray times. Scans that the
/// odometry does not bracket stay as they are; returns how many were corrected.
std::size_t deskewTraverse(TraverseData& traverse, double sweep_s);

}  // namespace lookup::survey

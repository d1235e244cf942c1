#pragma once
// Where a traverse starts in the survey's own map, without ground truth: the scans of its
// first metres (placed by odometry) are matched as one local cloud against the map's occupied
// cells with MRPT's ICP (mrpt::slam::CICP) from guesses along the mapping traverse (every few
// metres, both headings), and the guess with the best ICP goodness wins. A tunnel is
// self-similar along its axis: among near-equal goodness the guess closest to the mapping
// traverse's start (where survey traverses usually begin) is taken, unless the ceiling decides.
// The ceiling is distinct where the lidar is not: the traverse's first frames, placed at each
// tied fit, are refined against the mapping traverse's images there (startsFromCeiling), and a
// single place where they agree wins.

#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/poses/CPose2D.h>

#include <string>
#include <vector>

#include "lookup/common/pose_files.h"
#include "lookup/survey/ceiling_distance.h"
#include "lookup/survey/survey_options.h"
#include "lookup/survey/traverse.h"

namespace lookup::survey {

struct StartFix {
    mrpt::poses::CPose2D pose;  ///< vehicle pose at the traverse's first scan, grid frame
    double goodness = 0;        ///< CICP goodness of the winning match [0..1]
    std::size_t guesses = 0;    ///< initial guesses tried
    /// Fits as good as the winner's (within the tie margin) at other places, in guess order.
    std::vector<mrpt::poses::CPose2D> tied;
    /// What the ceiling made of the tie: "" (none, or not asked), "confirmed" (the winner),
    /// "placed" (moved to the one place the ceiling agrees with), "ambiguous" (several such
    /// places) or "no match" (none): in the last two, the winner stays.
    std::string ceiling;
};

/// Throws common::RawlogError naming the traverse when it has no scans or no guess reaches
/// SurveyOptions::start_min_goodness. `guesses_along` (grid frame) is the mapping traverse's
/// track; empty: `fallback` and its reverse are the only guesses.
StartFix findStartInMap(const TraverseData& traverse, const mrpt::maps::COccupancyGridMap2D& grid,
                        const common::PoseTrack& guesses_along,
                        const mrpt::poses::CPose2D& fallback, const SurveyOptions& options);

/// Decides a tie of `fix` (findStartInMap's, for `traverse`) by the ceiling: the traverse's
/// first start_match_travel_m of frames, placed by its odometry at the winner and then at each
/// tied fit, against `mapped` (the mapping traverse's frames, grid frame) at the ceiling height
/// `ceiling_height_m`. Sets StartFix::ceiling, and the pose when the ceiling places it.
void decideStartByCeiling(StartFix& fix, const TraverseData& traverse,
                          const CeilingTraverse& mapped, double ceiling_height_m,
                          const SurveyOptions& options);

}  // namespace lookup::survey

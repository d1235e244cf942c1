#include "lookup/survey/start_search.h"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/slam/CICP.h>

#include <cmath>
#include <cstdio>

#include "lookup/common/rawlog_io.h"

namespace lookup::survey {
namespace {

// The grid's occupied cells as points.
mrpt::maps::CSimplePointsMap occupiedCells(const mrpt::maps::COccupancyGridMap2D& grid) {
    mrpt::maps::CSimplePointsMap out;
    for (unsigned cy = 0; cy < grid.getSizeY(); ++cy) {
        for (unsigned cx = 0; cx < grid.getSizeX(); ++cx) {
            if (grid.getCell(cx, cy) < 0.35f) out.insertPoint(grid.idx2x(cx), grid.idx2y(cy), 0);
        }
    }
    return out;
}

// The scans of the first `travel_m` metres (by odometry) in the frame of the first scan's
// vehicle pose.
mrpt::maps::CSimplePointsMap firstScans(const TraverseData& t, double travel_m) {
    mrpt::maps::CSimplePointsMap out;
    out.insertionOptions.minDistBetweenLaserPoints = 0.05f;
    out.insertionOptions.isPlanarMap = true;
    mrpt::poses::CPose2D odometry, first;
    bool have_first = false;
    double travelled = 0;
    mrpt::poses::CPose2D last;
    for (const auto& o : t.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            odometry = odo->odometry;
            continue;
        }
        auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o);
        if (!scan) continue;
        if (!have_first) {
            first = last = odometry;
            have_first = true;
        }
        travelled += std::hypot(odometry.x() - last.x(), odometry.y() - last.y());
        last = odometry;
        const mrpt::poses::CPose3D rel(odometry - first);
        out.insertObservation(*scan, rel);
        if (travelled > travel_m) break;
    }
    return out;
}

std::vector<mrpt::poses::CPose2D> guessesFrom(const common::PoseTrack& track,
                                              const mrpt::poses::CPose2D& fallback,
                                              double spacing_m) {
    std::vector<mrpt::poses::CPose2D> out;
    const auto both = [&](const mrpt::poses::CPose2D& p) {
        out.push_back(p);
        out.emplace_back(p.x(), p.y(), mrpt::math::wrapToPi(p.phi() + M_PI));
    };
    if (track.empty()) {
        both(fallback);
        return out;
    }
    double since = spacing_m;
    for (std::size_t i = 0; i < track.size(); ++i) {
        if (i > 0) {
            since += std::hypot(track[i].pose.x() - track[i - 1].pose.x(),
                                track[i].pose.y() - track[i - 1].pose.y());
        }
        if (since < spacing_m) continue;
        since = 0;
        both(mrpt::poses::CPose2D(track[i].pose));
    }
    return out;
}

}  // namespace

StartFix findStartInMap(const TraverseData& traverse, const mrpt::maps::COccupancyGridMap2D& grid,
                        const common::PoseTrack& guesses_along,
                        const mrpt::poses::CPose2D& fallback, const SurveyOptions& options) {
    const auto local = firstScans(traverse, options.start_match_travel_m);
    if (local.size() < 20) {
        throw common::RawlogError(traverse.rawlog,
                                  "no lidar points to find this traverse's start in the map");
    }
    const auto map = occupiedCells(grid);
    mrpt::slam::CICP icp;
    icp.options.ICP_algorithm = mrpt::slam::icpClassic;
    icp.options.maxIterations = 60;
    icp.options.thresholdDist = 1.0;
    icp.options.thresholdAng = mrpt::DEG2RAD(10.0);
    icp.options.ALFA = 0.5;
    icp.options.smallestThresholdDist = 0.05;
    icp.options.onlyUniqueRobust = false;
    const auto guesses = guessesFrom(guesses_along, fallback, options.start_search_spacing_m);
    // Near-equal goodness (aliasing along a tunnel): the earliest guess wins.
    constexpr double kTie = 0.02;
    StartFix best;
    best.guesses = guesses.size();
    bool found = false;
    for (const auto& g : guesses) {
        mrpt::slam::CICP::TReturnInfo info;
        const auto pdf = icp.Align(&map, &local, g, info);
        if (!pdf) continue;
        if (!found || info.goodness > best.goodness + kTie) {
            best.pose = pdf->getMeanVal();
            best.goodness = info.goodness;
            found = true;
        }
    }
    if (!found || best.goodness < options.start_min_goodness) {
        char buf[200];
        std::snprintf(buf, sizeof(buf),
                      "start not found in the map: best ICP goodness %.2f of %zu guesses < "
                      "[survey] start_min_goodness %.2f",
                      best.goodness, guesses.size(), options.start_min_goodness);
        throw common::RawlogError(traverse.rawlog, buf);
    }
    return best;
}

}  // namespace lookup::survey

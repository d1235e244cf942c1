#include "lookup/survey/start_search.h"

#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/slam/CICP.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "lookup/common/rawlog_io.h"
#include "lookup/survey/pose_audit.h"

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

bool samePlace(const mrpt::poses::CPose2D& a, const mrpt::poses::CPose2D& b) {
    constexpr double kSamePlace_m = 0.3, kSameHeading_rad = 0.2;
    return a.distanceTo(b) < kSamePlace_m &&
           std::abs(mrpt::math::wrapToPi(a.phi() - b.phi())) < kSameHeading_rad;
}

bool isNewPlace(const mrpt::poses::CPose2D& p, const mrpt::poses::CPose2D& winner,
                const std::vector<mrpt::poses::CPose2D>& kept) {
    if (samePlace(p, winner)) return false;
    return std::none_of(kept.begin(), kept.end(),
                        [&](const mrpt::poses::CPose2D& k) { return samePlace(p, k); });
}

// The vehicle's odometry relative to its pose at the traverse's first scan (the start's
// origin), as a pose track.
common::PoseTrack odometryFromFirstScan(const TraverseData& t) {
    common::PoseTrack out;
    mrpt::poses::CPose2D odometry, first;
    bool have_odometry = false, have_first = false;
    for (const auto& o : t.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            odometry = odo->odometry;
            have_odometry = true;
            if (have_first) {
                out.push_back({mrpt::Clock::toDouble(odo->timestamp),
                               mrpt::poses::CPose3D(odometry - first)});
            }
            continue;
        }
        if (have_odometry && !have_first &&
            std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            first = odometry;
            have_first = true;
            out.push_back({mrpt::Clock::toDouble(o->timestamp), mrpt::poses::CPose3D()});
        }
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
    std::vector<std::pair<mrpt::poses::CPose2D, double>> fits;
    for (const auto& g : guesses) {
        mrpt::slam::CICP::TReturnInfo info;
        const auto pdf = icp.Align(&map, &local, g, info);
        if (!pdf) continue;
        fits.emplace_back(pdf->getMeanVal(), info.goodness);
        if (!found || info.goodness > best.goodness + kTie) {
            best.pose = pdf->getMeanVal();
            best.goodness = info.goodness;
            found = true;
        }
    }
    for (const auto& [pose, goodness] : fits) {
        if (goodness >= best.goodness - kTie && isNewPlace(pose, best.pose, best.tied)) {
            best.tied.push_back(pose);
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

void decideStartByCeiling(StartFix& fix, const TraverseData& traverse,
                          const CeilingTraverse& mapped, double ceiling_height_m,
                          const SurveyOptions& o) {
    if (fix.tied.empty()) return;
    const auto relative =
        common::makeInterpolator(odometryFromFirstScan(traverse), o.max_pose_gap_s);
    const CeilingTraverse own{"start", &traverse.ceiling, &relative};
    const auto starts = [&](const std::vector<mrpt::poses::CPose2D>& trials) {
        return startsFromCeiling(own, trials, mapped, ceiling_height_m, o.start_match_travel_m,
                                 o.start_search_spacing_m, o);
    };
    const auto winner = starts({fix.pose}).front();
    if (winner && winner->distanceTo(fix.pose) <= o.pose_audit_max_disagreement_m) {
        fix.ceiling = "confirmed";
        return;
    }
    std::vector<mrpt::poses::CPose2D> placed;
    if (winner) placed.push_back(*winner);
    for (const auto& s : starts(fix.tied)) {
        if (s) placed.push_back(*s);
    }
    // Trials finding one place may imply its start from frames metres apart.
    const double same_place_m =
        o.pose_audit_max_disagreement_m + kOdometrySlipShare * o.start_match_travel_m;
    const bool one_place =
        std::all_of(placed.begin(), placed.end(), [&](const mrpt::poses::CPose2D& p) {
            return p.distanceTo(placed.front()) <= same_place_m;
        });
    if (placed.empty()) {
        fix.ceiling = "no match";
    } else if (!one_place) {
        fix.ceiling = "ambiguous";
    } else {
        fix.ceiling = "placed";
        fix.pose = placed.front();
    }
}

}  // namespace lookup::survey

#pragma once
// The lidar's sweep time, first ray to last, estimated from the scans when the data sheet's is
// not configured. A scan de-skewed with the wrong sweep is bent by the vehicle's motion over the
// sweep, differently for each motion and viewpoint, so registrations of one place seen from
// different keyframes stop agreeing: the pose graph of the mapping traverse's first
// `lidar_sweep_estimate_m` settles at a higher cost per registration. The sweep whose graph
// costs least is the estimate: candidates spread over [0, one scan period], then the vertex of
// the parabola through the best and its neighbours. The configured sweep stands unless it
// costs more than 1.5 times the best: near the minimum the cost is flat, and a few
// milliseconds either way move nothing.

#include <mrpt/config/CConfigFileBase.h>

#include <nlohmann/json.hpp>

#include <string>
#include <utility>
#include <vector>

#include "lookup/survey/pose_graph.h"
#include "lookup/survey/survey_options.h"
#include "lookup/survey/traverse.h"

namespace lookup::survey {

struct LidarSweepEstimate {
    std::string source = "configured";  ///< "estimated", or "configured" (kept or not estimated)
    double sweep_ms = 0;                ///< applied [ms]
    double configured_ms = 0;           ///< [survey] lidar_sweep_ms [ms]
    double scan_period_ms = 0;          ///< median spacing of the scans' stamps [ms]
    std::size_t scans = 0;              ///< scans of the piece the graphs were built on
    /// Each sweep tried [ms] and its graph's final cost per registration.
    std::vector<std::pair<double, double>> tried;
    std::string warning;  ///< why the configured sweep is used ("" = estimated)
    double time_s = 0;    ///< wall time [s]
};

/// Estimates the sweep on `mapping`, read without de-skewing (its scans are not changed).
/// Falls back to the configured lidar_sweep_ms with a warning where too few scans or
/// registrations exist; never throws for the data.
LidarSweepEstimate estimateLidarSweep(const TraverseData& mapping, const PoseGraphOptions& graph,
                                      const mrpt::config::CConfigFileBase& config,
                                      const SurveyOptions& options);

/// survey_report.json's object for it.
nlohmann::ordered_json lidarSweepJson(const LidarSweepEstimate& e);

}  // namespace lookup::survey

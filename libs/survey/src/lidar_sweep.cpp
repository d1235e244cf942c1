#include "lookup/survey/lidar_sweep.h"

#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/system/datetime.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <optional>

#include "lookup/survey/laser_poses.h"
#include "lookup/survey/scan_deskew.h"

namespace lookup::survey {
namespace {

// Fewer scans or registrations than this leave the graph's cost without meaning.
constexpr std::size_t kMinScans = 50;
constexpr std::size_t kMinRegistrations = 30;
// Sweeps tried first, as fractions of the scan period; the parabola refines between them.
constexpr int kCoarseSteps = 4;
// A configured sweep whose graph costs at most this much more than the best is kept.
constexpr double kKeepConfigured = 1.5;

/// The first `max_m` of travel of `d`'s laser sequence (odometry's), its scans copied so that
/// de-skewing them leaves `d` untouched.
TraverseData piece(const TraverseData& d, double max_m) {
    TraverseData p;
    p.rawlog = d.rawlog;
    std::optional<mrpt::poses::CPose2D> last;
    double travelled = 0;
    for (const auto& o : d.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            if (last) travelled += (odo->odometry - *last).norm();
            last = odo->odometry;
            if (travelled > max_m) break;
            p.laser_sequence.push_back(o);
            ++p.odometry_count;
        } else if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            p.laser_sequence.push_back(std::make_shared<mrpt::obs::CObservation2DRangeScan>(*scan));
            ++p.scan_count;
        }
    }
    return p;
}

double medianScanPeriod_s(const TraverseData& d) {
    std::vector<double> t, dt;
    for (const auto& o : d.laser_sequence) {
        if (std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            t.push_back(mrpt::Clock::toDouble(o->timestamp));
        }
    }
    for (std::size_t i = 1; i < t.size(); ++i) dt.push_back(t[i] - t[i - 1]);
    if (dt.empty()) return 0;
    std::nth_element(dt.begin(), dt.begin() + dt.size() / 2, dt.end());
    return dt[dt.size() / 2];
}

/// The mapping graph's final cost per registration with scans de-skewed by `sweep_s`; NaN
/// when too few registrations were kept.
double graphCost(const TraverseData& raw, double sweep_s, const PoseGraphOptions& graph,
                 const mrpt::config::CConfigFileBase& config, const SurveyOptions& o) {
    TraverseData d = piece(raw, std::numeric_limits<double>::infinity());
    deskewTraverse(d, sweep_s);
    const LaserMap icp = buildMapIcpSlam(d, config, mrpt::poses::CPose2D(), {}, o.icp_max_range_m);
    PoseGraphReport report;
    optimisePoseGraph({{&d, icp.icp_track.poses}}, graph, &report);
    if (report.registrations < kMinRegistrations) return std::nan("");
    return report.final_cost / double(report.registrations);
}

/// The costs fall towards the best sweep and rise past it, and the best is well below the
/// worst: too little motion over the sweep (slow driving) or too noisy scans leave them flat.
bool pinnedDown(const std::vector<double>& cost, int best) {
    constexpr double kMaxBestToWorst = 0.5;
    for (int k = 0; k < best; ++k)
        if (!(cost[k] > cost[k + 1])) return false;
    for (int k = best + 1; k < int(cost.size()); ++k)
        if (!(cost[k] > cost[k - 1])) return false;
    return cost[best] <= kMaxBestToWorst * *std::max_element(cost.begin(), cost.end());
}

std::string costList(const std::vector<double>& cost) {
    std::string out;
    char buf[32];
    for (double c : cost) {
        std::snprintf(buf, sizeof(buf), "%s%.3g", out.empty() ? "" : " ", c);
        out += buf;
    }
    return out;
}

/// The cost of `ms` as tried, or tried now.
template <typename Try>
double costAt(const LidarSweepEstimate& e, double ms, const Try& tryOne) {
    for (const auto& [tried_ms, cost] : e.tried)
        if (std::abs(tried_ms - ms) < 1e-6) return cost;
    return tryOne(ms);
}

/// Vertex of the parabola through (x0, y0), (x1, y1), (x2, y2), x0 < x1 < x2 equally spaced.
double parabolaVertex(double x0, double y0, double x1, double y1, double x2, double y2) {
    const double den = y0 - 2 * y1 + y2;
    if (!(den > 0)) return x1;
    return std::clamp(x1 + 0.5 * (x1 - x0) * (y0 - y2) / den, x0, x2);
}

}  // namespace

LidarSweepEstimate estimateLidarSweep(const TraverseData& mapping, const PoseGraphOptions& graph,
                                      const mrpt::config::CConfigFileBase& config,
                                      const SurveyOptions& o) {
    const auto started = std::chrono::steady_clock::now();
    LidarSweepEstimate e;
    e.configured_ms = e.sweep_ms = o.lidar_sweep_ms;
    const TraverseData raw = piece(mapping, o.lidar_sweep_estimate_m);
    e.scans = raw.scan_count;
    e.scan_period_ms = 1e3 * medianScanPeriod_s(raw);
    const auto finish = [&](std::string warning) {
        e.warning = std::move(warning);
        e.time_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        return e;
    };
    if (e.scans < kMinScans || !(e.scan_period_ms > 0)) {
        return finish("lidar sweep not estimated: " + std::to_string(e.scans) +
                      " scans in the first lidar_sweep_estimate_m of the mapping traverse; the "
                      "configured [survey] lidar_sweep_ms is used");
    }
    const auto tryOne = [&](double ms) {
        e.tried.emplace_back(ms, graphCost(raw, 1e-3 * ms, graph, config, o));
        return e.tried.back().second;
    };
    std::vector<double> cost;
    const double step = e.scan_period_ms / kCoarseSteps;
    for (int k = 0; k <= kCoarseSteps; ++k) cost.push_back(tryOne(k * step));
    if (std::any_of(cost.begin(), cost.end(), [](double c) { return !std::isfinite(c); })) {
        return finish("lidar sweep not estimated: too few scan registrations");
    }
    const int best = int(std::min_element(cost.begin(), cost.end()) - cost.begin());
    if (!pinnedDown(cost, best)) {
        char buf[96];
        std::snprintf(buf, sizeof(buf),
                      "; the configured [survey] lidar_sweep_ms = %.1f ms is used",
                      e.configured_ms);
        return finish(
            "lidar sweep not estimated: the scans do not pin it down (graph cost per "
            "registration " +
            costList(cost) + " at 0.." + std::to_string(int(std::lround(e.scan_period_ms))) +
            " ms)" + buf);
    }
    const int mid = std::clamp(best, 1, kCoarseSteps - 1);
    const double vertex = parabolaVertex((mid - 1) * step, cost[mid - 1], mid * step, cost[mid],
                                         (mid + 1) * step, cost[mid + 1]);
    costAt(e, vertex, tryOne);
    const auto [best_ms, best_cost] =
        *std::min_element(e.tried.begin(), e.tried.end(), [](const auto& a, const auto& b) {
            return std::isfinite(a.second) && (!std::isfinite(b.second) || a.second < b.second);
        });
    // The configured sweep stands unless the scans clearly disagree with it.
    const double configured_cost = costAt(e, e.configured_ms, tryOne);
    if (std::isfinite(configured_cost) && configured_cost <= kKeepConfigured * best_cost) {
        return finish("");
    }
    e.sweep_ms = best_ms;
    e.source = "estimated";
    return finish("");
}

nlohmann::ordered_json lidarSweepJson(const LidarSweepEstimate& e) {
    nlohmann::ordered_json tried = nlohmann::ordered_json::array();
    for (const auto& [ms, cost] : e.tried) {
        tried.push_back({{"sweep_ms", ms},
                         {"cost_per_registration",
                          std::isfinite(cost) ? nlohmann::ordered_json(cost) : nullptr}});
    }
    return {{"source", e.source},
            {"sweep_ms", e.sweep_ms},
            {"configured_ms", e.configured_ms},
            {"scan_period_ms", e.scan_period_ms},
            {"scans", e.scans},
            {"tried", tried},
            {"time_s", e.time_s},
            {"warning", e.warning}};
}

}  // namespace lookup::survey

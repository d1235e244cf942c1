#pragma once
// Pose-graph back end of the survey's laser stage ([pose_graph] of share/lookup/survey.ini).
//
// ICP-SLAM (CMetricMapBuilderICP) registers every scan once, against the map built so far, and
// keeps whatever error that registration had: over a 1 km drive without loops its heading
// wanders by degrees and the far end of the map is metres off. Here its track is only a first
// estimate. Every keyframe scan is registered against the keyframes within
// `max_edge_distance_m` along its own traverse and, with several traverses, against the nearest
// ones of the others, by point-to-line ICP (each scan point against the wall line through its
// neighbours in the other scan). One robust least-squares problem (Ceres, Huber loss) over all
// keyframe poses then settles what the tens of overlapping registrations per keyframe agree
// on; weak odometry links bridge scans that match nothing. The grid is rebuilt from the scans at
// the optimised poses.

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/config/CLoadableOptions.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/math/CMatrixFixed.h>

#include <functional>
#include <string>
#include <vector>

#include "lookup/common/options_table.h"
#include "lookup/common/pose_files.h"
#include "lookup/survey/traverse.h"

namespace lookup::survey {

struct PoseGraphOptions : public common::TableOptions<PoseGraphOptions> {
    /// Optimise the laser poses as a pose graph (false: ICP-SLAM's grid and MCL on it alone, as
    /// MRPT's icp-slam and pf-localization apps make them).
    bool enabled = true;
    /// Put every reference traverse into the graph with the mapping one (their MCL poses as the
    /// first estimate), so the map averages all drives; false: the mapping traverse alone, the
    /// others localised on its map by MCL.
    bool all_traverses = true;
    double keyframe_spacing_m = 0.3;    ///< travel between graph keyframes [m]
    double keyframe_spacing_deg = 5.0;  ///< ... or turn [deg]
    double max_edge_distance_m = 12.0;  ///< keyframes this close are registered pairwise [m]
    int edges_per_keyframe = 16;        ///< registrations along its own traverse (spread out)
    int cross_edges_per_keyframe = 4;   ///< ... with each other traverse
    /// Share of a scan's points that must find a wall line of the other scan [0..1].
    double min_matched_share = 0.5;
    /// A registration further than this from the first estimate is a wrong match [m] / [deg].
    double max_correction_m = 0.5;
    double max_correction_deg = 2.0;
    /// Spread of a point's distance to the other scan's wall line (range noise, rough rock
    /// between samples) [m]; with the fit's Hessian it gives each registration's covariance.
    double point_std_m = 0.02;
    double registration_min_std_xy_m = 0.005;    ///< floor of that covariance [m]
    double registration_min_std_yaw_deg = 0.01;  ///< ... in heading [deg]
    double odometry_std_per_m = 0.1;             ///< odometry link error per metre [m/m]
    double odometry_std_yaw_deg_per_m = 1.0;     ///< ... heading [deg/m]
    /// Odometry readings further apart than this bracket a dropout [s]: a scan inside one gets
    /// the motion interpolated between them, and its links the uncertainty of a vehicle that
    /// may have accelerated meanwhile (half these accelerations times the time to the nearer
    /// reading squared) [m/s^2] / [deg/s^2].
    double odometry_gap_s = 0.2;
    double odometry_gap_accel_mps2 = 2.5;
    double odometry_gap_yaw_accel_deg_s2 = 30.0;
    double huber_sigmas = 3.0;  ///< registration residuals beyond this many sigmas count linearly
    int max_iterations = 100;   ///< Ceres iterations
    int threads = 0;            ///< registration threads (0: all cores)
    /// Marginal covariance of every n-th keyframe's pose (Ceres, sparse QR), relative to the
    /// fixed first one, interpolated between: how far the map may have drifted there
    /// (0: none computed).
    int covariance_stride = 10;

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    /// Throws common::ConfigError naming every invalid field.
    void check() const;
};

/// What the optimisation did, for survey_report.json.
struct PoseGraphReport {
    std::size_t traverses = 0;
    std::size_t keyframes = 0;
    std::size_t registrations = 0;           ///< pairwise registrations kept
    std::size_t cross_registrations = 0;     ///< ... of them between two traverses
    std::size_t rejected_registrations = 0;  ///< too few matched points, or too far moved
    double initial_cost = 0, final_cost = 0;
    double time_s = 0;
    double covariance_time_s = 0;
    bool covariance_ok = false;  ///< marginal covariances computed
};

/// One traverse in the graph: its scans and a first estimate of the vehicle pose at each.
struct GraphTraverse {
    const TraverseData* data = nullptr;
    common::PoseTrack initial;  ///< one pose per lidar scan of `data`, in scan order
};

/// Called with the fraction done [0..1].
using GraphProgressFn = std::function<void(double)>;

/// Optimises the traverses' poses jointly and returns one corrected track per traverse (same
/// length and time stamps as `initial`). The first keyframe of the first traverse keeps its
/// pose: it fixes the frame. Throws std::invalid_argument when a track and its scans differ in
/// length.
/// `covariances`, when given and covariance_stride > 0, receives per traverse one (x, y, yaw)
/// covariance per scan (empty where it could not be computed).
std::vector<common::PoseTrack> optimisePoseGraph(
    const std::vector<GraphTraverse>& traverses, const PoseGraphOptions& options,
    PoseGraphReport* report = nullptr, const GraphProgressFn& progress = {},
    std::vector<std::vector<mrpt::math::CMatrixDouble33>>* covariances = nullptr);

/// Occupancy grid from every scan of the traverses at the given poses (`tracks[i]`: one per
/// scan of `traverses[i].data`), with the grid resolution and insertion options of
/// [MappingApplication_occupancyGrid_00_*] in `config`.
mrpt::maps::COccupancyGridMap2D gridFromTracks(const std::vector<GraphTraverse>& traverses,
                                               const std::vector<common::PoseTrack>& tracks,
                                               const mrpt::config::CConfigFileBase& config);

}  // namespace lookup::survey

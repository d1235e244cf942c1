#pragma once
// Laser-derived vehicle poses, the paper's map-then-localise procedure done with MRPT:
// an occupancy grid from ICP-SLAM (mrpt::slam::CMetricMapBuilderICP) over a mapping traverse,
// then MCL (mrpt::slam::CMonteCarloLocalization2D) over each reference traverse on that grid.

#include <mrpt/config/CConfigFileBase.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/poses/CPose2D.h>

#include <functional>
#include <string>
#include <vector>

#include "lookup/common/pose_files.h"
#include "lookup/survey/survey_options.h"
#include "lookup/survey/traverse.h"

namespace lookup::survey {

/// Called with the fraction done [0..1] of the current stage.
using ProgressFn = std::function<void(double)>;

/// A pose track with the (x, y, yaw) covariance at each pose.
struct LaserTrack {
    common::PoseTrack poses;                        ///< one pose per lidar scan
    std::vector<mrpt::math::CMatrixDouble33> covs;  ///< same length as poses
};

struct LaserMap {
    mrpt::maps::COccupancyGridMap2D grid;  ///< the map, in the frame of `start`
    LaserTrack icp_track;                  ///< ICP-SLAM's own pose per scan
};

/// ICP-SLAM over the odometry + lidar sequence of `traverse`, starting at `start` (map frame).
/// Reads [MappingApplication] and [ICP] of `config`; the map definition must contain an
/// occupancy grid. Throws std::runtime_error naming the section when it does not. Returns
/// beyond `max_range_m` are dropped first (0 = keep all; SurveyOptions::icp_max_range_m).
LaserMap buildMapIcpSlam(const TraverseData& traverse, const mrpt::config::CConfigFileBase& config,
                         const mrpt::poses::CPose2D& start, const ProgressFn& progress = {},
                         double max_range_m = 0);

/// The map's own error (SurveyOptions::map_std_*) as an (x, y, yaw) covariance: laser poses
/// are relative to the map, so it comes on top of their own spread.
mrpt::math::CMatrixDouble33 mapErrorCovariance(const SurveyOptions& options);

/// MCL of `traverse` on `grid` (particles around `start`), with [PF_options], [KLD_options]
/// and [LikelihoodOptions] of `config` and the odometry noise of `options`. One mean pose and
/// covariance per lidar scan.
LaserTrack localizeMcl(const TraverseData& traverse, const mrpt::maps::COccupancyGridMap2D& grid,
                       const mrpt::config::CConfigFileBase& config, const SurveyOptions& options,
                       const mrpt::poses::CPose2D& start, const ProgressFn& progress = {});

/// Loads a `.gridmap` / `.gridmap.gz` file (COccupancyGridMap2D, MRPT serialization). Throws
/// std::runtime_error naming the file and reason.
mrpt::maps::COccupancyGridMap2D loadGridMap(const std::string& path);

}  // namespace lookup::survey

#include "lookup/survey/laser_poses.h"

#include <mrpt/bayes/CParticleFilter.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/maps/CMultiMetricMap.h>
#include <mrpt/maps/CSimpleMap.h>
#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/poses/CPosePDFGaussian.h>
#include <mrpt/random/RandomGenerators.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/slam/CMetricMapBuilderICP.h>
#include <mrpt/slam/CMonteCarloLocalization2D.h>

#include <cmath>
#include <filesystem>
#include <stdexcept>

namespace lookup::survey {
namespace {

/// A copy of a range scan with returns beyond `max_range_m` invalid (0: the scan itself).
mrpt::obs::CObservation::Ptr clipRange(const mrpt::obs::CObservation::Ptr& o, double max_range_m) {
    auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o);
    if (!scan || max_range_m <= 0) return o;
    auto clipped = std::make_shared<mrpt::obs::CObservation2DRangeScan>(*scan);
    for (std::size_t i = 0; i < clipped->getScanSize(); ++i) {
        if (clipped->getScanRange(i) > max_range_m) clipped->setScanRangeValidity(i, false);
    }
    return clipped;
}

/// Walks a traverse's time-ordered odometry and scans and calls `step(i, action, frame, scan)`
/// per scan with the odometry increment since the previous scan as the action and the scan
/// (clipped to `max_range_m`, 0 = as is) as the sensory frame: the form icp-slam and
/// pf-localization take from actions/sensory-frames rawlogs, independent of odometry/scan
/// time-stamp alignment.
template <class Step>
void forEachScanStep(const TraverseData& traverse,
                     const mrpt::obs::CActionRobotMovement2D::TMotionModelOptions& motion,
                     double max_range_m, Step&& step) {
    bool have_odometry = false;
    mrpt::poses::CPose2D last_used_odometry, latest_odometry;
    for (std::size_t i = 0; i < traverse.laser_sequence.size(); ++i) {
        const auto& o = traverse.laser_sequence[i];
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            latest_odometry = odo->odometry;
            if (!have_odometry) last_used_odometry = latest_odometry;
            have_odometry = true;
            continue;
        }
        mrpt::obs::CActionRobotMovement2D move;
        move.timestamp = o->timestamp;
        move.computeFromOdometry(latest_odometry - last_used_odometry, motion);
        last_used_odometry = latest_odometry;
        mrpt::obs::CActionCollection action;
        action.insert(move);
        mrpt::obs::CSensoryFrame sf;
        sf.insert(clipRange(o, max_range_m));
        step(i, action, sf, *o);
    }
}

}  // namespace

LaserMap buildMapIcpSlam(const TraverseData& traverse, const mrpt::config::CConfigFileBase& config,
                         const mrpt::poses::CPose2D& start, const ProgressFn& progress,
                         double max_range_m) {
    mrpt::slam::CMetricMapBuilderICP builder;
    builder.setVerbosityLevel(mrpt::system::LVL_ERROR);
    builder.ICP_options.loadFromConfigFile(config, "MappingApplication");
    builder.ICP_params.loadFromConfigFile(config, "ICP");
    // MRPT 2.5.8: an initial pose PDF given to initialize() leaves the odometry-based pose
    // extrapolator without a valid time stamp and the pose never moves, so only identity is
    // supported here; callers transform the results (see Survey::run).
    if (start != mrpt::poses::CPose2D()) {
        throw std::invalid_argument("buildMapIcpSlam: only an identity start is supported");
    }
    builder.initialize(mrpt::maps::CSimpleMap());

    LaserMap out;
    mrpt::obs::CActionRobotMovement2D::TMotionModelOptions motion;
    motion.modelSelection = mrpt::obs::CActionRobotMovement2D::mmGaussian;
    const std::size_t n = traverse.laser_sequence.size();
    forEachScanStep(
        traverse, motion, max_range_m,
        [&](std::size_t i, auto& action, auto& sf, const mrpt::obs::CObservation& scan) {
            builder.processActionObservation(action, sf);
            const auto pdf = builder.getCurrentPoseEstimation();
            mrpt::poses::CPose3D mean;
            pdf->getMean(mean);
            out.icp_track.poses.push_back({mrpt::Clock::toDouble(scan.timestamp), mean});
            mrpt::math::CMatrixDouble33 cov;
            cov.setZero();
            out.icp_track.covs.push_back(cov);
            if (progress && (i % 64 == 0 || i + 1 == n)) progress(double(i + 1) / double(n));
        });
    const auto* maps = builder.getCurrentlyBuiltMetricMap();
    auto grid = maps ? maps->mapByClass<mrpt::maps::COccupancyGridMap2D>() : nullptr;
    if (!grid) {
        throw std::runtime_error(
            "[MappingApplication]: the ICP-SLAM map definition has no occupancy grid "
            "(occupancyGrid_count = 1 expected)");
    }
    out.grid = *grid;
    return out;
}

LaserTrack localizeMcl(const TraverseData& traverse, const mrpt::maps::COccupancyGridMap2D& grid,
                       const mrpt::config::CConfigFileBase& config, const SurveyOptions& options,
                       const mrpt::poses::CPose2D& start, const ProgressFn& progress) {
    auto map = std::make_shared<mrpt::maps::COccupancyGridMap2D>(grid);
    if (config.sectionExists("LikelihoodOptions")) {
        map->likelihoodOptions.loadFromConfigFile(config, "LikelihoodOptions");
    }
    mrpt::bayes::CParticleFilter pf;
    pf.m_options.loadFromConfigFile(config, "PF_options");
    mrpt::slam::CMonteCarloLocalization2D pdf(options.mcl_particles);
    pdf.options.metricMap = map;
    if (config.sectionExists("KLD_options")) {
        pdf.options.KLD_params.loadFromConfigFile(config, "KLD_options");
    }
    // Deterministic runs: the same input gives the same database.
    mrpt::random::getRandomGenerator().randomize(1234);
    const double s_xy = options.mcl_init_std_xy_m;
    const double s_yaw = mrpt::DEG2RAD(options.mcl_init_std_yaw_deg);
    pdf.resetUniform(start.x() - s_xy, start.x() + s_xy, start.y() - s_xy, start.y() + s_xy,
                     start.phi() - s_yaw, start.phi() + s_yaw, options.mcl_particles);

    mrpt::obs::CActionRobotMovement2D::TMotionModelOptions motion;
    motion.modelSelection = mrpt::obs::CActionRobotMovement2D::mmGaussian;
    motion.gaussianModel.minStdXY = options.odometry_min_std_xy_m;
    motion.gaussianModel.minStdPHI = mrpt::DEG2RAD(options.odometry_min_std_yaw_deg);

    const mrpt::math::CMatrixDouble33 map_error = mapErrorCovariance(options);
    LaserTrack out;
    const std::size_t n = traverse.laser_sequence.size();
    forEachScanStep(
        traverse, motion, 0.0,
        [&](std::size_t i, auto& action, auto& sf, const mrpt::obs::CObservation& scan) {
            pf.executeOn(pdf, &action, &sf);

            auto [cov, mean] = pdf.getCovarianceAndMean();
            cov += map_error;  // MCL's spread is relative to the map
            out.poses.push_back(
                {mrpt::Clock::toDouble(scan.timestamp), mrpt::poses::CPose3D(mean)});
            out.covs.push_back(cov);
            if (progress && (i % 64 == 0 || i + 1 == n)) progress(double(i + 1) / double(n));
        });
    return out;
}

mrpt::math::CMatrixDouble33 mapErrorCovariance(const SurveyOptions& options) {
    mrpt::math::CMatrixDouble33 cov;
    cov.setZero();
    cov(0, 0) = cov(1, 1) = options.map_std_xy_m * options.map_std_xy_m;
    cov(2, 2) = std::pow(mrpt::DEG2RAD(options.map_std_yaw_deg), 2);
    return cov;
}

mrpt::maps::COccupancyGridMap2D loadGridMap(const std::string& path) {
    if (!std::filesystem::is_regular_file(path)) {
        throw std::runtime_error(path + ": no such map file");
    }
    mrpt::maps::COccupancyGridMap2D grid;
    try {
        mrpt::io::CFileGZInputStream f(path);
        auto arch = mrpt::serialization::archiveFrom(f);
        arch >> grid;
    } catch (const std::exception& e) {
        throw std::runtime_error(path +
                                 ": unreadable map (expected a COccupancyGridMap2D "
                                 "serialization): " +
                                 std::string(e.what()).substr(0, 300));
    }
    if (grid.getSizeX() == 0 || grid.getSizeY() == 0) {
        throw std::runtime_error(path + ": empty map");
    }
    return grid;
}

}  // namespace lookup::survey

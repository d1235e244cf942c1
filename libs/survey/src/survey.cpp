#include "lookup/survey/survey.h"

#include <mrpt/core/format.h>
#include <mrpt/math/distributions.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/system/CTicTac.h>
#include <mrpt/system/progress.h>
#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <optional>
#include <sstream>

#include <nlohmann/json.hpp>
#include <opencv2/imgcodecs.hpp>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"
#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"
#include "lookup/refine/lens_shading.h"
#include "lookup/survey/keyframes.h"
#include "lookup/survey/mrpt_sections.h"
#include "lookup/survey/scan_deskew.h"
#include "lookup/survey/start_search.h"
#include "lookup/survey/traverse.h"

namespace lookup::survey {
namespace fs = std::filesystem;
namespace {

PoseErrorStats statsOf(std::vector<double> err_m, const std::vector<double>& yaw_deg) {
    PoseErrorStats s;
    s.count = err_m.size();
    if (err_m.empty()) return s;
    double sum = 0;
    for (double e : err_m) sum += e;
    s.mean_m = sum / err_m.size();
    double ysum = 0;
    for (double e : yaw_deg) ysum += e;
    s.mean_yaw_deg = yaw_deg.empty() ? 0 : ysum / yaw_deg.size();
    std::sort(err_m.begin(), err_m.end());
    s.max_m = err_m.back();
    s.p95_m = err_m[std::min(err_m.size() - 1,
                             static_cast<std::size_t>(std::ceil(0.95 * err_m.size())) - 1)];
    return s;
}

// Index of the element of sorted `times` nearest to t.
std::size_t nearestIndex(const std::vector<double>& times, double t) {
    auto it = std::lower_bound(times.begin(), times.end(), t);
    if (it == times.end()) return times.size() - 1;
    if (it == times.begin()) return 0;
    const auto hi = static_cast<std::size_t>(it - times.begin());
    return (t - times[hi - 1] <= times[hi] - t) ? hi - 1 : hi;
}

cv::Mat loadPixels(const mrpt::obs::CObservationImage& obs, int flags) {
    if (obs.image.isExternallyStored()) {
        return cv::imread(obs.image.getExternalStorageFileAbsolutePath(), flags);
    }
    cv::Mat m;
    obs.image.asCvMat(m, mrpt::img::DEEP_COPY);
    return m;
}

std::string imageName(const mrpt::obs::CObservationImage& obs) {
    return obs.image.isExternallyStored() ? obs.image.getExternalStorageFileAbsolutePath()
                                          : obs.sensorLabel + " image in the rawlog";
}

// Why the pixels of `obs` cannot be used ("" = usable): unreadable, empty, not 8-bit, or not
// the size its intrinsics (and the database's camera, `expected`) say.
std::string pixelProblem(const mrpt::obs::CObservationImage& obs, const cv::Mat& m,
                         const mrpt::img::TCamera* expected) {
    if (m.empty()) return imageName(obs) + ": unreadable or empty image";
    if (m.depth() != CV_8U) return imageName(obs) + ": not an 8-bit image";
    const auto& c = obs.cameraParams;
    if (std::uint32_t(m.cols) != c.ncols || std::uint32_t(m.rows) != c.nrows) {
        return imageName(obs) + ": image is " + std::to_string(m.cols) + "x" +
               std::to_string(m.rows) + " but its intrinsics say " + std::to_string(c.ncols) + "x" +
               std::to_string(c.nrows);
    }
    if (expected && (expected->ncols != c.ncols || expected->nrows != c.nrows)) {
        return imageName(obs) + ": image is " + std::to_string(m.cols) + "x" +
               std::to_string(m.rows) + " but the database's camera is " +
               std::to_string(expected->ncols) + "x" + std::to_string(expected->nrows);
    }
    return "";
}

}  // namespace

ImageQuality ceilingQuality(const mrpt::obs::CObservationImage& obs,
                            const mrpt::img::TCamera* expected, int max_width_px,
                            std::string& problem) {
    cv::Mat m;
    try {
        m = loadPixels(obs, cv::IMREAD_UNCHANGED);
    } catch (const std::exception&) {
        m = cv::Mat();
    }
    problem = pixelProblem(obs, m, expected);
    if (!problem.empty()) {
        ImageQuality q;
        q.usable = false;
        return q;
    }
    if (m.channels() != 1 && m.channels() != 3) m = loadPixels(obs, cv::IMREAD_GRAYSCALE);
    return measureImageQuality(m, max_width_px);
}

namespace {

std::uint64_t folderSize(const std::string& dir) {
    std::uint64_t total = 0;
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        if (e.is_regular_file()) total += e.file_size();
    }
    return total;
}

class ProgressBar {
  public:
    ProgressBar(bool enabled, std::string stage) : enabled_(enabled), stage_(std::move(stage)) {}
    void operator()(double ratio) const {
        if (!enabled_) return;
        std::cerr << "\r" << stage_ << " " << mrpt::system::progress(ratio, 30) << std::flush;
        if (ratio >= 1.0) std::cerr << "\n";
    }

  private:
    bool enabled_;
    std::string stage_;
};

}  // namespace

std::vector<std::string> traverseWarnings(const TraverseReport& r, const std::string& rawlog,
                                          const SurveyOptions& o) {
    std::vector<std::string> out;
    const auto& k = r.skipped;
    if (k.lidar_ranges + k.records() > 0) {
        out.push_back(rawlog + ": refused " + std::to_string(k.lidar_ranges) +
                      " non-finite lidar ranges, " + std::to_string(k.scans) + " scans, " +
                      std::to_string(k.odometry) + " odometry records, " +
                      std::to_string(k.ceiling_intrinsics + k.forward_intrinsics) +
                      " images with unusable intrinsics (first: " + k.first + ")");
    }
    if (r.rejected_blur + r.rejected_exposure > 0) {
        out.push_back(rawlog + ": skipped " +
                      std::to_string(r.rejected_blur + r.rejected_exposure) +
                      " ceiling keyframes (" + std::to_string(r.rejected_blur) + " blurred, " +
                      std::to_string(r.rejected_exposure) +
                      " badly exposed: [survey] min_sharpness, min_mean_intensity, "
                      "max_mean_intensity, max_clipped_fraction), kept " +
                      std::to_string(r.references) + " references");
    }
    if (r.rejected_image + r.rejected_forward > 0) {
        out.push_back(rawlog + ": refused " + std::to_string(r.rejected_image) + " ceiling and " +
                      std::to_string(r.rejected_forward) +
                      " forward images (first: " + r.first_image_problem + ")");
    }
    if (r.lens.corrected) {
        out.push_back(rawlog + ": " +
                      refine::dirtyLensWarning(r.lens.dirty_share, r.lens.least_transmission,
                                               o.lens, "the references"));
    }
    const ImageQuality& q = r.ceiling_images;
    const bool dim = q.mean_intensity < o.warn_dim_mean_intensity;
    if (r.references > 0 && (dim || q.clipped_fraction > o.warn_clipped_fraction)) {
        out.push_back(rawlog + mrpt::format(": the ceiling images are %s (median over the "
                                            "references: mean grey %.1f, %.0f %% of pixels "
                                            "clipped; [survey] warn_dim_mean_intensity, "
                                            "warn_clipped_fraction): they localise, but the "
                                            "first fix may wait and fewer frames refine; set "
                                            "the lamps and exposure as docs/vehicle.md says",
                                            dim ? "dim" : "saturated", q.mean_intensity,
                                            100 * q.clipped_fraction));
    }
    return out;
}

namespace {

struct TraverseStart {
    std::string source;         ///< "map origin", "ground truth" or "scan match"
    mrpt::poses::CPose2D pose;  ///< grid frame while the laser stage runs, then map frame
    double goodness = 0;        ///< of the scan match
    std::size_t tied_places = 0;
    std::string ceiling;  ///< StartFix::ceiling
};

// The operator's start pose of the mapping traverse ([survey] start_pose, else the dataset's),
// the origin when neither gives one.
mrpt::poses::CPose2D operatorStart(const SurveyOptions& o, const SurveyInputs& in) {
    const std::string& text = o.start_pose.empty() ? in.start_pose : o.start_pose;
    if (text.empty()) return {};
    if (auto p = parseStartPose(text)) return *p;
    throw common::ConfigError("start_pose '" + text + "': expected three numbers: x y yaw_deg");
}

/// Where the database's ceiling height comes from ([survey]): the dataset's stated height when
/// use_dataset_ceiling_height asks for it, the configured one when ceiling_estimate is off, else
/// measured on the images.
enum class CeilingRule { Dataset, Configured, Measured };

CeilingRule ceilingRule(const SurveyInputs& in, const SurveyOptions& o) {
    if (in.ceiling_height_m > 0 && o.use_dataset_ceiling_height) return CeilingRule::Dataset;
    return o.ceiling_estimate ? CeilingRule::Measured : CeilingRule::Configured;
}

/// The mapping traverse's ceiling frames on its track (grid frame), which decide a start the
/// lidar leaves tied, and the ceiling height they are compared at: measured on them alone
/// (the survey's estimate waits for every traverse's poses), when first needed.
class MappedCeiling {
  public:
    /// `mapping` null: no mapping traverse (a map file's frame).
    MappedCeiling(const SurveyInputs& in, const SurveyOptions& o, const TraverseData* mapping,
                  const common::PoseTrack& track)
        : in_(in),
          o_(o),
          poses_(common::makeInterpolator(track, o.max_pose_gap_s)),
          traverse_{"mapping", mapping ? &mapping->ceiling : nullptr, &poses_} {}

    bool usable() const { return o_.start_by_ceiling && traverse_.ceiling && !poses_.empty(); }
    const CeilingTraverse& traverse() const { return traverse_; }
    double ceilingHeight() {
        if (height_m_) return *height_m_;
        switch (ceilingRule(in_, o_)) {
            case CeilingRule::Dataset:
                height_m_ = in_.ceiling_height_m;
                break;
            case CeilingRule::Configured:
                height_m_ = o_.ceiling_height_m;
                break;
            case CeilingRule::Measured:
                height_m_ = estimateCeilingDistance({traverse_}, o_).ceiling_height_m;
                break;
        }
        return *height_m_;
    }

  private:
    const SurveyInputs& in_;
    const SurveyOptions& o_;
    mrpt::poses::CPose3DInterpolator poses_;
    CeilingTraverse traverse_;
    std::optional<double> height_m_;
};

// Where MCL starts a traverse on the grid: the map's own origin for the traverse that built
// it, the ground truth only as a diagnostic, else its first scans matched against the map, a
// tie along a uniform drive decided by the ceiling.
TraverseStart startInGrid(bool own_map, bool use_gt, const mrpt::poses::CPose2D& gt_start,
                          const mrpt::poses::CPose2D& fallback, const TraverseData& d,
                          const mrpt::maps::COccupancyGridMap2D& grid,
                          const common::PoseTrack& mapping_track, MappedCeiling& mapped,
                          const SurveyOptions& o) {
    if (use_gt) return {"ground truth", gt_start, 0, 0, ""};
    if (own_map) return {"map origin", mrpt::poses::CPose2D(), 0, 0, ""};
    StartFix fix = findStartInMap(d, grid, mapping_track, fallback, o);
    if (!fix.tied.empty() && mapped.usable()) {
        decideStartByCeiling(fix, d, mapped.traverse(), mapped.ceilingHeight(), o);
    }
    return {"scan match", fix.pose, fix.goodness, fix.tied.size(), fix.ceiling};
}

/// The warning for a start the lidar left tied and the ceiling did not decide; else empty.
std::string undecidedStartWarning(const std::string& rawlog, const TraverseStart& s) {
    if (s.ceiling != "ambiguous" && s.ceiling != "no match") return {};
    return rawlog +
           mrpt::format(
               ": the lidar fits its first metres as well at %zu other places "
               "along the drive and the ceiling images %s: started at the fit "
               "nearest the mapping traverse's start (the pose audit checks "
               "it; start every survey traverse at the same portal)",
               s.tied_places,
               s.ceiling == "ambiguous" ? "agree with several of them" : "match none of them");
}

// The cameras' configured time offsets, applied to their stamps as read: every later step
// (pose per image, forward image per reference, the ceiling height) sees the pose clock.
void configuredOffsets(const SurveyOptions& o, TraverseData& d) {
    shiftStamps(d.ceiling, o.ceiling_time_offset_s);
    shiftStamps(d.forward, o.forward_time_offset_s);
}

nlohmann::ordered_json statsJson(const PoseErrorStats& s) {
    return {{"count", s.count},
            {"mean_m", s.mean_m},
            {"p95_m", s.p95_m},
            {"max_m", s.max_m},
            {"mean_yaw_deg", s.mean_yaw_deg}};
}

nlohmann::ordered_json poseGraphJson(const PoseGraphReport& g) {
    return {{"traverses", g.traverses},
            {"keyframes", g.keyframes},
            {"registrations", g.registrations},
            {"cross_registrations", g.cross_registrations},
            {"rejected_registrations", g.rejected_registrations},
            {"initial_cost", g.initial_cost},
            {"final_cost", g.final_cost},
            {"time_s", g.time_s},
            {"covariance", g.covariance_ok},
            {"covariance_time_s", g.covariance_time_s}};
}

nlohmann::ordered_json traverseJson(const TraverseReport& t) {
    using nlohmann::ordered_json;
    ordered_json j = {{"name", t.name},
                      {"ceiling_frames", t.ceiling_frames},
                      {"frames_without_pose", t.frames_without_pose},
                      {"references", t.references},
                      {"rejected_blur", t.rejected_blur},
                      {"rejected_exposure", t.rejected_exposure},
                      {"rejected_image", t.rejected_image},
                      {"rejected_forward", t.rejected_forward},
                      {"rejected_audit", t.rejected_audit},
                      {"without_forward", t.without_forward},
                      {"scans_deskewed", t.scans_deskewed}};
    j["lens"] = {{"images", t.lens.images},
                 {"dirty_share", t.lens.dirty_share},
                 {"least_transmission", t.lens.least_transmission},
                 {"corrected", t.lens.corrected}};
    j["ceiling_images"] = {{"median_mean_grey", t.ceiling_images.mean_intensity},
                           {"median_clipped_share", t.ceiling_images.clipped_fraction},
                           {"median_sharpness", t.ceiling_images.sharpness}};
    j["skipped"] = {{"lidar_ranges", t.skipped.lidar_ranges},
                    {"scans", t.skipped.scans},
                    {"odometry", t.skipped.odometry},
                    {"imu", t.skipped.imu},
                    {"ceiling_intrinsics", t.skipped.ceiling_intrinsics},
                    {"forward_intrinsics", t.skipped.forward_intrinsics},
                    {"first", t.skipped.first},
                    {"first_image", t.first_image_problem}};
    const LevellingReport& l = t.levelling;
    j["levelling"] = {{"imu_records", l.imu_records},
                      {"scans_levelled", l.scans_levelled},
                      {"odometry_levelled", l.odometry_levelled},
                      {"max_pitch_deg", l.max_pitch_deg},
                      {"odometry_m", l.odometry_m},
                      {"levelled_m", l.levelled_m},
                      {"floor_returns", l.floor_returns},
                      {"roof_returns", l.roof_returns}};
    j["localisation_time_s"] = t.localisation_time_s;
    if (!t.start_source.empty()) {
        j["start"] = {{"source", t.start_source},
                      {"x", t.start.x()},
                      {"y", t.start.y()},
                      {"yaw_deg", mrpt::RAD2DEG(t.start.phi())},
                      {"goodness", t.start_goodness},
                      {"tied_places", t.start_tied_places},
                      {"ceiling", t.start_ceiling}};
    }
    j["has_ground_truth"] = t.has_ground_truth;
    if (t.has_ground_truth) {
        j["error"] = statsJson(t.error);
        j["segments"] = ordered_json::array();
        for (const auto& s : t.segments) {
            j["segments"].push_back(ordered_json{{"from_m", s.from_m},
                                                 {"to_m", s.to_m},
                                                 {"x", s.x},
                                                 {"y", s.y},
                                                 {"error", statsJson(s.error)}});
        }
    }
    return j;
}

/// Every traverse as read (stamps shifted by the configured offsets), with its ground truth.
struct SurveyData {
    std::vector<TraverseData> data;
    std::vector<std::optional<mrpt::poses::CPose3DInterpolator>> gt;
};

/// The options traverses are read with: scans not de-skewed when the sweep is to be estimated.
SurveyOptions readingOptions(SurveyOptions o, bool laser) {
    if (laser && o.lidar_sweep_estimate) o.lidar_sweep_ms = 0;
    return o;
}

SurveyData readTraverses(const SurveyInputs& in, const SurveyOptions& o, bool laser) {
    SurveyData s;
    for (const auto& spec : in.traverses) {
        s.data.push_back(readTraverse(spec.rawlog, o, laser && spec.reference));
        configuredOffsets(o, s.data.back());
        if (!spec.ground_truth.empty()) {
            s.gt.emplace_back(common::makeInterpolator(common::readPoseFile(spec.ground_truth),
                                                       o.max_pose_gap_s));
        } else {
            s.gt.emplace_back(std::nullopt);
        }
    }
    return s;
}

/// Vehicle poses of every traverse in the map frame, and what found them.
struct VehiclePoses {
    explicit VehiclePoses(std::size_t n) : tracks(n), starts(n), localisation_time_s(n, 0.0) {}
    std::vector<LaserTrack> tracks;
    std::vector<TraverseStart> starts;
    std::vector<double> localisation_time_s;
    std::optional<mrpt::maps::COccupancyGridMap2D> grid;
};

/// Surveyed poses from files (one for all, or each traverse's ground truth), with the
/// configured spread as their covariance; the grid only when a map file is given.
VehiclePoses posesFromFiles(const SurveyInputs& in, const SurveyOptions& o, std::size_t n,
                            SurveyResult& result) {
    VehiclePoses poses(n);
    mrpt::math::CMatrixDouble33 cov;
    cov.setZero();
    cov(0, 0) = cov(1, 1) = std::pow(o.pose_file_std_xy_m, 2);
    cov(2, 2) = std::pow(mrpt::DEG2RAD(o.pose_file_std_yaw_deg), 2);
    const auto trackFrom = [&](const std::string& file) {
        LaserTrack track;
        track.poses = common::readPoseFile(file);
        track.covs.assign(track.poses.size(), cov);
        return track;
    };
    if (in.poses_file == kPosesFromGroundTruth) {
        // Each traverse's own surveyed track (e.g. <traverse>.rawlog.GT.txt).
        result.pose_source = "ground-truth files";
        for (std::size_t i = 0; i < n; ++i) {
            if (in.traverses[i].ground_truth.empty()) {
                throw common::ConfigError(in.traverses[i].rawlog +
                                          ": --poses ground-truth, but this traverse "
                                          "has no ground-truth file");
            }
            poses.tracks[i] = trackFrom(in.traverses[i].ground_truth);
        }
    } else {
        result.pose_source = "file:" + fs::absolute(in.poses_file).string();
        const LaserTrack file_track = trackFrom(in.poses_file);
        for (auto& t : poses.tracks) t = file_track;
    }
    if (!in.map_file.empty()) poses.grid = loadGridMap(in.map_file);
    return poses;
}

/// The ground truth's pose at the traverse's first laser record when start_at_ground_truth
/// asks for it and it has one, else `fallback`.
mrpt::poses::CPose2D groundTruthStart(const SurveyOptions& o, const TraverseData& d,
                                      const std::optional<mrpt::poses::CPose3DInterpolator>& gt,
                                      const mrpt::poses::CPose2D& fallback) {
    if (!o.start_at_ground_truth || !gt) return fallback;
    const double t0 = mrpt::Clock::toDouble(d.laser_sequence.front()->timestamp);
    if (auto p = common::poseAt(*gt, t0)) return mrpt::poses::CPose2D(*p);
    return fallback;
}

/// The first traverse marked `mapping`, or in.traverses.size() when none is.
std::size_t mappingIndex(const SurveyInputs& in) {
    for (std::size_t i = 0; i < in.traverses.size(); ++i) {
        if (in.traverses[i].mapping) return i;
    }
    return in.traverses.size();
}

/// The laser stage's grid map in its own frame (the grid frame), and the mapping traverse on it.
struct GridMap {
    mrpt::maps::COccupancyGridMap2D grid;
    mrpt::poses::CPose2D origin;                   ///< the grid frame's pose in the map frame
    common::PoseTrack mapping_track;               ///< where the other traverses' starts are sought
    std::optional<common::PoseTrack> graph_track;  ///< the mapping traverse's pose-graph track
    /// The graph's covariances relative to the start along mapping_track, when final (else
    /// none: zero where the marks are compared).
    std::vector<mrpt::math::CMatrixDouble33> graph_covs;
};

/// The mapping traverse's own pose graph over its ICP-SLAM track, and the grid rebuilt from it.
void mappingGraph(const SurveyInputs& in, std::size_t mapping, const TraverseData& d,
                  const LaserMap& icp, const PoseGraphOptions& g,
                  const mrpt::config::CConfigFileBase& config, GridMap& map, SurveyResult& result) {
    ProgressBar graph_bar(in.show_progress, "pose graph " + in.traverses[mapping].name);
    const std::vector<GraphTraverse> alone{{&d, icp.icp_track.poses}};
    // Its covariances are only kept when no joint graph follows.
    const bool others = std::any_of(in.traverses.begin(), in.traverses.end(), [&](const auto& t) {
        return t.reference && &t != &in.traverses[mapping];
    });
    const bool final_poses = g.all_traverses && !others;
    std::vector<std::vector<mrpt::math::CMatrixDouble33>> covs;
    map.graph_track = optimisePoseGraph(alone, g, &result.pose_graph, graph_bar,
                                        final_poses ? &covs : nullptr)[0];
    if (final_poses) map.graph_covs = covs[0];
    map.grid = gridFromTracks(alone, {*map.graph_track}, config);
}

/// ICP-SLAM over the mapping traverse, refined by its own pose graph when enabled.
GridMap buildMap(const SurveyInputs& in, std::size_t mapping, SurveyData& survey,
                 const SurveyOptions& o, const PoseGraphOptions& g,
                 const mrpt::config::CConfigFileBase& config, SurveyResult& result) {
    if (mapping == survey.data.size()) throw std::runtime_error("no mapping traverse");
    TraverseData& d = survey.data[mapping];
    // The mapping traverse needs lidar + odometry even if it is not a reference.
    if (d.scan_count == 0 || d.odometry_count == 0) {
        d = readTraverse(in.traverses[mapping].rawlog, o, true);
        configuredOffsets(o, d);
    }
    result.pose_source = "laser";
    GridMap map;
    // ICP-SLAM runs in its own frame (its start = identity: MRPT 2.5.8's pose extrapolator
    // stalls when initialize() is given a start pose); poses are moved into the ground-truth
    // frame by the origin afterwards.
    map.origin = groundTruthStart(o, d, survey.gt[mapping], operatorStart(o, in));
    mrpt::system::CTicTac timer;
    ProgressBar bar(in.show_progress, "ICP-SLAM " + in.traverses[mapping].name);
    LaserMap icp = buildMapIcpSlam(d, config, mrpt::poses::CPose2D(), bar, o.icp_max_range_m);
    if (g.enabled) {
        mappingGraph(in, mapping, d, icp, g, config, map, result);
    } else {
        map.grid = std::move(icp.grid);
    }
    map.mapping_track = map.graph_track ? *map.graph_track : icp.icp_track.poses;
    result.mapping_time_s = timer.Tac();
    return map;
}

/// MCL of every reference traverse on the grid (the mapping one too, on its own map, unless
/// the joint graph places it); poses and starts in the grid frame.
void localizeOnGrid(const SurveyInputs& in, const SurveyData& survey, const GridMap& map,
                    std::size_t mapping, bool joint, const SurveyOptions& o,
                    const mrpt::config::CConfigFileBase& config, VehiclePoses& poses,
                    SurveyResult& result) {
    MappedCeiling mapped(in, o, mapping < survey.data.size() ? &survey.data[mapping] : nullptr,
                         map.mapping_track);
    for (std::size_t i = 0; i < survey.data.size(); ++i) {
        if (!in.traverses[i].reference || (joint && i == mapping)) continue;
        mrpt::system::CTicTac timer;
        ProgressBar bar(in.show_progress, "MCL " + in.traverses[i].name);
        const bool own_map = i == mapping && in.map_file.empty();
        const bool use_gt = o.start_at_ground_truth && survey.gt[i].has_value();
        const mrpt::poses::CPose2D gt_start =
            groundTruthStart(o, survey.data[i], survey.gt[i], map.origin) - map.origin;
        poses.starts[i] =
            startInGrid(own_map, use_gt, gt_start,
                        in.map_file.empty() ? mrpt::poses::CPose2D() : operatorStart(o, in),
                        survey.data[i], map.grid, map.mapping_track, mapped, o);
        const auto warning = undecidedStartWarning(survey.data[i].rawlog, poses.starts[i]);
        if (!warning.empty()) result.warnings.push_back(warning);
        poses.tracks[i] =
            localizeMcl(survey.data[i], map.grid, config, o, poses.starts[i].pose, bar);
        poses.localisation_time_s[i] = timer.Tac();
        result.localisation_time_s += poses.localisation_time_s[i];
    }
}

/// Every reference traverse joins the mapping one in one pose graph, MCL's poses on the first
/// map as its first estimate; the map is rebuilt from all of them. The graph's poses replace
/// MCL's; their covariance is the graph's marginal one (how far the map may have drifted there,
/// relative to its start) on top of the map's local error.
void jointGraph(const SurveyInputs& in, const SurveyData& survey, std::size_t mapping,
                const SurveyOptions& o, const PoseGraphOptions& g,
                const mrpt::config::CConfigFileBase& config, GridMap& map, VehiclePoses& poses,
                SurveyResult& result) {
    std::vector<GraphTraverse> graph{{&survey.data[mapping], *map.graph_track}};
    std::vector<std::size_t> members{mapping};
    for (std::size_t i = 0; i < survey.data.size(); ++i) {
        if (!in.traverses[i].reference || i == mapping) continue;
        graph.push_back({&survey.data[i], poses.tracks[i].poses});
        members.push_back(i);
    }
    std::vector<common::PoseTrack> member_tracks{*map.graph_track};
    std::vector<std::vector<mrpt::math::CMatrixDouble33>> member_covs{map.graph_covs};
    if (graph.size() > 1) {
        mrpt::system::CTicTac timer;
        ProgressBar graph_bar(in.show_progress, "pose graph, all traverses");
        std::vector<std::vector<mrpt::math::CMatrixDouble33>> covs;
        member_tracks = optimisePoseGraph(graph, g, &result.pose_graph, graph_bar, &covs);
        covs.resize(members.size());  // none when the graph had no keyframes
        member_covs = std::move(covs);
        map.grid = gridFromTracks(graph, member_tracks, config);
        // Where the marks are compared: the mapping traverse as the joint graph placed it.
        if (!member_tracks[0].empty()) {
            map.mapping_track = member_tracks[0];
            map.graph_covs = member_covs[0];
        }
        result.mapping_time_s += timer.Tac();
    }
    const mrpt::math::CMatrixDouble33 floor = mapErrorCovariance(o);
    for (std::size_t k = 0; k < members.size(); ++k) {
        if (!in.traverses[members[k]].reference) continue;
        LaserTrack& track = poses.tracks[members[k]];
        track.poses = member_tracks[k];
        track.covs.assign(track.poses.size(), floor);
        if (member_covs[k].size() == track.poses.size()) {
            for (std::size_t n = 0; n < track.covs.size(); ++n) track.covs[n] += member_covs[k][n];
        }
    }
}

/// The rigid correction of the map frame (x, y, yaw about `pivot`) and its covariance.
struct FrameTie {
    Eigen::Vector3d delta = Eigen::Vector3d::Zero();
    Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
};

/// d(pose at `p`)/d(correction about `pivot`): the offset, and the heading times the lever.
Eigen::Matrix3d leverJacobian(const mrpt::poses::CPose2D& pivot, double x, double y) {
    Eigen::Matrix3d j = Eigen::Matrix3d::Identity();
    j(0, 2) = -(y - pivot.y());
    j(1, 2) = x - pivot.x();
    return j;
}

/// A mark's covariance; a mark given as exact (zero deviation) keeps a micrometre's, so that it
/// can be weighed against the other one: it then holds the frame where it is.
Eigen::Matrix3d markCovariance(double std_xy_m, double std_yaw_deg) {
    const double xy = std::max(std_xy_m, 1e-6), yaw = mrpt::DEG2RAD(std::max(std_yaw_deg, 1e-6));
    return Eigen::Vector3d(xy * xy, xy * xy, yaw * yaw).asDiagonal();
}

/// A mark besides the start's against the mapping traverse's pose at its time (map frame).
struct MarkTie {
    mrpt::poses::CPose2D map_pose, mark;
    Eigen::Matrix3d weight;  ///< inverse of the mark's and the graph's covariance together
    bool used = true;

    /// The mark minus the map's pose, before and after a correction `d` about `start`.
    Eigen::Vector3d disagreement() const {
        return {mark.x() - map_pose.x(), mark.y() - map_pose.y(),
                mrpt::math::wrapToPi(mark.phi() - map_pose.phi())};
    }
    Eigen::Vector3d residual(const mrpt::poses::CPose2D& start, const Eigen::Vector3d& d) const {
        return disagreement() - leverJacobian(start, map_pose.x(), map_pose.y()) * d;
    }
    double chi2(const mrpt::poses::CPose2D& start, const Eigen::Vector3d& d) const {
        const Eigen::Vector3d r = residual(start, d);
        return r.dot(weight * r);
    }
};

/// Weighted least squares over a small rigid correction about the start: the start lies on
/// its mark by construction, every other mark where the map put the vehicle at its time. The
/// laser map's shape is kept (over a survey's length it is far more precise than a mark); each
/// mark's weight includes the graph's uncertainty there relative to the start.
FrameTie fitToMarks(const mrpt::poses::CPose2D& start, const Eigen::Matrix3d& w_start,
                    const std::vector<MarkTie>& marks) {
    Eigen::Matrix3d h = w_start;
    Eigen::Vector3d g = Eigen::Vector3d::Zero();
    for (const auto& m : marks) {
        if (!m.used) continue;
        const Eigen::Matrix3d a = leverJacobian(start, m.map_pose.x(), m.map_pose.y());
        h += a.transpose() * m.weight * a;
        g += a.transpose() * m.weight * m.disagreement();
    }
    FrameTie tie;
    tie.cov = h.inverse();
    tie.delta = tie.cov * g;
    return tie;
}

/// The fit to every mark, leaving out the worst one while the fit's chi-square lies beyond
/// 99.9 % for its degrees of freedom (3 per mark besides the start's): a wrong mark, or a map
/// that drifted. Returns the chi-square of the last fit.
FrameTie tieToMarks(const mrpt::poses::CPose2D& start, const SurveyOptions& o,
                    std::vector<MarkTie>& marks, double& chi2) {
    const Eigen::Matrix3d w_start =
        markCovariance(o.start_pose_std_xy_m, o.start_pose_std_yaw_deg).inverse();
    for (;;) {
        const FrameTie tie = fitToMarks(start, w_start, marks);
        chi2 = tie.delta.dot(w_start * tie.delta);
        std::size_t used = 0, worst = 0;
        double worst_chi2 = -1;
        for (std::size_t k = 0; k < marks.size(); ++k) {
            if (!marks[k].used) continue;
            ++used;
            const double c = marks[k].chi2(start, tie.delta);
            chi2 += c;
            if (c > worst_chi2) worst = k, worst_chi2 = c;
        }
        if (used == 0 || chi2 <= mrpt::math::chi2inv(0.999, 3 * used)) return tie;
        marks[worst].used = false;
    }
}

/// The end mark (at the mapping traverse's last pose) and the marks along the drive, each
/// against the map's pose at its time (map frame) with the graph's covariance there; a mark
/// outside the drive's time is said and left out.
std::vector<MarkTie> marksAgainstMap(const mrpt::poses::CPose2D& origin, const GridMap& map,
                                     const SurveyInputs& in, const SurveyOptions& o,
                                     SurveyResult& result) {
    const auto& track = map.mapping_track;
    std::vector<double> times;
    for (const auto& p : track) times.push_back(p.time_s);
    const auto interp = common::makeInterpolator(track, o.max_pose_gap_s);
    // The graph's covariance is in the grid frame: turned into the map frame.
    const Eigen::Matrix3d turn =
        Eigen::AngleAxisd(origin.phi(), Eigen::Vector3d::UnitZ()).toRotationMatrix();
    const auto against = [&](double t, const mrpt::poses::CPose2D& mark,
                             const Eigen::Matrix3d& mark_cov) -> std::optional<MarkTie> {
        if (times.empty() || t < times.front() - 1e-6 || t > times.back() + 1e-6) {
            return std::nullopt;
        }
        const auto pose = common::poseAt(interp, std::clamp(t, times.front(), times.back()));
        if (!pose) return std::nullopt;
        Eigen::Matrix3d graph_cov = Eigen::Matrix3d::Zero();
        if (map.graph_covs.size() == track.size()) {
            graph_cov = turn * map.graph_covs[nearestIndex(times, t)].asEigen() * turn.transpose();
        }
        return MarkTie{origin + mrpt::poses::CPose2D(*pose), mark,
                       (mark_cov + graph_cov).inverse()};
    };
    std::vector<MarkTie> ties;
    const std::string& end_text = o.end_pose.empty() ? in.end_pose : o.end_pose;
    const auto end_mark = parseStartPose(end_text);
    if (end_mark && !times.empty()) {
        const auto tie = against(times.back(), *end_mark,
                                 markCovariance(o.end_pose_std_xy_m, o.end_pose_std_yaw_deg));
        if (tie) ties.push_back(*tie);
        result.end_mark.given = tie.has_value();
    }
    const std::string& marks_text = o.marks.empty() ? in.marks : o.marks;
    for (const TimedMark& m : parseMarks(marks_text).value_or(std::vector<TimedMark>{})) {
        const auto tie =
            against(m.time_s, m.pose, markCovariance(o.marks_std_xy_m, o.marks_std_yaw_deg));
        if (!tie) {
            result.warnings.push_back(mrpt::format(
                "marks: the mark at time %.3f lies outside the mapping traverse's laser poses: "
                "not used",
                m.time_s));
            continue;
        }
        ties.push_back(*tie);
        result.drive_marks.push_back({m.time_s});
    }
    return ties;
}

/// What each mark's fit says, into the report; a mark left out is warned about.
void reportMarks(const std::vector<MarkTie>& ties, const mrpt::poses::CPose2D& origin,
                 const FrameTie& tie, double chi2, const std::string& end_text,
                 SurveyResult& result) {
    std::size_t k = 0;
    if (result.end_mark.given) {
        const MarkTie& end = ties[k++];
        result.end_mark.used = end.used;
        result.end_mark.disagreement_m = std::hypot(end.disagreement().x(), end.disagreement().y());
        result.end_mark.disagreement_deg = mrpt::RAD2DEG(end.disagreement().z());
        result.end_mark.chi2 = chi2;
        if (!end.used) {
            result.warnings.push_back(
                "end_pose '" + end_text + "' is " + std::to_string(result.end_mark.disagreement_m) +
                " m and " + std::to_string(result.end_mark.disagreement_deg) +
                " deg from the mapping traverse's last laser pose, more than the marks' and the "
                "map's uncertainty allow: not used (a wrong mark, or a map that drifted)");
        }
    }
    for (auto& r : result.drive_marks) {
        const MarkTie& m = ties[k++];
        const Eigen::Vector3d before = m.disagreement(), after = m.residual(origin, tie.delta);
        r.used = m.used;
        r.disagreement_m = std::hypot(before.x(), before.y());
        r.disagreement_deg = mrpt::RAD2DEG(before.z());
        r.residual_m = std::hypot(after.x(), after.y());
        if (!m.used) {
            result.warnings.push_back(mrpt::format(
                "marks: the mark at time %.3f is %.3f m and %.3f deg from the mapping traverse's "
                "laser pose then, more than the marks' and the map's uncertainty allow: not used "
                "(a wrong mark, or a map that drifted)",
                r.time_s, r.disagreement_m, r.disagreement_deg));
        }
    }
}

/// The operator's marks define the map frame, and their errors are a rigid error of the whole
/// map: an offset everywhere, a heading error times the distance from the start. With an end
/// mark or marks along the drive the map is moved by the correction the marks agree on; every
/// laser pose's covariance (the graph's is relative to the fixed start) carries what is left of
/// that rigid error.
void tieMapToMarks(const mrpt::poses::CPose2D& origin, const GridMap& map, const SurveyInputs& in,
                   const SurveyOptions& o, VehiclePoses& poses, SurveyResult& result) {
    std::vector<MarkTie> ties = marksAgainstMap(origin, map, in, o, result);
    double chi2 = 0;
    const FrameTie tie = tieToMarks(origin, o, ties, chi2);
    reportMarks(ties, origin, tie, chi2, o.end_pose.empty() ? in.end_pose : o.end_pose, result);
    result.end_mark.correction = mrpt::poses::CPose2D(tie.delta.x(), tie.delta.y(), tie.delta.z());
    result.end_mark.std_xy_m = std::sqrt(0.5 * (tie.cov(0, 0) + tie.cov(1, 1)));
    result.end_mark.std_yaw_deg = mrpt::RAD2DEG(std::sqrt(tie.cov(2, 2)));
    if (std::any_of(ties.begin(), ties.end(), [](const MarkTie& m) { return m.used; })) {
        // Turned by the correction's heading about the start, then shifted by its offset.
        const mrpt::poses::CPose2D correction =
            mrpt::poses::CPose2D(origin.x() + tie.delta.x(), origin.y() + tie.delta.y(),
                                 tie.delta.z()) +
            mrpt::poses::CPose2D(-origin.x(), -origin.y(), 0);
        const mrpt::poses::CPose3D correction3(correction);
        for (auto& start : poses.starts) start.pose = correction + start.pose;
        for (auto& track : poses.tracks) {
            for (auto& p : track.poses) p.pose = correction3 + p.pose;
        }
    }
    for (auto& track : poses.tracks) {
        for (std::size_t k = 0; k < track.poses.size() && k < track.covs.size(); ++k) {
            const mrpt::poses::CPose3D& p = track.poses[k].pose;
            const Eigen::Matrix3d j = leverJacobian(origin, p.x(), p.y());
            track.covs[k].asEigen() += j * tie.cov * j.transpose();
        }
    }
}

/// From the grid frame into the map frame: poses and starts composed with the grid's origin,
/// (x, y) covariances rotated.
void toMapFrame(const mrpt::poses::CPose2D& origin, VehiclePoses& poses) {
    for (auto& start : poses.starts) start.pose = origin + start.pose;
    const mrpt::poses::CPose3D origin3(origin);
    mrpt::math::CMatrixDouble33 rotation;
    rotation.setIdentity();
    rotation(0, 0) = rotation(1, 1) = std::cos(origin.phi());
    rotation(1, 0) = std::sin(origin.phi());
    rotation(0, 1) = -rotation(1, 0);
    for (auto& track : poses.tracks) {
        for (auto& p : track.poses) p.pose = origin3 + p.pose;
        for (auto& c : track.covs) {
            c = mrpt::math::CMatrixDouble33(rotation.asEigen() * c.asEigen() *
                                            rotation.asEigen().transpose());
        }
    }
}

/// The laser stage: a grid map (given, or ICP-SLAM of the mapping traverse with its pose
/// graph), MCL of the reference traverses on it, the joint pose graph when configured.
VehiclePoses posesFromLaser(const SurveyInputs& in, SurveyData& survey, const SurveyOptions& o,
                            const PoseGraphOptions& g, const mrpt::config::CConfigFileBase& config,
                            SurveyResult& result) {
    VehiclePoses poses(survey.data.size());
    const std::size_t mapping = mappingIndex(in);
    GridMap map;
    if (!in.map_file.empty()) {
        result.pose_source = "laser+map:" + fs::absolute(in.map_file).string();
        map.grid = loadGridMap(in.map_file);
    } else {
        map = buildMap(in, mapping, survey, o, g, config, result);
    }
    const bool joint = map.graph_track.has_value() && g.all_traverses;
    localizeOnGrid(in, survey, map, mapping, joint, o, config, poses, result);
    if (joint) {
        jointGraph(in, survey, mapping, o, g, config, map, poses, result);
        poses.starts[mapping] = {"map origin", mrpt::poses::CPose2D(), 0, 0, ""};
    }
    toMapFrame(map.origin, poses);
    // The frame's own error: the operator's marks (not a map file's frame, nor the truth's).
    if (in.map_file.empty() && !o.start_at_ground_truth) {
        tieMapToMarks(map.origin, map, in, o, poses, result);
    }
    poses.grid = std::move(map.grid);
    return poses;
}

/// The database's cameras, each fixed by its first usable image.
struct Cameras {
    std::optional<mrpt::img::TCamera> ceiling, forward;
};

/// A traverse's vehicle poses, looked up by the ceiling images' times, which are uncertain by
/// `image_time_sigma_s`.
struct TrackLookup {
    TrackLookup(const LaserTrack& t, double max_gap_s, double image_time_sigma)
        : track(t),
          interp(common::makeInterpolator(t.poses, max_gap_s)),
          image_time_sigma_s(image_time_sigma) {
        for (const auto& p : t.poses) times.push_back(p.time_s);
    }
    /// The track's covariance at image time `t`, with what the time's uncertainty adds: the
    /// vehicle moves (speed x sigma) along its motion and turns (rate x sigma) meanwhile.
    mrpt::math::CMatrixDouble33 covarianceAt(double t) const {
        mrpt::math::CMatrixDouble33 cov = track.covs[nearestIndex(times, t)];
        constexpr double kSpan_s = 0.05;
        const auto a = common::poseAt(interp, t - kSpan_s), b = common::poseAt(interp, t + kSpan_s);
        if (!a || !b || image_time_sigma_s <= 0) return cov;
        const Eigen::Vector3d rate((b->x() - a->x()) / (2 * kSpan_s),
                                   (b->y() - a->y()) / (2 * kSpan_s),
                                   mrpt::math::wrapToPi(b->yaw() - a->yaw()) / (2 * kSpan_s));
        const Eigen::Matrix3d added =
            image_time_sigma_s * image_time_sigma_s * rate * rate.transpose();
        cov.asEigen() += added;
        return cov;
    }
    const LaserTrack& track;
    mrpt::poses::CPose3DInterpolator interp;
    std::vector<double> times;
    double image_time_sigma_s = 0;
};

/// The keyframe candidates: the ceiling frames with a pose on the track.
struct PosedFrames {
    std::vector<KeyframeCandidate> candidates;
    std::vector<std::size_t> frame_of;         ///< candidate -> ceiling frame
    std::size_t without_pose = 0;              ///< frames outside the track
    std::optional<std::size_t> first_outside;  ///< the first of them
};

PosedFrames posedFrames(const TraverseData& d, const TrackLookup& poses) {
    PosedFrames out;
    for (std::size_t f = 0; f < d.ceiling.size(); ++f) {
        const double t = mrpt::Clock::toDouble(d.ceiling[f]->timestamp);
        if (auto p = common::poseAt(poses.interp, t)) {
            out.candidates.push_back({t, *p});
            out.frame_of.push_back(f);
        } else {
            ++out.without_pose;
            if (!out.first_outside) out.first_outside = f;
        }
    }
    return out;
}

/// Throws when more than max_outside_fraction of the ceiling frames have no pose on the track
/// (`track_name`): the camera's and the track's clocks do not match.
void checkPoseCoverage(const TraverseData& d, const PosedFrames& frames, const TrackLookup& poses,
                       const SurveyOptions& o, const std::string& track_name) {
    if (frames.without_pose <= o.max_outside_fraction * d.ceiling.size()) return;
    const std::size_t f = *frames.first_outside;
    throw common::RawlogError(d.rawlog, d.ceiling_records[f],
                              "mismatched time stamps: " + std::to_string(frames.without_pose) +
                                  " of " + std::to_string(d.ceiling.size()) + " " +
                                  o.ceiling_camera_label + " images (first at t=" +
                                  std::to_string(mrpt::Clock::toDouble(d.ceiling[f]->timestamp)) +
                                  " s) have no pose in [" + std::to_string(poses.times.front()) +
                                  ", " + std::to_string(poses.times.back()) + "] s of " +
                                  track_name);
}

/// Keyframes among the candidates, judged by image quality; the first usable image fixes the
/// database's ceiling camera.
KeyframeSelection selectReferences(const TraverseData& d, const PosedFrames& frames,
                                   const SurveyOptions& o, Cameras& cameras, TraverseReport& rep) {
    return selectKeyframes(frames.candidates, o, [&](std::size_t c) {
        const auto& image = *d.ceiling[frames.frame_of[c]];
        std::string problem;
        const auto q = ceilingQuality(image, cameras.ceiling ? &*cameras.ceiling : nullptr,
                                      o.ceiling_max_width_px, problem);
        if (!problem.empty() && rep.first_image_problem.empty()) rep.first_image_problem = problem;
        if (q.usable && !cameras.ceiling) cameras.ceiling = image.cameraParams;
        return q;
    });
}

/// The forward frames of a traverse, each checked once when first wanted.
class ForwardImages {
  public:
    explicit ForwardImages(const TraverseData& d) : d_(d), state_(d.forward.size(), 0) {
        for (const auto& fw : d.forward) times_.push_back(mrpt::Clock::toDouble(fw->timestamp));
    }

    /// The frame nearest in time to `t_s` when within `max_dt_s` and usable (refused ones are
    /// counted in `rep`); the first used fixes the database's forward camera.
    std::optional<std::size_t> nearest(double t_s, double max_dt_s, Cameras& cameras,
                                       TraverseReport& rep) {
        if (times_.empty()) return std::nullopt;
        const std::size_t fi = nearestIndex(times_, t_s);
        if (std::abs(times_[fi] - t_s) > max_dt_s || !usable(fi, cameras, rep)) return std::nullopt;
        if (!cameras.forward) cameras.forward = d_.forward[fi]->cameraParams;
        return fi;
    }
    double time(std::size_t fi) const { return times_[fi]; }

  private:
    bool usable(std::size_t fi, const Cameras& cameras, TraverseReport& rep) {
        if (state_[fi] == 0) {
            const auto& fw = *d_.forward[fi];
            cv::Mat m;
            try {
                m = loadPixels(fw, cv::IMREAD_UNCHANGED);
            } catch (const std::exception&) {
                m = cv::Mat();
            }
            const std::string problem =
                pixelProblem(fw, m, cameras.forward ? &*cameras.forward : nullptr);
            state_[fi] = problem.empty() ? 1 : -1;
            if (!problem.empty()) {
                ++rep.rejected_forward;
                if (rep.first_image_problem.empty()) rep.first_image_problem = problem;
            }
        }
        return state_[fi] > 0;
    }
    const TraverseData& d_;
    std::vector<double> times_;
    std::vector<int> state_;  ///< 0 not checked, 1 usable, -1 refused
};

/// The references' errors against the ground truth, in travel order.
struct ReferenceErrors {
    std::vector<double> err_m, err_yaw_deg, travelled_m;
    std::vector<mrpt::poses::CPose3D> poses;

    void add(const mrpt::poses::CPose3D& truth, const database::ReferenceInput& ref) {
        const double dx = truth.x() - ref.vehicle_pose.x();
        const double dy = truth.y() - ref.vehicle_pose.y();
        err_m.push_back(std::hypot(dx, dy));
        err_yaw_deg.push_back(
            std::abs(mrpt::RAD2DEG(mrpt::math::wrapToPi(truth.yaw() - ref.vehicle_pose.yaw()))));
        travelled_m.push_back(ref.travelled_m);
        poses.push_back(ref.vehicle_pose);
    }
};

/// The survey camera's lens judged over the traverse's kept references, in travel order (they
/// lie keyframe_spacing_m apart, the ceiling moved on between them); said in `rep.lens`.
refine::LensShading judgeLens(const TraverseData& d, const PosedFrames& frames,
                              const KeyframeSelection& selection, const SurveyOptions& o,
                              TraverseReport& rep) {
    refine::LensShading lens(o.lens);
    double last_m = -1e9;
    for (std::size_t k = 0; k < selection.kept.size(); ++k) {
        if (selection.kept_travelled_m[k] - last_m < o.lens.min_travel_m) continue;
        const auto& ceiling = *d.ceiling[frames.frame_of[selection.kept[k]]];
        const cv::Mat image = loadPixels(ceiling, cv::IMREAD_UNCHANGED);
        if (image.empty()) continue;
        lens.add(image, refine::driveInImage(ceiling.cameraPose, ceiling.cameraParams));
        last_m = selection.kept_travelled_m[k];
    }
    rep.lens = {lens.imagesAdded(), lens.dirtyShare(), lens.leastTransmission(), lens.dirty()};
    return lens;
}

/// `ceiling` with its image divided by the lens's transmission, where the lens is dirty.
mrpt::obs::CObservationImage::Ptr withoutDirt(const mrpt::obs::CObservationImage::Ptr& ceiling,
                                              const refine::LensShading& lens) {
    if (!lens.dirty()) return ceiling;
    const cv::Mat image = loadPixels(*ceiling, cv::IMREAD_UNCHANGED);
    if (image.empty()) return ceiling;  // refused downstream, naming the file
    auto clean = mrpt::obs::CObservationImage::Create(*ceiling);
    clean->image = mrpt::img::CImage(lens.correct(image), mrpt::img::DEEP_COPY);
    return clean;
}

/// Writes the selected references of one traverse (pose, covariance, quality, forward image);
/// returns their errors against `gt`.
ReferenceErrors writeReferences(const TraverseSpec& spec, const TraverseData& d,
                                const TrackLookup& poses, const PosedFrames& frames,
                                const KeyframeSelection& selection,
                                const std::optional<mrpt::poses::CPose3DInterpolator>& gt,
                                const SurveyOptions& o, Cameras& cameras,
                                database::DatabaseWriter& writer, TraverseReport& rep) {
    ForwardImages forward(d);
    const refine::LensShading lens = judgeLens(d, frames, selection, o, rep);
    ReferenceErrors errors;
    for (std::size_t k = 0; k < selection.kept.size(); ++k) {
        const KeyframeCandidate& candidate = frames.candidates[selection.kept[k]];
        database::ReferenceInput ref;
        ref.traverse = spec.name;
        ref.ceiling = withoutDirt(d.ceiling[frames.frame_of[selection.kept[k]]], lens);
        ref.vehicle_pose = candidate.vehicle_pose;
        ref.vehicle_cov = poses.covarianceAt(candidate.time_s);
        ref.sharpness = selection.kept_quality[k].sharpness;
        ref.mean_intensity = selection.kept_quality[k].mean_intensity;
        ref.travelled_m = selection.kept_travelled_m[k];
        if (auto fi = forward.nearest(candidate.time_s, o.forward_max_dt_s, cameras, rep)) {
            ref.forward = d.forward[*fi];
            ref.forward_vehicle_pose =
                common::poseAt(poses.interp, forward.time(*fi)).value_or(ref.vehicle_pose);
        }
        if (!ref.forward) ++rep.without_forward;
        writer.add(ref);
        if (gt) {
            if (auto truth = common::poseAt(*gt, candidate.time_s)) errors.add(*truth, ref);
        }
    }
    return errors;
}

/// The error per 10 m of travel, to show where the laser poses degrade.
std::vector<SegmentError> errorSegments(const ReferenceErrors& e) {
    constexpr double kSegment_m = 10.0;
    std::vector<SegmentError> out;
    std::size_t b = 0;
    while (b < e.err_m.size()) {
        const double from = std::floor(e.travelled_m[b] / kSegment_m) * kSegment_m;
        std::size_t end = b;
        while (end < e.err_m.size() && e.travelled_m[end] < from + kSegment_m) ++end;
        SegmentError seg;
        seg.from_m = from;
        seg.to_m = from + kSegment_m;
        const auto& mid = e.poses[(b + end) / 2];
        seg.x = mid.x();
        seg.y = mid.y();
        seg.error = statsOf({e.err_m.begin() + b, e.err_m.begin() + end},
                            {e.err_yaw_deg.begin() + b, e.err_yaw_deg.begin() + end});
        out.push_back(seg);
        b = end;
    }
    return out;
}

/// Removes the candidates in a stretch whose laser poses the images contradict; their count.
std::size_t dropContradicted(PosedFrames& frames, const PoseAudit& audit,
                             const std::string& traverse) {
    PosedFrames kept = frames;
    kept.candidates.clear();
    kept.frame_of.clear();
    for (std::size_t c = 0; c < frames.candidates.size(); ++c) {
        if (audit.excludes(traverse, frames.candidates[c].time_s)) continue;
        kept.candidates.push_back(frames.candidates[c]);
        kept.frame_of.push_back(frames.frame_of[c]);
    }
    const std::size_t dropped = frames.candidates.size() - kept.candidates.size();
    frames = std::move(kept);
    return dropped;
}

/// One reference traverse into the database: a pose per ceiling frame, keyframes, forward
/// images, the records; its report.
TraverseReport addTraverse(const TraverseSpec& spec, const TraverseData& d, const LaserTrack& track,
                           const std::optional<mrpt::poses::CPose3DInterpolator>& gt,
                           const TraverseStart& start, double localisation_time_s,
                           double image_time_sigma_s, const PoseAudit& audit,
                           const SurveyOptions& o, const std::string& track_name, Cameras& cameras,
                           database::DatabaseWriter& writer) {
    TraverseReport rep;
    rep.name = spec.name;
    rep.ceiling_frames = d.ceiling.size();
    rep.has_ground_truth = gt.has_value();
    rep.localisation_time_s = localisation_time_s;
    rep.start_source = start.source;
    rep.start = start.pose;
    rep.start_goodness = start.goodness;
    rep.start_tied_places = start.tied_places;
    rep.start_ceiling = start.ceiling;
    if (track.poses.empty()) {
        throw common::RawlogError(d.rawlog, "no vehicle poses (no lidar scans localised)");
    }
    const TrackLookup poses(track, o.max_pose_gap_s, image_time_sigma_s);
    PosedFrames frames = posedFrames(d, poses);
    rep.frames_without_pose = frames.without_pose;
    checkPoseCoverage(d, frames, poses, o, track_name);
    rep.rejected_audit = dropContradicted(frames, audit, spec.name);
    const KeyframeSelection selection = selectReferences(d, frames, o, cameras, rep);
    rep.rejected_image = selection.rejected_unusable;
    rep.skipped = d.skipped;
    rep.scans_deskewed = d.scans_deskewed;
    rep.levelling = d.levelling;
    rep.rejected_blur = selection.rejected_blur;
    rep.rejected_exposure = selection.rejected_exposure;
    rep.ceiling_images = medianQuality(selection.kept_quality);
    const ReferenceErrors errors =
        writeReferences(spec, d, poses, frames, selection, gt, o, cameras, writer, rep);
    rep.references = selection.kept.size();
    if (gt) {
        rep.error = statsOf(errors.err_m, errors.err_yaw_deg);
        rep.segments = errorSegments(errors);
    }
    return rep;
}

/// db.ini's description of the database to be: its name, cameras' labels, source rawlogs and
/// the [survey] options used.
database::DatabaseInfo databaseInfo(const SurveyInputs& in, const SurveyOptions& o) {
    database::DatabaseInfo info;
    info.name = in.name;
    info.ceiling_camera_label = o.ceiling_camera_label;
    info.forward_camera_label = o.forward_camera_label;
    info.ceiling_readout_ms = o.ceiling_readout_ms;
    info.ceiling_stamp_row = o.ceiling_stamp_row;
    for (const auto& spec : in.traverses) {
        info.source_rawlogs.push_back(fs::absolute(spec.rawlog).string());
    }
    mrpt::config::CConfigFileMemory used;
    o.saveToConfigFile(used, "survey");
    info.options_ini = used.getContent();
    return info;
}

/// References are told apart by their traverse's name (the database, the pose audit).
void checkUniqueNames(const SurveyInputs& in) {
    for (std::size_t i = 0; i < in.traverses.size(); ++i) {
        for (std::size_t k = 0; k < i; ++k) {
            if (in.traverses[i].name != in.traverses[k].name) continue;
            throw common::ConfigError("two traverses are named '" + in.traverses[i].name + "' (" +
                                      in.traverses[k].rawlog + ", " + in.traverses[i].rawlog +
                                      "): names must differ");
        }
    }
}

/// The reference traverses' ceiling frames on their laser poses, as the ceiling-height estimate
/// and the pose audit read them; `traverses` points into `interps` and into the caller's data.
struct LaserPosedCeilings {
    std::vector<mrpt::poses::CPose3DInterpolator> interps;
    std::vector<CeilingTraverse> traverses;
};

LaserPosedCeilings laserPosedCeilings(const SurveyInputs& in, const std::vector<TraverseData>& data,
                                      const std::vector<LaserTrack>& tracks, double max_gap_s) {
    LaserPosedCeilings c;
    c.interps.reserve(data.size());  // the pointers below must stay valid
    for (std::size_t i = 0; i < data.size(); ++i) {
        c.interps.push_back(common::makeInterpolator(tracks[i].poses, max_gap_s));
        if (!in.traverses[i].reference || tracks[i].poses.empty()) continue;
        c.traverses.push_back({in.traverses[i].name, &data[i].ceiling, &c.interps.back()});
    }
    return c;
}

}  // namespace

std::string SurveyResult::summaryLine() const {
    std::ostringstream o;
    if (!ok()) {
        o << "lookup-survey: FAILED: " << reason;
        return o.str();
    }
    o.setf(std::ios::fixed);
    o.precision(2);
    o << "lookup-survey: " << references << " references in " << out_dir << " ("
      << size_bytes / 1.0e6 << " MB, " << total_time_s << " s, poses: " << pose_source << ")";
    if (!ceiling_source.empty()) {
        o.precision(3);
        o << "; ceiling " << ceiling.ceiling_height_m << " m (" << ceiling_source << ")";
    }
    if (!time_offsets.empty()) {
        const auto& c = time_offsets.front();
        o.precision(1);
        o << "; " << c.label << " time offset " << 1e3 * c.offset_s << " +- "
          << 1e3 * c.applied_sigma_s << " ms (" << c.source << "); lidar sweep "
          << lidar_sweep.sweep_ms << " ms (" << lidar_sweep.source << ")";
    }
    if (pose_audit.ran && pose_audit.note.empty()) {
        o << "; pose audit: " << pose_audit.suspect << " suspect of " << pose_audit.sampled
          << " frames";
        if (pose_audit.traverses_discarded > 0) {
            o << ", " << pose_audit.traverses_discarded << " traverse(s) matching nowhere left out";
        }
    } else {
        o << "; poses not audited: " << pose_audit.note;
    }
    for (const auto& t : traverses) {
        if (t.start_ceiling == "placed") o << "; " << t.name << "'s start placed by the ceiling";
    }
    for (const auto& t : traverses) {
        if (!t.has_ground_truth) continue;
        o.precision(3);
        o << "; " << t.name << " error mean " << t.error.mean_m << " p95 " << t.error.p95_m
          << " max " << t.error.max_m << " m";
    }
    return o.str();
}

std::string SurveyResult::toJson() const {
    using nlohmann::ordered_json;
    ordered_json j;
    j["status"] = ok() ? "ok" : "failed";
    j["reason"] = reason;
    j["database"] = out_dir;
    j["pose_source"] = pose_source;
    j["references"] = references;
    j["size_bytes"] = size_bytes;
    j["time_s"] = {{"total", total_time_s},
                   {"mapping", mapping_time_s},
                   {"localisation", localisation_time_s},
                   {"writing", writing_time_s}};
    if (pose_graph.keyframes > 0) j["pose_graph"] = poseGraphJson(pose_graph);
    if (!ceiling_source.empty()) j["ceiling"] = ceilingJson(ceiling, ceiling_source);
    if (!time_offsets.empty()) {
        j["time_offsets"] = ordered_json::array();
        for (const auto& t : time_offsets) j["time_offsets"].push_back(timeOffsetJson(t));
        j["lidar_sweep"] = lidarSweepJson(lidar_sweep);
    }
    if (time_offset_across.tried) {
        j["time_offset_across_traverses"] = timeOffsetJson(time_offset_across);
    }
    if (end_mark.given || !drive_marks.empty()) {
        j["end_mark"] = {{"given", end_mark.given},
                         {"used", end_mark.used},
                         {"disagreement_m", end_mark.disagreement_m},
                         {"disagreement_deg", end_mark.disagreement_deg},
                         {"chi2", end_mark.chi2},
                         {"correction",
                          {{"x", end_mark.correction.x()},
                           {"y", end_mark.correction.y()},
                           {"yaw_deg", mrpt::RAD2DEG(end_mark.correction.phi())}}},
                         {"frame_std_xy_m", end_mark.std_xy_m},
                         {"frame_std_yaw_deg", end_mark.std_yaw_deg}};
    }
    if (!drive_marks.empty()) {
        j["marks"] = ordered_json::array();
        for (const auto& m : drive_marks) {
            j["marks"].push_back({{"time_s", m.time_s},
                                  {"used", m.used},
                                  {"disagreement_m", m.disagreement_m},
                                  {"disagreement_deg", m.disagreement_deg},
                                  {"residual_m", m.residual_m}});
        }
    }
    j["pose_audit"] = poseAuditJson(pose_audit);
    j["traverses"] = ordered_json::array();
    for (const auto& t : traverses) j["traverses"].push_back(traverseJson(t));
    // Paths and reasons are bytes from the file system: invalid UTF-8 is replaced, not fatal.
    return j.dump(2, ' ', false, nlohmann::json::error_handler_t::replace) + "\n";
}

Survey::Survey(SurveyOptions options, const mrpt::config::CConfigFileBase& config)
    : options_(std::move(options)) {
    options_.check();
    config_.setFileName(common::configSourceName(config));
    checkMrptSections(config);
    common::loadAndCheck(graph_options_, config, "pose_graph");
    std::vector<std::string> sections;
    config.getAllSections(sections);
    for (const auto& s : sections) {
        std::vector<std::string> keys;
        config.getAllKeys(s, keys);
        for (const auto& k : keys) config_.write(s, k, config.read_string(s, k, ""));
    }
}

double Survey::ceilingHeight(const SurveyInputs& in, const std::vector<TraverseData>& data,
                             const std::vector<LaserTrack>& tracks, SurveyResult& result) const {
    const CeilingRule rule = ceilingRule(in, options_);
    if (rule == CeilingRule::Dataset) {
        result.ceiling_source = "dataset";
        result.ceiling.ceiling_height_m = in.ceiling_height_m;
        result.warnings.push_back("ceiling height taken from the dataset (" +
                                  std::to_string(in.ceiling_height_m) +
                                  " m; [survey] use_dataset_ceiling_height = true), not measured");
        return in.ceiling_height_m;
    }
    if (in.ceiling_height_m > 0) {
        result.warnings.push_back(
            "the dataset states ceiling_height_m = " + std::to_string(in.ceiling_height_m) +
            " m: ignored (the survey measures it; [survey] "
            "use_dataset_ceiling_height = true uses it)");
    }
    if (rule == CeilingRule::Configured) {
        result.ceiling_source = "configured";
        result.ceiling.ceiling_height_m = result.ceiling.prior_m = options_.ceiling_height_m;
        return options_.ceiling_height_m;
    }
    const auto posed = laserPosedCeilings(in, data, tracks, options_.max_pose_gap_s);
    const auto& traverses = posed.traverses;
    result.ceiling = estimateCeilingDistance(traverses, options_);
    result.ceiling_source = result.ceiling.estimated ? "estimated" : "configured";
    if (!result.ceiling.warning.empty()) result.warnings.push_back(result.ceiling.warning);
    return result.ceiling.ceiling_height_m;
}

void Survey::lidarSweep(const SurveyInputs& in, std::vector<TraverseData>& data,
                        SurveyResult& result) const {
    LidarSweepEstimate& e = result.lidar_sweep;
    e.configured_ms = e.sweep_ms = options_.lidar_sweep_ms;
    const std::size_t mapping = mappingIndex(in);
    if (!options_.lidar_sweep_estimate || mapping == data.size()) return;
    TraverseData& m = data[mapping];
    if (m.scan_count == 0 || m.odometry_count == 0) {
        m = readTraverse(in.traverses[mapping].rawlog, readingOptions(options_, true), true);
        configuredOffsets(options_, m);
    }
    e = estimateLidarSweep(m, graph_options_, config_, options_);
    if (!e.warning.empty()) result.warnings.push_back(e.warning);
    for (auto& d : data) d.scans_deskewed = deskewTraverse(d, 1e-3 * e.sweep_ms);
}

void Survey::timeOffsets(const SurveyInputs& in, std::vector<TraverseData>& data,
                         const std::vector<LaserTrack>& tracks, double ceiling_height_m,
                         SurveyResult& result) const {
    TimeOffsetEstimate ceiling;
    ceiling.label = options_.ceiling_camera_label;
    ceiling.source = "configured";
    ceiling.offset_s = ceiling.configured_s = options_.ceiling_time_offset_s;
    ceiling.applied_sigma_s = options_.ceiling_time_offset_sigma_s;
    if (options_.time_offset_estimate) {
        const auto posed = laserPosedCeilings(in, data, tracks, options_.max_pose_gap_s);
        ceiling = estimateTimeOffset(posed.traverses, ceiling_height_m, options_);
        if (!ceiling.warning.empty()) result.warnings.push_back(ceiling.warning);
        for (auto& d : data) shiftStamps(d.ceiling, ceiling.offset_s - ceiling.configured_s);
    }
    TimeOffsetEstimate forward;
    forward.label = options_.forward_camera_label;
    forward.source = "configured";
    forward.offset_s = forward.configured_s = options_.forward_time_offset_s;
    result.time_offsets = {ceiling, forward};
}

void Survey::auditPoses(const SurveyInputs& in, std::vector<TraverseData>& data,
                        const std::vector<LaserTrack>& tracks, double ceiling_height_m,
                        SurveyResult& result) const {
    const auto posed = laserPosedCeilings(in, data, tracks, options_.max_pose_gap_s);
    const auto& traverses = posed.traverses;
    result.pose_audit = auditLaserPoses(traverses, ceiling_height_m, options_);
    // Where the image motion left the camera's offset as configured, the audit's fixes across
    // traverses may pin it down; the audit then runs again on the stamps corrected.
    TimeOffsetEstimate& ceiling = result.time_offsets.front();
    if (options_.time_offset_estimate && ceiling.source != "estimated" && result.pose_audit.ran) {
        result.time_offset_across = estimateTimeOffsetAcrossTraverses(result.pose_audit, traverses,
                                                                      ceiling.offset_s, options_);
        const auto& across = result.time_offset_across;
        if (across.source == "estimated") {
            for (auto& d : data) shiftStamps(d.ceiling, across.offset_s - ceiling.offset_s);
            auto& w = result.warnings;
            w.erase(std::remove(w.begin(), w.end(), ceiling.warning), w.end());
            ceiling = across;
            result.pose_audit = auditLaserPoses(traverses, ceiling_height_m, options_);
        }
    }
    for (const auto& s : result.pose_audit.stretches) {
        char buf[400];
        if (s.whole_traverse_compared > 0) {
            std::snprintf(buf, sizeof(buf),
                          "%s: none of its %zu comparisons with the other traverses found its "
                          "ceiling where its laser poses put it (a start aliased along a uniform "
                          "drive?): none of its references kept",
                          s.traverse.c_str(), s.whole_traverse_compared);
            result.warnings.push_back(buf);
            continue;
        }
        std::snprintf(buf, sizeof(buf),
                      "%s: the ceiling images put the frame at t=%.3f s %.2f m from its pose "
                      "(against traverse %s, agreeing with none): no references kept between "
                      "the audited frames around it",
                      s.traverse.c_str(), s.sample_s, s.disagreement_m, s.against.c_str());
        result.warnings.push_back(buf);
    }
}

SurveyResult Survey::run(const SurveyInputs& in) const {
    SurveyResult result;
    mrpt::system::CTicTac total;
    result.out_dir = fs::absolute(in.out_dir).lexically_normal().string();
    try {
        if (in.traverses.empty()) throw std::runtime_error("no input traverses");
        checkUniqueNames(in);
        if (in.out_dir.empty()) throw common::ConfigError("no output folder given");
        // Leftovers of an interrupted run: the old database put back, stale folders removed.
        for (auto& line : database::recoverInterrupted(in.out_dir)) {
            result.warnings.push_back(std::move(line));
        }
        // 1. Read every traverse (image headers, odometry, scans) and its ground truth.
        const bool laser = in.poses_file.empty();
        SurveyData survey = readTraverses(in, readingOptions(options_, laser), laser);
        if (laser) lidarSweep(in, survey.data, result);

        // 2. Vehicle poses per traverse.
        VehiclePoses poses =
            laser ? posesFromLaser(in, survey, options_, graph_options_, config_, result)
                  : posesFromFiles(in, options_, survey.data.size(), result);

        // 3. References: pose per ceiling image, keyframes, forward image, database records.
        mrpt::system::CTicTac timer;
        database::DatabaseWriter writer(in.out_dir, options_.ceiling_max_width_px);
        if (poses.grid) writer.setMap(*poses.grid);
        database::DatabaseInfo info = databaseInfo(in, options_);
        info.ceiling_height_m = ceilingHeight(in, survey.data, poses.tracks, result);
        timeOffsets(in, survey.data, poses.tracks, info.ceiling_height_m, result);
        auditPoses(in, survey.data, poses.tracks, info.ceiling_height_m, result);
        if (laser) info.ceiling_time_offset_sigma_s = result.time_offsets.front().applied_sigma_s;
        info.pose_source = result.pose_source;
        const std::string track_name = laser ? std::string("the laser track") : in.poses_file;
        Cameras cameras;
        for (std::size_t i = 0; i < survey.data.size(); ++i) {
            if (!in.traverses[i].reference) continue;
            TraverseReport rep = addTraverse(
                in.traverses[i], survey.data[i], poses.tracks[i], survey.gt[i], poses.starts[i],
                poses.localisation_time_s[i], result.time_offsets.front().applied_sigma_s,
                result.pose_audit, options_, track_name, cameras, writer);
            for (auto& w : traverseWarnings(rep, survey.data[i].rawlog, options_))
                result.warnings.push_back(std::move(w));
            result.traverses.push_back(std::move(rep));
        }
        if (cameras.ceiling) info.ceiling_camera = *cameras.ceiling;
        if (cameras.forward) info.forward_camera = *cameras.forward;
        result.references = writer.size();
        if (result.references == 0) {
            throw std::runtime_error("no references kept (all frames rejected or without pose)");
        }
        result.writing_time_s = timer.Tac();
        result.status = SurveyStatus::Ok;
        result.size_bytes = folderSize(writer.stagingDir());
        result.total_time_s = total.Tac();
        writer.writeTextFile(database::kReport, result.toJson());
        writer.commit(info);
    } catch (const std::exception& e) {
        result.status = SurveyStatus::Failed;
        result.reason = common::errorLine(e);
        result.detail = e.what();
        result.exit_code = common::exitCodeFor(e);
        result.references = 0;
    }
    result.total_time_s = total.Tac();
    return result;
}

}  // namespace lookup::survey

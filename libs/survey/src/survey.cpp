#include "lookup/survey/survey.h"

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

#include <opencv2/imgcodecs.hpp>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"
#include "lookup/survey/keyframes.h"
#include "lookup/survey/mrpt_sections.h"
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

std::optional<mrpt::poses::CPose3D> poseAt(const mrpt::poses::CPose3DInterpolator& interp,
                                           double t) {
    mrpt::math::TPose3D p;
    bool valid = false;
    interp.interpolate(mrpt::Clock::fromDouble(t), p, valid);
    if (!valid) return std::nullopt;
    return mrpt::poses::CPose3D(p);
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

// Quality of a candidate ceiling image; not usable (with `problem` set) when pixelProblem().
ImageQuality ceilingQuality(const mrpt::obs::CObservationImage& obs,
                            const mrpt::img::TCamera* expected, std::string& problem) {
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
    return measureImageQuality(m);
}

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

std::string jsonEscape(const std::string& s) {
    std::string o;
    for (char c : s) {
        if (c == '"' || c == '\\') {
            o += '\\';
            o += c;
        } else if (static_cast<unsigned char>(c) < 0x20) {
            o += ' ';
        } else {
            o += c;
        }
    }
    return o;
}

// One warning line per kind of refused input of a traverse.
void addWarnings(const TraverseReport& r, const std::string& rawlog,
                 std::vector<std::string>& out) {
    const auto& k = r.skipped;
    if (k.lidar_ranges + k.records() > 0) {
        out.push_back(rawlog + ": refused " + std::to_string(k.lidar_ranges) +
                      " non-finite lidar ranges, " + std::to_string(k.scans) + " scans, " +
                      std::to_string(k.odometry) + " odometry records, " +
                      std::to_string(k.ceiling_intrinsics + k.forward_intrinsics) +
                      " images with unusable intrinsics (first: " + k.first + ")");
    }
    if (r.rejected_image + r.rejected_forward > 0) {
        out.push_back(rawlog + ": refused " + std::to_string(r.rejected_image) + " ceiling and " +
                      std::to_string(r.rejected_forward) +
                      " forward images (first: " + r.first_image_problem + ")");
    }
}

std::string statsJson(const PoseErrorStats& s) {
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  "{\"count\": %zu, \"mean_m\": %.4f, \"p95_m\": %.4f, \"max_m\": %.4f, "
                  "\"mean_yaw_deg\": %.3f}",
                  s.count, s.mean_m, s.p95_m, s.max_m, s.mean_yaw_deg);
    return buf;
}

struct TraverseStart {
    std::string source;         ///< "map origin", "ground truth" or "scan match"
    mrpt::poses::CPose2D pose;  ///< grid frame while the laser stage runs, then map frame
    double goodness = 0;        ///< of the scan match
};

// The operator's start pose of the mapping traverse ([survey] start_pose, else the dataset's),
// the origin when neither gives one.
mrpt::poses::CPose2D operatorStart(const SurveyOptions& o, const SurveyInputs& in) {
    const std::string& text = o.start_pose.empty() ? in.start_pose : o.start_pose;
    if (text.empty()) return {};
    if (auto p = parseStartPose(text)) return *p;
    throw common::ConfigError("start_pose '" + text + "': expected three numbers: x y yaw_deg");
}

// Where MCL starts a traverse on the grid: the map's own origin for the traverse that built
// it, the ground truth only as a diagnostic, else its first scans matched against the map.
TraverseStart startInGrid(bool own_map, bool use_gt, const mrpt::poses::CPose2D& gt_start,
                          const mrpt::poses::CPose2D& fallback, const TraverseData& d,
                          const mrpt::maps::COccupancyGridMap2D& grid,
                          const common::PoseTrack& mapping_track, const SurveyOptions& o) {
    if (use_gt) return {"ground truth", gt_start, 0};
    if (own_map) return {"map origin", mrpt::poses::CPose2D(), 0};
    const StartFix fix = findStartInMap(d, grid, mapping_track, fallback, o);
    return {"scan match", fix.pose, fix.goodness};
}

std::string startJson(const TraverseReport& t) {
    if (t.start_source.empty()) return "";
    char buf[200];
    std::snprintf(buf, sizeof(buf),
                  ", \"start\": {\"source\": \"%s\", \"x\": %.3f, \"y\": %.3f, "
                  "\"yaw_deg\": %.2f, \"goodness\": %.3f}",
                  t.start_source.c_str(), t.start.x(), t.start.y(), mrpt::RAD2DEG(t.start.phi()),
                  t.start_goodness);
    return buf;
}

// The cameras' configured time offsets, applied to their stamps as read: every later step
// (pose per image, forward image per reference, the ceiling height) sees the pose clock.
void configuredOffsets(const SurveyOptions& o, TraverseData& d) {
    shiftStamps(d.ceiling, o.ceiling_time_offset_s);
    shiftStamps(d.forward, o.forward_time_offset_s);
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
        o << "; " << c.label << " time offset " << 1e3 * c.offset_s << " ms (" << c.source;
        if (c.source == "estimated") o << " +- " << 1e3 * c.sigma_s << " ms";
        o << ")";
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
    std::ostringstream o;
    o << "{\n  \"status\": \"" << (ok() ? "ok" : "failed") << "\",\n";
    o << "  \"reason\": \"" << jsonEscape(reason) << "\",\n";
    o << "  \"database\": \"" << jsonEscape(out_dir) << "\",\n";
    o << "  \"pose_source\": \"" << jsonEscape(pose_source) << "\",\n";
    o << "  \"references\": " << references << ",\n";
    o << "  \"size_bytes\": " << size_bytes << ",\n";
    o << "  \"time_s\": {\"total\": " << total_time_s << ", \"mapping\": " << mapping_time_s
      << ", \"localisation\": " << localisation_time_s << ", \"writing\": " << writing_time_s
      << "},\n";
    if (pose_graph.keyframes > 0) {
        const auto& g = pose_graph;
        o << "  \"pose_graph\": {\"traverses\": " << g.traverses
          << ", \"keyframes\": " << g.keyframes << ", \"registrations\": " << g.registrations
          << ", \"cross_registrations\": " << g.cross_registrations
          << ", \"rejected_registrations\": " << g.rejected_registrations
          << ", \"initial_cost\": " << g.initial_cost << ", \"final_cost\": " << g.final_cost
          << ", \"time_s\": " << g.time_s
          << ", \"covariance\": " << (g.covariance_ok ? "true" : "false")
          << ", \"covariance_time_s\": " << g.covariance_time_s << "},\n";
    }
    if (!ceiling_source.empty()) {
        o << "  \"ceiling\": " << ceilingJson(ceiling, ceiling_source) << ",\n";
    }
    if (!time_offsets.empty()) {
        o << "  \"time_offsets\": [";
        for (std::size_t i = 0; i < time_offsets.size(); ++i) {
            o << (i ? ",\n    " : "\n    ") << timeOffsetJson(time_offsets[i]);
        }
        o << "\n  ],\n";
    }
    o << "  \"traverses\": [";
    for (std::size_t i = 0; i < traverses.size(); ++i) {
        const auto& t = traverses[i];
        o << (i ? "," : "") << "\n    {\"name\": \"" << jsonEscape(t.name)
          << "\", \"ceiling_frames\": " << t.ceiling_frames
          << ", \"frames_without_pose\": " << t.frames_without_pose
          << ", \"references\": " << t.references << ", \"rejected_blur\": " << t.rejected_blur
          << ", \"rejected_exposure\": " << t.rejected_exposure
          << ", \"rejected_image\": " << t.rejected_image
          << ", \"rejected_forward\": " << t.rejected_forward
          << ", \"without_forward\": " << t.without_forward
          << ",\n     \"skipped\": {\"lidar_ranges\": " << t.skipped.lidar_ranges
          << ", \"scans\": " << t.skipped.scans << ", \"odometry\": " << t.skipped.odometry
          << ", \"ceiling_intrinsics\": " << t.skipped.ceiling_intrinsics
          << ", \"forward_intrinsics\": " << t.skipped.forward_intrinsics << ", \"first\": \""
          << jsonEscape(t.skipped.first) << "\", \"first_image\": \""
          << jsonEscape(t.first_image_problem) << "\"}"
          << ", \"localisation_time_s\": " << t.localisation_time_s << startJson(t)
          << ", \"has_ground_truth\": " << (t.has_ground_truth ? "true" : "false");
        if (t.has_ground_truth) {
            o << ",\n     \"error\": " << statsJson(t.error) << ",\n     \"segments\": [";
            for (std::size_t k = 0; k < t.segments.size(); ++k) {
                const auto& s = t.segments[k];
                char buf[160];
                std::snprintf(buf, sizeof(buf),
                              "{\"from_m\": %.1f, \"to_m\": %.1f, \"x\": %.2f, \"y\": %.2f, ",
                              s.from_m, s.to_m, s.x, s.y);
                o << (k ? ",\n       " : "\n       ") << buf << "\"error\": " << statsJson(s.error)
                  << "}";
            }
            o << "]";
        }
        o << "}";
    }
    o << "\n  ]\n}\n";
    return o.str();
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
    if (in.ceiling_height_m > 0 && options_.use_dataset_ceiling_height) {
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
    if (!options_.ceiling_estimate) {
        result.ceiling_source = "configured";
        result.ceiling.ceiling_height_m = result.ceiling.prior_m = options_.ceiling_height_m;
        return options_.ceiling_height_m;
    }
    std::vector<mrpt::poses::CPose3DInterpolator> interps;
    interps.reserve(data.size());
    std::vector<CeilingTraverse> traverses;
    for (std::size_t i = 0; i < data.size(); ++i) {
        interps.push_back(common::makeInterpolator(tracks[i].poses, options_.max_pose_gap_s));
        if (!in.traverses[i].reference || tracks[i].poses.empty()) continue;
        traverses.push_back({in.traverses[i].name, &data[i].ceiling, &interps.back()});
    }
    result.ceiling = estimateCeilingDistance(traverses, options_);
    result.ceiling_source = result.ceiling.estimated ? "estimated" : "configured";
    if (!result.ceiling.warning.empty()) result.warnings.push_back(result.ceiling.warning);
    return result.ceiling.ceiling_height_m;
}

void Survey::timeOffsets(std::vector<TraverseData>& data, const std::vector<LaserTrack>& tracks,
                         const std::vector<bool>& reference, double ceiling_height_m,
                         SurveyResult& result) const {
    TimeOffsetEstimate ceiling;
    ceiling.label = options_.ceiling_camera_label;
    ceiling.source = "configured";
    ceiling.offset_s = ceiling.configured_s = options_.ceiling_time_offset_s;
    if (options_.time_offset_estimate) {
        std::vector<mrpt::poses::CPose3DInterpolator> interps;
        interps.reserve(data.size());
        std::vector<CeilingTraverse> traverses;
        for (std::size_t i = 0; i < data.size(); ++i) {
            interps.push_back(common::makeInterpolator(tracks[i].poses, options_.max_pose_gap_s));
            if (!reference[i] || tracks[i].poses.empty()) continue;
            traverses.push_back({"", &data[i].ceiling, &interps.back()});
        }
        ceiling = estimateTimeOffset(traverses, ceiling_height_m, options_);
        if (!ceiling.warning.empty()) result.warnings.push_back(ceiling.warning);
        for (auto& d : data) shiftStamps(d.ceiling, ceiling.offset_s - ceiling.configured_s);
    }
    TimeOffsetEstimate forward;
    forward.label = options_.forward_camera_label;
    forward.source = "configured";
    forward.offset_s = forward.configured_s = options_.forward_time_offset_s;
    result.time_offsets = {ceiling, forward};
}

SurveyResult Survey::run(const SurveyInputs& in) const {
    SurveyResult result;
    mrpt::system::CTicTac total;
    result.out_dir = fs::absolute(in.out_dir).lexically_normal().string();
    try {
        if (in.traverses.empty()) throw std::runtime_error("no input traverses");
        if (in.out_dir.empty()) throw common::ConfigError("no output folder given");
        // Leftovers of an interrupted run: the old database put back, stale folders removed.
        for (auto& line : database::recoverInterrupted(in.out_dir)) {
            result.warnings.push_back(std::move(line));
        }
        const bool laser = in.poses_file.empty();

        // 1. Read every traverse (image headers, odometry, scans) and its ground truth.
        std::vector<TraverseData> data;
        std::vector<std::optional<mrpt::poses::CPose3DInterpolator>> gt;
        for (const auto& spec : in.traverses) {
            data.push_back(readTraverse(spec.rawlog, options_, laser && spec.reference));
            configuredOffsets(options_, data.back());
            if (!spec.ground_truth.empty()) {
                gt.emplace_back(common::makeInterpolator(common::readPoseFile(spec.ground_truth),
                                                         options_.max_pose_gap_s));
            } else {
                gt.emplace_back(std::nullopt);
            }
        }

        // 2. Vehicle poses per traverse.
        std::vector<LaserTrack> tracks(data.size());
        std::vector<TraverseStart> result_starts(data.size());
        std::vector<double> localisation_time(data.size(), 0.0);
        std::optional<mrpt::maps::COccupancyGridMap2D> grid;
        mrpt::system::CTicTac timer;
        if (!laser) {
            mrpt::math::CMatrixDouble33 cov;
            cov.setZero();
            cov(0, 0) = cov(1, 1) = std::pow(options_.pose_file_std_xy_m, 2);
            cov(2, 2) = std::pow(mrpt::DEG2RAD(options_.pose_file_std_yaw_deg), 2);
            const auto trackFrom = [&](const std::string& file) {
                LaserTrack track;
                track.poses = common::readPoseFile(file);
                track.covs.assign(track.poses.size(), cov);
                return track;
            };
            if (in.poses_file == kPosesFromGroundTruth) {
                // Each traverse's own surveyed track (e.g. <traverse>.rawlog.GT.txt).
                result.pose_source = "ground-truth files";
                for (std::size_t i = 0; i < tracks.size(); ++i) {
                    if (in.traverses[i].ground_truth.empty()) {
                        throw common::ConfigError(in.traverses[i].rawlog +
                                                  ": --poses ground-truth, but this traverse "
                                                  "has no ground-truth file");
                    }
                    tracks[i] = trackFrom(in.traverses[i].ground_truth);
                }
            } else {
                result.pose_source = "file:" + fs::absolute(in.poses_file).string();
                const LaserTrack file_track = trackFrom(in.poses_file);
                for (auto& t : tracks) t = file_track;
            }
            if (!in.map_file.empty()) grid = loadGridMap(in.map_file);
        } else {
            const auto startOf = [&](std::size_t i,
                                     const mrpt::poses::CPose2D& fallback) -> mrpt::poses::CPose2D {
                if (!options_.start_at_ground_truth || !gt[i]) return fallback;
                const auto& seq = data[i].laser_sequence;
                const double t0 = mrpt::Clock::toDouble(seq.front()->timestamp);
                if (auto p = poseAt(*gt[i], t0)) return mrpt::poses::CPose2D(*p);
                return fallback;
            };
            std::size_t mapping = data.size();
            for (std::size_t i = 0; i < data.size(); ++i) {
                if (in.traverses[i].mapping) {
                    mapping = i;
                    break;
                }
            }
            mrpt::poses::CPose2D map_origin;
            common::PoseTrack mapping_track;  // grid frame: where other traverses are sought
            std::vector<TraverseStart> starts(data.size());
            // Pose-graph tracks per traverse (grid frame), where the graph optimised them.
            std::vector<std::optional<common::PoseTrack>> graph_tracks(data.size());
            std::vector<std::vector<mrpt::math::CMatrixDouble33>> graph_covs(data.size());
            if (!in.map_file.empty()) {
                result.pose_source = "laser+map:" + fs::absolute(in.map_file).string();
                grid = loadGridMap(in.map_file);
            } else {
                if (mapping == data.size()) throw std::runtime_error("no mapping traverse");
                // The mapping traverse needs lidar + odometry even if it is not a reference.
                if (data[mapping].scan_count == 0 || data[mapping].odometry_count == 0) {
                    data[mapping] = readTraverse(in.traverses[mapping].rawlog, options_, true);
                    configuredOffsets(options_, data[mapping]);
                }
                result.pose_source = "laser";
                // ICP-SLAM runs in its own frame (its start = identity: MRPT 2.5.8's pose
                // extrapolator stalls when initialize() is given a start pose); poses are moved
                // into the ground-truth frame by map_origin afterwards.
                map_origin = startOf(mapping, operatorStart(options_, in));
                timer.Tic();
                ProgressBar bar(in.show_progress, "ICP-SLAM " + in.traverses[mapping].name);
                LaserMap icp = buildMapIcpSlam(data[mapping], config_, mrpt::poses::CPose2D(), bar,
                                               options_.icp_max_range_m);
                if (graph_options_.enabled) {
                    ProgressBar graph_bar(in.show_progress,
                                          "pose graph " + in.traverses[mapping].name);
                    const std::vector<GraphTraverse> alone{{&data[mapping], icp.icp_track.poses}};
                    // Its covariances are only kept when no joint graph follows.
                    const bool others = std::any_of(
                        in.traverses.begin(), in.traverses.end(),
                        [&](const auto& t) { return t.reference && &t != &in.traverses[mapping]; });
                    const bool final_poses = graph_options_.all_traverses && !others;
                    std::vector<std::vector<mrpt::math::CMatrixDouble33>> covs;
                    graph_tracks[mapping] =
                        optimisePoseGraph(alone, graph_options_, &result.pose_graph, graph_bar,
                                          final_poses ? &covs : nullptr)[0];
                    if (final_poses) graph_covs[mapping] = covs[0];
                    grid = gridFromTracks(alone, {*graph_tracks[mapping]}, config_);
                } else {
                    grid = std::move(icp.grid);
                }
                mapping_track =
                    graph_tracks[mapping] ? *graph_tracks[mapping] : icp.icp_track.poses;
                result.mapping_time_s = timer.Tac();
            }
            // Poses in the grid's frame first; moved into the map frame at the end.
            const bool joint = graph_tracks[mapping].has_value() && graph_options_.all_traverses;
            for (std::size_t i = 0; i < data.size(); ++i) {
                if (!in.traverses[i].reference || (joint && i == mapping)) continue;
                timer.Tic();
                ProgressBar bar(in.show_progress, "MCL " + in.traverses[i].name);
                const bool own_map = i == mapping && in.map_file.empty();
                const bool use_gt = options_.start_at_ground_truth && gt[i].has_value();
                starts[i] = startInGrid(
                    own_map, use_gt, startOf(i, map_origin) - map_origin,
                    in.map_file.empty() ? mrpt::poses::CPose2D() : operatorStart(options_, in),
                    data[i], *grid, mapping_track, options_);
                tracks[i] = localizeMcl(data[i], *grid, config_, options_, starts[i].pose, bar);
                localisation_time[i] = timer.Tac();
                result.localisation_time_s += localisation_time[i];
            }
            if (joint) {
                // Every reference traverse joins the mapping one in the graph, MCL's poses on
                // the first map as its first estimate; the map is rebuilt from all of them.
                std::vector<GraphTraverse> graph{{&data[mapping], *graph_tracks[mapping]}};
                std::vector<std::size_t> members{mapping};
                for (std::size_t i = 0; i < data.size(); ++i) {
                    if (!in.traverses[i].reference || i == mapping) continue;
                    graph.push_back({&data[i], tracks[i].poses});
                    members.push_back(i);
                }
                if (graph.size() > 1) {
                    timer.Tic();
                    ProgressBar graph_bar(in.show_progress, "pose graph, all traverses");
                    std::vector<std::vector<mrpt::math::CMatrixDouble33>> covs;
                    const auto optimised = optimisePoseGraph(graph, graph_options_,
                                                             &result.pose_graph, graph_bar, &covs);
                    for (std::size_t k = 0; k < members.size(); ++k) {
                        graph_tracks[members[k]] = optimised[k];
                        graph_covs[members[k]] = covs[k];
                    }
                    grid = gridFromTracks(graph, optimised, config_);
                    result.mapping_time_s += timer.Tac();
                }
                // The graph's poses replace MCL's. Their covariance: the graph's marginal one
                // (how far the map may have drifted there, relative to its start) on top of
                // the map's local error.
                const mrpt::math::CMatrixDouble33 floor = mapErrorCovariance(options_);
                for (const std::size_t i : members) {
                    if (!in.traverses[i].reference) continue;
                    tracks[i].poses = *graph_tracks[i];
                    tracks[i].covs.assign(tracks[i].poses.size(), floor);
                    if (graph_covs[i].size() == tracks[i].poses.size()) {
                        for (std::size_t k = 0; k < graph_covs[i].size(); ++k) {
                            tracks[i].covs[k] += graph_covs[i][k];
                        }
                    }
                }
            }
            if (joint) starts[mapping] = {"map origin", mrpt::poses::CPose2D(), 0};
            for (std::size_t i = 0; i < data.size(); ++i)
                starts[i].pose = map_origin + starts[i].pose;
            result_starts = std::move(starts);
            // Into the map frame: poses composed with its origin, (x, y) covariances rotated.
            const mrpt::poses::CPose3D origin3(map_origin);
            mrpt::math::CMatrixDouble33 rotation;
            rotation.setIdentity();
            rotation(0, 0) = rotation(1, 1) = std::cos(map_origin.phi());
            rotation(1, 0) = std::sin(map_origin.phi());
            rotation(0, 1) = -rotation(1, 0);
            for (std::size_t i = 0; i < data.size(); ++i) {
                for (auto& p : tracks[i].poses) p.pose = origin3 + p.pose;
                for (auto& c : tracks[i].covs) {
                    c = mrpt::math::CMatrixDouble33(rotation.asEigen() * c.asEigen() *
                                                    rotation.asEigen().transpose());
                }
            }
        }

        // 3. References: pose per ceiling image, keyframes, forward image, database records.
        timer.Tic();
        database::DatabaseWriter writer(in.out_dir);
        if (grid) writer.setMap(*grid);
        database::DatabaseInfo info;
        info.name = in.name;
        info.ceiling_camera_label = options_.ceiling_camera_label;
        info.forward_camera_label = options_.forward_camera_label;
        info.ceiling_height_m = ceilingHeight(in, data, tracks, result);
        {
            std::vector<bool> reference;
            for (const auto& t : in.traverses) reference.push_back(t.reference);
            timeOffsets(data, tracks, reference, info.ceiling_height_m, result);
        }
        info.pose_source = result.pose_source;
        {
            mrpt::config::CConfigFileMemory used;
            options_.saveToConfigFile(used, "survey");
            info.options_ini = used.getContent();
        }
        bool have_intrinsics = false, have_forward_intrinsics = false;
        for (std::size_t i = 0; i < data.size(); ++i) {
            const auto& spec = in.traverses[i];
            info.source_rawlogs.push_back(fs::absolute(spec.rawlog).string());
            if (!spec.reference) continue;
            const auto& d = data[i];
            TraverseReport rep;
            rep.name = spec.name;
            rep.ceiling_frames = d.ceiling.size();
            rep.has_ground_truth = gt[i].has_value();
            rep.localisation_time_s = localisation_time[i];
            rep.start_source = result_starts[i].source;
            rep.start = result_starts[i].pose;
            rep.start_goodness = result_starts[i].goodness;
            const auto& track = tracks[i];
            if (track.poses.empty()) {
                throw common::RawlogError(d.rawlog, "no vehicle poses (no lidar scans localised)");
            }
            const auto interp = common::makeInterpolator(track.poses, options_.max_pose_gap_s);
            std::vector<double> track_times;
            for (const auto& p : track.poses) track_times.push_back(p.time_s);

            std::vector<KeyframeCandidate> candidates;
            std::vector<std::size_t> frame_of;  // candidate -> ceiling frame
            std::optional<std::size_t> first_outside;
            for (std::size_t f = 0; f < d.ceiling.size(); ++f) {
                const double t = mrpt::Clock::toDouble(d.ceiling[f]->timestamp);
                if (auto p = poseAt(interp, t)) {
                    candidates.push_back({t, *p});
                    frame_of.push_back(f);
                } else {
                    ++rep.frames_without_pose;
                    if (!first_outside) first_outside = f;
                }
            }
            if (rep.frames_without_pose > options_.max_outside_fraction * d.ceiling.size()) {
                const std::size_t f = *first_outside;
                throw common::RawlogError(
                    d.rawlog, d.ceiling_records[f],
                    "mismatched time stamps: " + std::to_string(rep.frames_without_pose) + " of " +
                        std::to_string(d.ceiling.size()) + " " + options_.ceiling_camera_label +
                        " images (first at t=" +
                        std::to_string(mrpt::Clock::toDouble(d.ceiling[f]->timestamp)) +
                        " s) have no pose in [" + std::to_string(track_times.front()) + ", " +
                        std::to_string(track_times.back()) + "] s of " +
                        (laser ? std::string("the laser track") : in.poses_file));
            }
            const auto selection = selectKeyframes(candidates, options_, [&](std::size_t c) {
                std::string problem;
                const auto q =
                    ceilingQuality(*d.ceiling[frame_of[c]],
                                   have_intrinsics ? &info.ceiling_camera : nullptr, problem);
                if (!problem.empty() && rep.first_image_problem.empty()) {
                    rep.first_image_problem = problem;
                }
                // The first usable image fixes the database's camera.
                if (q.usable && !have_intrinsics) {
                    info.ceiling_camera = d.ceiling[frame_of[c]]->cameraParams;
                    have_intrinsics = true;
                }
                return q;
            });
            rep.rejected_image = selection.rejected_unusable;
            rep.skipped = d.skipped;
            rep.rejected_blur = selection.rejected_blur;
            rep.rejected_exposure = selection.rejected_exposure;

            std::vector<double> forward_times;
            for (const auto& fw : d.forward)
                forward_times.push_back(mrpt::Clock::toDouble(fw->timestamp));
            std::vector<int> forward_state(d.forward.size(), 0);  // 0 unknown, 1 ok, -1 refused
            const auto forwardUsable = [&](std::size_t fi) {
                if (forward_state[fi] == 0) {
                    const auto& fw = *d.forward[fi];
                    cv::Mat m;
                    try {
                        m = loadPixels(fw, cv::IMREAD_UNCHANGED);
                    } catch (const std::exception&) {
                        m = cv::Mat();
                    }
                    const std::string problem = pixelProblem(
                        fw, m, have_forward_intrinsics ? &info.forward_camera : nullptr);
                    forward_state[fi] = problem.empty() ? 1 : -1;
                    if (!problem.empty()) {
                        ++rep.rejected_forward;
                        if (rep.first_image_problem.empty()) rep.first_image_problem = problem;
                    }
                }
                return forward_state[fi] > 0;
            };

            std::vector<double> err_m, err_yaw, travelled;
            std::vector<mrpt::poses::CPose3D> ref_poses;
            for (std::size_t k = 0; k < selection.kept.size(); ++k) {
                const std::size_t c = selection.kept[k];
                const auto& ceiling = d.ceiling[frame_of[c]];
                database::ReferenceInput ref;
                ref.traverse = spec.name;
                ref.ceiling = ceiling;
                ref.vehicle_pose = candidates[c].vehicle_pose;
                ref.vehicle_cov = track.covs[nearestIndex(track_times, candidates[c].time_s)];
                ref.sharpness = selection.kept_quality[k].sharpness;
                ref.mean_intensity = selection.kept_quality[k].mean_intensity;
                ref.travelled_m = selection.kept_travelled_m[k];
                if (!forward_times.empty()) {
                    const std::size_t fi = nearestIndex(forward_times, candidates[c].time_s);
                    if (std::abs(forward_times[fi] - candidates[c].time_s) <=
                            options_.forward_max_dt_s &&
                        forwardUsable(fi)) {
                        ref.forward = d.forward[fi];
                        ref.forward_vehicle_pose =
                            poseAt(interp, forward_times[fi]).value_or(ref.vehicle_pose);
                        if (!have_forward_intrinsics) {
                            info.forward_camera = ref.forward->cameraParams;
                            have_forward_intrinsics = true;
                        }
                    }
                }
                if (!ref.forward) ++rep.without_forward;
                writer.add(ref);
                if (gt[i]) {
                    if (auto truth = poseAt(*gt[i], candidates[c].time_s)) {
                        const double dx = truth->x() - ref.vehicle_pose.x();
                        const double dy = truth->y() - ref.vehicle_pose.y();
                        err_m.push_back(std::hypot(dx, dy));
                        err_yaw.push_back(std::abs(mrpt::RAD2DEG(
                            mrpt::math::wrapToPi(truth->yaw() - ref.vehicle_pose.yaw()))));
                        travelled.push_back(ref.travelled_m);
                        ref_poses.push_back(ref.vehicle_pose);
                    }
                }
            }
            rep.references = selection.kept.size();
            if (gt[i]) {
                rep.error = statsOf(err_m, err_yaw);
                // Per 10 m of travel, to show where the laser poses degrade.
                constexpr double kSegment_m = 10.0;
                std::size_t b = 0;
                while (b < err_m.size()) {
                    const double from = std::floor(travelled[b] / kSegment_m) * kSegment_m;
                    std::size_t e = b;
                    while (e < err_m.size() && travelled[e] < from + kSegment_m) ++e;
                    SegmentError seg;
                    seg.from_m = from;
                    seg.to_m = from + kSegment_m;
                    const auto& mid = ref_poses[(b + e) / 2];
                    seg.x = mid.x();
                    seg.y = mid.y();
                    seg.error = statsOf({err_m.begin() + b, err_m.begin() + e},
                                        {err_yaw.begin() + b, err_yaw.begin() + e});
                    rep.segments.push_back(seg);
                    b = e;
                }
            }
            addWarnings(rep, d.rawlog, result.warnings);
            result.traverses.push_back(rep);
        }
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

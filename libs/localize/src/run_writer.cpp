#include "lookup/localize/run_writer.h"
#include <limits>

#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>

#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/grey.h"
#include "lookup/eval/run_io.h"
#include "lookup/obs/observation_lookup_result.h"

namespace lookup::localize {
namespace fs = std::filesystem;

namespace {

void writeTumRow(common::OutputFile& f, double t, const mrpt::poses::CPose2D& p, double z = 0) {
    // Planar pose (rotation about z only) at the floor's height where one is known.
    char height[32] = "0";
    if (z != 0) std::snprintf(height, sizeof height, "%.4f", z);
    f.printf("%.6f %.5f %.5f %s 0 0 %.9f %.9f\n", t, p.x(), p.y(), height, std::sin(p.phi() / 2),
             std::cos(p.phi() / 2));
}

std::string withoutSlash(std::string dir) {
    while (dir.size() > 1 && dir.back() == '/') dir.pop_back();
    return dir;
}

/// What an interrupted run may have left beside `out`: a half-written `.partial` run (removed)
/// and, after a kill between the two renames of RunWriter::publish, the previous run as
/// `.old` with nothing at `out` (restored).
void removeLeftovers(const std::string& out) {
    std::error_code ec;
    const std::string old = out + ".old", partial = out + ".partial";
    if (fs::exists(old)) {
        if (!fs::exists(out)) {
            fs::rename(old, out, ec);
            if (ec) throw common::WriteError(old, "cannot restore to " + out + ": " + ec.message());
            std::cerr << "lookup-localize: note: restored " << out << " from " << old
                      << " (a run was interrupted while replacing it)\n";
        } else {
            fs::remove_all(old, ec);
            std::cerr << "lookup-localize: note: removed " << old
                      << ", left by an interrupted run\n";
        }
    }
    if (fs::exists(partial)) {
        std::cerr << "lookup-localize: note: removing " << partial
                  << ", the unfinished run folder of an earlier start that failed or was killed\n";
        fs::remove_all(partial, ec);
        if (ec) throw common::WriteError(partial, "cannot remove: " + ec.message());
    }
}

/// `out` may be replaced only when it is absent, empty or a run folder.
void checkReplaceable(const std::string& out) {
    if (!fs::exists(out)) return;
    if (!fs::is_directory(out)) {
        throw common::ConfigError("--out " + out + ": exists and is not a folder");
    }
    if (fs::is_empty(out)) return;
    for (const char* f : {"frames.csv", "timing.json", "run.ini"}) {
        if (fs::exists(fs::path(out) / f)) return;
    }
    throw common::ConfigError("--out " + out +
                              ": not a run folder (no frames.csv, timing.json or run.ini) and "
                              "it would be replaced; give a new or a run folder");
}

obs::LookupStatus toLookupStatus(FrameStatus s) {
    switch (s) {
        case FrameStatus::Refined:
            return obs::LookupStatus::Refined;
        case FrameStatus::Fallback:
            return obs::LookupStatus::CoarseOnly;
        default:
            return obs::LookupStatus::Failed;
    }
}

}  // namespace

cv::Mat drawFlowOverlay(const cv::Mat& query_grey, const refine::RefineResult& result) {
    cv::Mat canvas;
    cv::cvtColor(query_grey, canvas, cv::COLOR_GRAY2BGR);
    for (const auto& ref : result.references) {
        for (const auto& m : ref.matches) {
            if (!m.matched()) {
                cv::circle(canvas, m.reference_px, 2, cv::Scalar(255, 0, 0), -1);  // blue
                continue;
            }
            const cv::Scalar colour = m.inlier ? cv::Scalar(0, 200, 0) : cv::Scalar(150, 150, 150);
            cv::arrowedLine(canvas, m.reference_px, m.query_px, colour, 1, cv::LINE_AA, 0, 0.2);
        }
    }
    return canvas;
}

RunWriter::RunWriter(const std::string& out_dir, const std::string& run_ini_text,
                     bool write_debug_images, int debug_image_every)
    : final_dir_(withoutSlash(out_dir)),
      dir_(final_dir_ + ".partial"),
      debug_images_(write_debug_images),
      debug_every_(debug_image_every) {
    removeLeftovers(final_dir_);
    checkReplaceable(final_dir_);
    std::error_code ec;
    fs::create_directories(dir_, ec);
    if (ec) throw common::WriteError(dir_, "cannot create: " + ec.message());
    common::OutputFile ini(dir_ + "/run.ini");
    ini.write(run_ini_text);
    ini.close();
    frames_csv_ = std::make_unique<common::OutputFile>(dir_ + "/frames.csv");
    frames_csv_->write(eval::framesCsvHeader() + "\n");
    frames_csv_->flush();
    poses_tum_ = std::make_unique<common::OutputFile>(dir_ + "/poses.tum");
    coarse_tum_ = std::make_unique<common::OutputFile>(dir_ + "/coarse.tum");
    results_ = std::make_unique<common::RawlogWriter>(dir_ + "/results.rawlog");
}

RunWriter::~RunWriter() = default;

void RunWriter::cleanLeftovers(const std::string& out_dir) {
    removeLeftovers(withoutSlash(out_dir));
}

void RunWriter::write(const FrameResult& frame, const mrpt::obs::CObservationImage* query) {
    eval::FrameRow row;
    row.time_s = frame.time_s;
    row.status = toString(frame.status);
    row.reason = frame.reason;
    row.has_pose = frame.has_pose;
    if (frame.has_pose) {
        const auto& m = frame.pose.mean;
        const auto& c = frame.pose.cov;
        row.x = m.x(), row.y = m.y(), row.yaw = m.phi();
        row.cov_xx = c(0, 0), row.cov_xy = c(0, 1), row.cov_yy = c(1, 1), row.cov_tt = c(2, 2);
        row.has_z = frame.height_m.has_value();
        row.z = frame.height_m.value_or(0.0);
        writeTumRow(*poses_tum_, frame.time_s, m, row.z);
    }
    if (frame.coarse_pose) {
        row.has_coarse = true;
        row.coarse_x = frame.coarse_pose->x();
        row.coarse_y = frame.coarse_pose->y();
        row.coarse_yaw = frame.coarse_pose->phi();
        writeTumRow(*coarse_tum_, frame.time_s, *frame.coarse_pose);
    }
    row.inlier_share = frame.inlier_share;
    row.references = static_cast<int>(frame.reference_indices.size());
    row.ms = frame.times.total_ms;
    frames_csv_->write(eval::formatFramesCsvRow(row) + "\n");
    for (auto* f : {frames_csv_.get(), poses_tum_.get(), coarse_tum_.get()}) f->flush();

    const auto stamp = mrpt::Clock::fromDouble(frame.time_s);
    if (frame.has_pose) {
        mrpt::obs::CObservationRobotPose pose_obs;
        pose_obs.sensorLabel = "LOOKUP_POSE";
        pose_obs.timestamp = stamp;
        pose_obs.pose = mrpt::poses::CPose3DPDFGaussian(frame.pose);
        pose_obs.pose.mean.z(frame.height_m.value_or(0.0));
        results_->write(pose_obs);
    }
    obs::CObservationLookupResult result;
    result.sensorLabel = "LOOKUP_RESULT";
    result.timestamp = stamp;
    result.pose = mrpt::poses::CPose3DPDFGaussian(frame.pose);
    result.pose.mean.z(frame.height_m.value_or(0.0));
    result.status = toLookupStatus(frame.status);
    result.reason = frame.reason;
    result.processing_time_s = frame.times.total_ms / 1e3;
    result.sensorPose = frame.camera_on_vehicle;
    if (frame.refinement) {
        result.ceiling_distance_m = frame.refinement->estimate.ceiling_height_m;
        for (const auto& ref : frame.refinement->references) {
            obs::ReferenceEvidence ev;
            ev.reference_id = static_cast<uint32_t>(ref.id);
            for (const auto& m : ref.matches) {
                if (!m.matched()) continue;
                (m.inlier ? ev.inliers : ev.outliers)++;
                result.flows.push_back({ev.reference_id, m.reference_px.x, m.reference_px.y,
                                        m.query_px.x, m.query_px.y, m.inlier});
            }
            result.references.push_back(ev);
        }
    }
    results_->write(result);

    if (debug_images_ && query != nullptr && frame.refinement &&
        frame_count_ % static_cast<std::size_t>(debug_every_) == 0) {
        mrpt::obs::CObservationImage overlay;
        overlay.sensorLabel = "LOOKUP_FLOW";
        overlay.timestamp = stamp;
        overlay.cameraParams = query->cameraParams;
        overlay.cameraPose = query->cameraPose;
        const cv::Mat grey = common::greyOf(query->image.asCvMatRef());
        overlay.image =
            mrpt::img::CImage(drawFlowOverlay(grey, *frame.refinement), mrpt::img::DEEP_COPY);
        char name[64];
        std::snprintf(name, sizeof name, "flow_%06zu.png", frame_count_);
        results_->writeWithExternalImage(overlay, name);
    }
    ++frame_count_;
}

void RunWriter::finish(const RunTiming& t) {
    results_->close();
    for (auto* f : {frames_csv_.get(), poses_tum_.get(), coarse_tum_.get()}) f->close();
    const double n = std::max<std::size_t>(t.processed(), 1);
    nlohmann::json j;
    j["frames"] = t.frames;
    j["frames_dropped"] = t.frames_dropped;
    j["startup_s"] = t.startup_s;
    j["wall_s"] = t.wall_s;
    j["frames_per_s"] = t.wall_s > 0 ? t.processed() / t.wall_s : 0.0;
    j["ms_per_frame"] = {{"coarse", t.coarse_ms / n},
                         {"select", t.select_ms / n},
                         {"refine", t.refine_ms / n},
                         {"place", t.place_ms / n},
                         {"total", t.total_ms / n}};
    for (const auto& [stage, ms] : t.refine_stage_ms) j["refine_ms_per_frame"][stage] = ms / n;
    if (!t.cold_start_frames.empty()) {
        const auto& c = t.cold_start_frames;
        const auto within = [&c](int n) {
            return std::count_if(c.begin(), c.end(), [n](int f) { return f >= 0 && f < n; });
        };
        j["cold_starts"] = {{"count", c.size()},
                            {"fixed_within_3_frames", within(3)},
                            {"fixed", within(std::numeric_limits<int>::max())},
                            {"frames_to_fix", c}};
    }
    j["skipped"] = nlohmann::json::object();
    for (const auto& [kind, count] : t.skipped) j["skipped"][kind] = count;
    if (!t.online_refresh.empty()) j["online_refresh"] = t.online_refresh;
    if (!t.camera_time_offset.empty()) j["camera_time_offset"] = t.camera_time_offset;
    if (!t.readout.empty()) j["readout"] = t.readout;
    if (!t.lens.empty()) j["lens"] = t.lens;
    // Last: its presence, with the frame count, marks the run complete (lookup-eval checks).
    common::writeFileAtomically(dir_ + "/timing.json", j.dump(2) + "\n");
    common::syncDirectory(dir_);
    publish();
}

void RunWriter::publish() {
    const std::string old = final_dir_ + ".old";
    std::error_code ec;
    const bool replacing = fs::exists(final_dir_);
    if (replacing) {
        fs::rename(final_dir_, old, ec);
        if (ec) throw common::WriteError(final_dir_, "cannot move aside: " + ec.message());
    }
    fs::rename(dir_, final_dir_, ec);
    if (ec) {
        std::error_code back;
        if (replacing) fs::rename(old, final_dir_, back);
        throw common::WriteError(final_dir_,
                                 "cannot rename " + dir_ + " into place: " + ec.message());
    }
    common::syncDirectory(fs::absolute(final_dir_).parent_path().string());
    if (replacing) {
        fs::remove_all(old, ec);
        if (ec) {
            std::cerr << "lookup-localize: warning: " << old
                      << ": previous run not removed: " << ec.message() << "\n";
        }
    }
}

}  // namespace lookup::localize

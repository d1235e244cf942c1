#include "lookup/localize/run_writer.h"

#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/poses/CPose3DPDFGaussian.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>

#include "lookup/eval/run_io.h"
#include "lookup/obs/observation_lookup_result.h"

namespace lookup::localize {
namespace fs = std::filesystem;

namespace {

std::FILE* openOrThrow(const std::string& path) {
    std::FILE* f = std::fopen(path.c_str(), "w");
    if (f == nullptr) throw std::runtime_error(path + ": cannot open for writing");
    return f;
}

void writeTumRow(std::FILE* f, double t, const mrpt::poses::CPose2D& p) {
    // Planar pose: rotation about z only.
    std::fprintf(f, "%.6f %.5f %.5f 0 0 0 %.9f %.9f\n", t, p.x(), p.y(), std::sin(p.phi() / 2),
                 std::cos(p.phi() / 2));
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
    : dir_(out_dir), debug_images_(write_debug_images), debug_every_(debug_image_every) {
    std::error_code ec;
    fs::create_directories(dir_, ec);
    if (ec) throw std::runtime_error(dir_ + ": cannot create: " + ec.message());
    std::ofstream(dir_ + "/run.ini") << run_ini_text;
    frames_csv_ = openOrThrow(dir_ + "/frames.csv");
    std::fprintf(frames_csv_, "%s\n", eval::framesCsvHeader().c_str());
    poses_tum_ = openOrThrow(dir_ + "/poses.tum");
    coarse_tum_ = openOrThrow(dir_ + "/coarse.tum");
    results_ = std::make_unique<common::RawlogWriter>(dir_ + "/results.rawlog");
}

RunWriter::~RunWriter() {
    for (std::FILE* f : {frames_csv_, poses_tum_, coarse_tum_}) {
        if (f != nullptr) std::fclose(f);
    }
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
        writeTumRow(poses_tum_, frame.time_s, m);
    }
    if (frame.coarse_pose) {
        row.has_coarse = true;
        row.coarse_x = frame.coarse_pose->x();
        row.coarse_y = frame.coarse_pose->y();
        row.coarse_yaw = frame.coarse_pose->phi();
        writeTumRow(coarse_tum_, frame.time_s, *frame.coarse_pose);
    }
    row.inlier_share = frame.inlier_share;
    row.references = static_cast<int>(frame.reference_indices.size());
    row.ms = frame.times.total_ms;
    std::fprintf(frames_csv_, "%s\n", eval::formatFramesCsvRow(row).c_str());
    for (std::FILE* f : {frames_csv_, poses_tum_, coarse_tum_}) std::fflush(f);

    const auto stamp = mrpt::Clock::fromDouble(frame.time_s);
    if (frame.has_pose) {
        mrpt::obs::CObservationRobotPose pose_obs;
        pose_obs.sensorLabel = "LOOKUP_POSE";
        pose_obs.timestamp = stamp;
        pose_obs.pose = mrpt::poses::CPose3DPDFGaussian(frame.pose);
        results_->write(pose_obs);
    }
    obs::CObservationLookupResult result;
    result.sensorLabel = "LOOKUP_RESULT";
    result.timestamp = stamp;
    result.pose = mrpt::poses::CPose3DPDFGaussian(frame.pose);
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
        cv::Mat grey = query->image.asCvMatRef();
        if (grey.channels() == 3) cv::cvtColor(grey, grey, cv::COLOR_BGR2GRAY);
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
    const double n = std::max<std::size_t>(t.frames - t.frames_dropped, 1);
    nlohmann::json j;
    j["frames"] = t.frames;
    j["frames_dropped"] = t.frames_dropped;
    j["startup_s"] = t.startup_s;
    j["wall_s"] = t.wall_s;
    j["frames_per_s"] = t.wall_s > 0 ? (t.frames - t.frames_dropped) / t.wall_s : 0.0;
    j["ms_per_frame"] = {{"coarse", t.coarse_ms / n},
                         {"select", t.select_ms / n},
                         {"refine", t.refine_ms / n},
                         {"total", t.total_ms / n}};
    for (const auto& [stage, ms] : t.refine_stage_ms) j["refine_ms_per_frame"][stage] = ms / n;
    j["skipped"] = nlohmann::json::object();
    for (const auto& [kind, count] : t.skipped) j["skipped"][kind] = count;
    std::ofstream(dir_ + "/timing.json") << j.dump(2) << "\n";
}

}  // namespace lookup::localize

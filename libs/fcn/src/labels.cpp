#include "lookup/fcn/labels.h"

#include <mrpt/obs/CObservationImage.h>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include "lookup/common/camera_params.h"
#include "lookup/common/grey.h"
#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/refine/geometry.h"
#include "lookup/refine/matcher.h"
#include "lookup/refine/rectifier.h"

namespace lookup::fcn {
namespace {

struct QueryFrame {
    std::size_t record = 0;
    double time_s = 0;
    mrpt::poses::CPose3D vehicle_in_map;
    mrpt::obs::CObservationImage::Ptr obs;
};

cv::Mat greyOf(const mrpt::obs::CObservationImage& obs, const std::string& where) {
    cv::Mat grey;
    try {
        const cv::Mat& m = obs.image.asCvMatRef();  // loads an external image
        grey = m.channels() == 1 ? m.clone() : common::greyOf(m);
    } catch (const std::exception& e) {
        throw std::runtime_error(where + ": cannot read the ceiling image: " + e.what());
    }
    if (grey.empty() || grey.type() != CV_8UC1) {
        throw std::runtime_error(where + ": ceiling image is empty or not 8-bit");
    }
    return grey;
}

// Every `stride`-th ceiling frame of one training rawlog, without its pose yet.
std::vector<QueryFrame> readQueryFrames(const std::string& rawlog, const std::string& label,
                                        int stride) {
    std::vector<QueryFrame> frames;
    common::RawlogReader reader(rawlog);
    mrpt::obs::CObservation::Ptr obs;
    std::size_t ceiling = 0;
    while (reader.next(obs)) {
        auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(obs);
        if (!img || img->sensorLabel != label) continue;
        if (ceiling++ % stride != 0) continue;
        QueryFrame f;
        f.record = reader.recordIndex();
        f.time_s = mrpt::Clock::toDouble(img->timestamp);
        f.obs = img;
        frames.push_back(std::move(f));
    }
    if (frames.empty()) {
        throw std::runtime_error(rawlog + ": no ceiling images labelled '" + label + "'");
    }
    return frames;
}

// The survey's own poses of the traverse recorded while `frames` were: the references of the
// database's traverse with the most references in their time span.
common::PoseTrack surveyPoses(const database::ReferenceDatabase& db,
                              const std::vector<QueryFrame>& frames, std::string& traverse) {
    const double t0 = frames.front().time_s, t1 = frames.back().time_s;
    std::map<std::string, common::PoseTrack> by_traverse;
    for (const auto& r : db.references()) {
        if (r.time_s >= t0 && r.time_s <= t1)
            by_traverse[r.traverse].push_back({r.time_s, r.vehicle_pose});
    }
    common::PoseTrack best;
    for (auto& [name, track] : by_traverse) {
        if (track.size() > best.size()) {
            best = std::move(track);
            traverse = name;
        }
    }
    std::sort(best.begin(), best.end(),
              [](const auto& a, const auto& b) { return a.time_s < b.time_s; });
    return best;
}

// Gives each frame its vehicle pose: from `pose_file` (TUM or MRPT) when given, else from the
// survey of the traverse recorded during the rawlog. Frames without one are dropped.
void attachPoses(std::vector<QueryFrame>& frames, const database::ReferenceDatabase& db,
                 const std::string& rawlog, const std::string& pose_file) {
    std::string source = pose_file, traverse;
    const common::PoseTrack track =
        pose_file.empty() ? surveyPoses(db, frames, traverse) : common::readPoseFile(pose_file);
    if (pose_file.empty()) source = db.directory() + " traverse '" + traverse + "'";
    if (track.size() < 2 && !pose_file.empty()) {
        throw std::runtime_error(pose_file + ": fewer than 2 poses (the poses of " + rawlog + ")");
    }
    if (track.size() < 2) {
        throw std::runtime_error(rawlog + ": its poses are unknown: no survey traverse of " +
                                 db.directory() +
                                 " was recorded during it and no pose file was given "
                                 "(--train-poses)");
    }
    const auto interp = common::makeInterpolator(track, 1.0);
    std::vector<QueryFrame> posed;
    for (auto& f : frames) {
        bool valid = false;
        interp.interpolate(f.obs->timestamp, f.vehicle_in_map, valid);
        if (valid) posed.push_back(std::move(f));
    }
    if (posed.empty()) {
        throw std::runtime_error(rawlog + ": none of its " + std::to_string(frames.size()) +
                                 " ceiling images lies within the time span of " + source);
    }
    frames = std::move(posed);
}

// A RANSAC inlier within `precise_px` of the fitted homography (any inlier if 0): the points
// that match precisely and lie on the plane, so that the network learns to prefer them.
bool isTarget(const refine::PointMatch& m, double residual_px, double precise_px) {
    return m.inlier && (precise_px <= 0 || residual_px <= precise_px);
}

// Whether the pair must be labelled on rectified images.
bool rectifying(const PairCameras* cameras) {
    if (!cameras) return false;
    const auto& r = cameras->reference;
    if (refine::hasDistortion(r) || refine::hasDistortion(cameras->query)) return true;
    // A query camera of another size or focal length (another vehicle's, or one finer than
    // the database stores).
    return common::cameraProblem(r).empty() && r.ncols > 0 && r.nrows > 0 &&
           !refine::Rectifier(r).isIdentity(cameras->query);
}

// Reference points of the rectified image moved to where the raw reference records them;
// those whose patch would leave the raw image are dropped (the network scores raw pixels).
void toRawReference(std::vector<refine::PointMatch>& matches, std::vector<double>& residual_px,
                    const mrpt::img::TCamera& camera, int margin_px) {
    std::vector<cv::Point2f> rectified;
    for (const auto& m : matches) rectified.push_back(m.reference_px);
    const auto raw = refine::distortPixels(rectified, camera);
    std::size_t kept = 0;
    for (std::size_t i = 0; i < matches.size(); ++i) {
        const cv::Point2d& p = raw[i];
        if (!(p.x >= margin_px && p.y >= margin_px && p.x < int(camera.ncols) - margin_px &&
              p.y < int(camera.nrows) - margin_px)) {
            continue;
        }
        matches[kept] = matches[i];
        matches[kept].reference_px = cv::Point2f(p);
        residual_px[kept++] = residual_px[i];
    }
    matches.resize(kept);
    residual_px.resize(kept);
}

/// The ceiling homography the poses predict from the reference into the query; on a grade
/// (3-D poses) with the ceiling parallel to their floor.
cv::Matx33d priorHomography(const database::Reference& ref, const refine::Pinhole& ref_camera,
                            const QueryFrame& f, const refine::Pinhole& query_camera, double h) {
    const auto floor = refine::floorFrame({ref.vehicle_pose, f.vehicle_in_map});
    if (!floor) {
        return refine::ceilingHomography(ref_camera, ref.ceiling_camera_pose, query_camera,
                                         f.vehicle_in_map + f.obs->cameraPose, h);
    }
    return refine::ceilingHomography(
        ref_camera, refine::inFloorFrame(ref.vehicle_pose, *floor) + ref.ceiling_camera_mount,
        query_camera, refine::inFloorFrame(f.vehicle_in_map, *floor) + f.obs->cameraPose, h);
}

}  // namespace

mrpt::img::TCamera labelCamera(const PairCameras& cameras) {
    return rectifying(&cameras) ? refine::idealPinhole(cameras.reference) : cameras.query;
}

PairLabels labelPair(const cv::Mat& reference, const cv::Mat& query, const LabelOptions& options,
                     const cv::Matx33d* reference_to_query, const PairCameras* cameras) {
    CV_Assert(reference.type() == CV_8UC1 && query.type() == CV_8UC1);
    const bool rectify = rectifying(cameras);
    const int levels = refine::effectivePyramidLevels(options.matcher);
    std::optional<refine::Rectifier> rectifier;
    if (rectify) rectifier.emplace(cameras->reference);
    const auto ref = refine::ImagePyramid::build(
        rectify ? rectifier->rectify(reference, cameras->reference) : reference, levels,
        options.matcher);
    const auto qry = refine::ImagePyramid::build(
        rectify ? rectifier->rectify(query, cameras->query) : query, levels, options.matcher);
    std::vector<cv::Point2f> points;
    const int margin = options.matcher.patch_px / 2;
    for (int y = margin; y + margin < reference.rows; y += options.grid_step_px) {
        for (int x = margin; x + margin < reference.cols; x += options.grid_step_px) {
            points.emplace_back(float(x), float(y));
        }
    }
    // Matched as the localiser matches them: with the motion-compensating warp the patches of
    // another camera height or heading are aligned before SAD compares them.
    const bool warp = reference_to_query && options.matcher.compensate_motion;
    std::vector<cv::Point2f> offsets;
    if (reference_to_query && !warp) {
        offsets.reserve(points.size());
        for (const auto& p : points) {
            const cv::Vec3d q = (*reference_to_query) * cv::Vec3d(p.x, p.y, 1.0);
            offsets.emplace_back(
                q[2] > 1e-9 ? cv::Point2f(float(q[0] / q[2] - p.x), float(q[1] / q[2] - p.y))
                            : cv::Point2f(0, 0));
        }
    }
    PairLabels out;
    out.matches = warp ? refine::matchPointsCompensated(ref, qry, points, *reference_to_query,
                                                        options.matcher)
                       : refine::matchPoints(ref, qry, points, offsets, options.matcher);
    out.fit = refine::estimateHomography(out.matches, options.homography);
    out.residual_px.assign(out.matches.size(), std::numeric_limits<double>::infinity());
    for (std::size_t i = 0; i < out.matches.size(); ++i) {
        const auto& m = out.matches[i];
        cv::Point2d predicted;
        if (out.fit.ok && m.matched() &&
            refine::applyHomography(out.fit.H, cv::Point2d(m.reference_px), predicted)) {
            out.residual_px[i] = cv::norm(predicted - cv::Point2d(m.query_px));
        }
    }
    if (rectify) toRawReference(out.matches, out.residual_px, cameras->reference, margin);
    return out;
}

LabelSet generateLabels(const database::ReferenceDatabase& db,
                        const std::vector<std::string>& rawlogs,
                        const std::vector<std::string>& pose_files, const LabelOptions& options,
                        const ProgressFn& progress) {
    const auto t0 = std::chrono::steady_clock::now();
    options.check();
    LabelSet out;
    refine::Pinhole ref_camera;
    std::string why;
    if (!refine::pinholeFrom(db.info().ceiling_camera, ref_camera, &why)) {
        throw std::runtime_error(db.directory() + "/db.ini [ceiling_camera]: " + why);
    }
    const double h = db.info().ceiling_height_m;

    struct Job {
        const std::string* rawlog;
        QueryFrame* frame;
        bool held_out;
    };
    std::vector<std::vector<QueryFrame>> all_frames;
    std::vector<Job> jobs;
    if (!pose_files.empty() && pose_files.size() != rawlogs.size()) {
        throw std::runtime_error(std::to_string(pose_files.size()) + " pose files for " +
                                 std::to_string(rawlogs.size()) + " training rawlogs");
    }
    for (std::size_t r = 0; r < rawlogs.size(); ++r) {
        all_frames.push_back(
            readQueryFrames(rawlogs[r], db.info().ceiling_camera_label, options.query_stride));
        attachPoses(all_frames.back(), db, rawlogs[r], pose_files.empty() ? "" : pose_files[r]);
    }
    for (std::size_t r = 0; r < rawlogs.size(); ++r) {
        auto& frames = all_frames[r];
        const double split =
            frames.front().time_s +
            (1.0 - options.held_out_share) * (frames.back().time_s - frames.front().time_s);
        for (auto& f : frames) jobs.push_back({&rawlogs[r], &f, f.time_s >= split});
    }

    std::size_t done = 0;
    for (const Job& job : jobs) {
        QueryFrame& f = *job.frame;
        ++out.stats.query_frames;
        // Nearest references in space, skipping the same moment of the same survey traverse.
        std::vector<database::Neighbour> chosen;
        for (const auto& n : db.nearest(f.vehicle_in_map, options.references_per_query + 8)) {
            if (n.distance > options.max_reference_distance_m) break;
            if (std::abs(db.reference(n.index).time_s - f.time_s) < options.min_time_gap_s) {
                continue;
            }
            chosen.push_back(n);
            if (int(chosen.size()) == options.references_per_query) break;
        }
        if (chosen.empty()) {
            ++out.stats.frames_without_reference;
        } else {
            const std::string where = *job.rawlog + " record " + std::to_string(f.record);
            const cv::Mat query = greyOf(*f.obs, where);
            if (const std::string bad =
                    common::cameraProblem(f.obs->cameraParams, query.cols, query.rows);
                !bad.empty()) {
                throw std::runtime_error(where + ": camera parameters: " + bad);
            }
            for (const auto& n : chosen) {
                const auto& ref = db.reference(n.index);
                const cv::Mat ref_image = db.ceilingImage(n.index);
                LabelledPair pair;
                pair.reference = n.index;
                pair.query_rawlog = *job.rawlog;
                pair.query_record = f.record;
                pair.query_time_s = f.time_s;
                pair.distance_m = n.distance;
                pair.held_out = job.held_out;
                const PairCameras cameras{ref.ceiling_camera, f.obs->cameraParams};
                refine::Pinhole query_camera;
                refine::pinholeFrom(labelCamera(cameras), query_camera, &why);
                const cv::Matx33d H = priorHomography(ref, ref_camera, f, query_camera, h);
                const auto labels = labelPair(ref_image, query, options,
                                              options.use_pose_prior ? &H : nullptr, &cameras);
                const auto& fit = labels.fit;
                for (std::size_t i = 0; i < labels.matches.size(); ++i) {
                    const auto& m = labels.matches[i];
                    pair.points.push_back(m.reference_px);
                    pair.inlier.push_back(m.inlier ? 1 : 0);
                    pair.target.push_back(
                        isTarget(m, labels.residual_px[i], options.precise_inlier_px) ? 1 : 0);
                    pair.inliers += m.inlier ? 1 : 0;
                    pair.targets += pair.target.back();
                }
                if (!fit.ok) {
                    pair.reason = "no homography: " + fit.reason;
                } else if (pair.inliers < options.min_pair_inliers) {
                    pair.reason = "only " + std::to_string(pair.inliers) + " inliers";
                } else {
                    pair.usable = true;
                    ++out.stats.usable_pairs;
                    ++(pair.held_out ? out.stats.held_out_pairs : out.stats.training_pairs);
                    out.stats.points += pair.points.size();
                    out.stats.inlier_points += pair.inliers;
                    out.stats.target_points += pair.targets;
                }
                ++out.stats.pairs;
                out.pairs.push_back(std::move(pair));
            }
            f.obs->image.unload();
        }
        f.obs.reset();
        if (progress) progress(++done, jobs.size());
    }
    out.stats.seconds =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return out;
}

}  // namespace lookup::fcn

#include "lookup/survey/refresh.h"

#include <mrpt/obs/CObservationOdometry.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/odometry_track.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"
#include "lookup/database/reference_database.h"
#include "lookup/eval/run_io.h"
#include "lookup/survey/keyframes.h"
#include "lookup/survey/laser_poses.h"
#include "lookup/survey/traverse.h"

namespace lookup::survey {
namespace fs = std::filesystem;
namespace {

/// A ceiling frame of the drive as the run saw it.
struct DriveFrame {
    double time_s = 0;
    enum State { Unknown, Refined, Unrefined } state = Unknown;
    mrpt::poses::CPose2D pose;        ///< the run's refined pose
    mrpt::math::CMatrixDouble33 cov;  ///< its covariance (x, y, yaw)
    std::optional<mrpt::poses::CPose2D> odometry;
    double travelled_m = 0;  ///< odometry path length from the first frame
};

/// The constant offset between the run's frame times and the rawlog's stamps (the localiser
/// reports frames at the corrected image time): the one that pairs most frames within 2 ms.
double runTimeOffset(const std::vector<double>& frames, const std::vector<double>& rows) {
    const auto matched = [&](double offset) {
        std::size_t n = 0;
        for (double t : frames) {
            const auto it = std::lower_bound(rows.begin(), rows.end(), t + offset - 0.002);
            if (it != rows.end() && *it <= t + offset + 0.002) ++n;
        }
        return n;
    };
    double best = 0;
    std::size_t best_n = matched(0);
    for (std::size_t i = 0; i < std::min<std::size_t>(rows.size(), 20); ++i) {
        for (std::size_t j = 0; j < std::min<std::size_t>(frames.size(), 20); ++j) {
            const double offset = rows[i] - frames[j];
            if (std::abs(offset) > 0.5) continue;
            if (const std::size_t n = matched(offset); n > best_n) best = offset, best_n = n;
        }
    }
    return best;
}

/// Each ceiling frame of the drive with the run's verdict and the odometry at its time.
std::vector<DriveFrame> driveFrames(const TraverseData& d, const eval::Run& run,
                                    const RefreshInputs& in) {
    std::vector<double> frame_times, row_times;
    for (const auto& c : d.ceiling) frame_times.push_back(mrpt::Clock::toDouble(c->timestamp));
    for (const auto& r : run.frames) row_times.push_back(r.time_s);
    if (!std::is_sorted(row_times.begin(), row_times.end())) {
        throw eval::RunError(in.run_dir + "/frames.csv: frames not in time order");
    }
    const double offset = runTimeOffset(frame_times, row_times);
    common::OdometryTrack odometry;
    for (const auto& o : d.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            odometry.add(mrpt::Clock::toDouble(odo->timestamp), odo->odometry);
        }
    }
    std::vector<DriveFrame> out(frame_times.size());
    std::size_t matched = 0;
    for (std::size_t f = 0; f < frame_times.size(); ++f) {
        DriveFrame& frame = out[f];
        frame.time_s = frame_times[f];
        if (auto p = odometry.at(frame.time_s)) frame.odometry = p->pose;
        if (f > 0) {
            const auto &a = out[f - 1].odometry, &b = frame.odometry;
            frame.travelled_m = out[f - 1].travelled_m + (a && b ? a->distanceTo(*b) : 0.0);
        }
        const double t = frame.time_s + offset;
        const auto it = std::lower_bound(row_times.begin(), row_times.end(), t - 0.002);
        if (it == row_times.end() || *it > t + 0.002) continue;
        ++matched;
        const eval::FrameRow& row = run.frames[std::size_t(it - row_times.begin())];
        const bool refined = row.status == "refined" && row.has_pose;
        frame.state = refined ? DriveFrame::Refined : DriveFrame::Unrefined;
        frame.pose = mrpt::poses::CPose2D(row.x, row.y, row.yaw);
        frame.cov.setZero();
        frame.cov(0, 0) = row.cov_xx;
        frame.cov(0, 1) = frame.cov(1, 0) = row.cov_xy;
        frame.cov(1, 1) = row.cov_yy;
        frame.cov(2, 2) = row.cov_tt;
    }
    if (matched < 0.8 * frame_times.size()) {
        throw eval::RunError(in.run_dir + ": frames.csv has rows for only " +
                             std::to_string(matched) + " of the " + std::to_string(out.size()) +
                             " ceiling images of " + in.rawlog + ": not a run of this drive");
    }
    if (odometry.empty()) {
        throw common::RawlogError(in.rawlog,
                                  "no odometry: the stretches between fixes cannot be "
                                  "bridged");
    }
    return out;
}

/// A candidate reference from the drive: its frame, pose and covariance.
struct Posed {
    std::size_t frame = 0;
    mrpt::poses::CPose2D pose;
    mrpt::math::CMatrixDouble33 cov;
    bool bridged = false;     ///< inside the stretch (else a margin frame with the run's own fix)
    std::size_t stretch = 0;  ///< index in RefreshResult::stretches
    ImageQuality quality;     ///< measured when it was kept as a keyframe
};

/// The stretch's frames posed from the fixes at `a` and `b` and the odometry between them
/// (database::bridgeStretch). Empty, with `s.refused` set, when the odometry does not join the
/// fixes.
std::vector<Posed> bridge(const std::vector<DriveFrame>& frames, std::size_t a, std::size_t b,
                          const SurveyOptions& o, RefreshStretch& s) {
    std::vector<database::DriveFramePose> posed(b - a + 1);
    for (std::size_t f = a; f <= b; ++f) {
        if (!frames[f].odometry) {
            s.refused = "no odometry at t=" + std::to_string(frames[f].time_s);
            return {};
        }
        posed[f - a] = {*frames[f].odometry, frames[f].travelled_m, frames[f].pose, frames[f].cov};
    }
    const std::vector<database::DriveFramePose> between(posed.begin() + 1, posed.end() - 1);
    const database::Bridge bridged =
        database::bridgeStretch(posed.front(), posed.back(), between, o.refresh);
    s.closure_m = bridged.closure_m;
    s.refused = bridged.refused;
    std::vector<Posed> out;
    for (std::size_t k = 0; k < bridged.poses.size(); ++k) {
        Posed p;
        p.frame = a + 1 + k;
        p.bridged = true;
        p.pose = bridged.poses[k];
        p.cov = bridged.covs[k];
        out.push_back(p);
    }
    return out;
}

/// The refined frames within `margin_m` of travel before `a` (walking back) or after `b`.
std::vector<Posed> margin(const std::vector<DriveFrame>& frames, std::size_t from, int step,
                          double margin_m) {
    std::vector<Posed> out;
    const double s0 = frames[from].travelled_m;
    for (auto f = static_cast<std::ptrdiff_t>(from);
         f >= 0 && f < static_cast<std::ptrdiff_t>(frames.size()); f += step) {
        const DriveFrame& frame = frames[std::size_t(f)];
        if (frame.state != DriveFrame::Refined || std::abs(frame.travelled_m - s0) > margin_m) {
            break;
        }
        out.push_back({std::size_t(f), frame.pose, frame.cov, false, 0, {}});
    }
    if (step < 0) std::reverse(out.begin(), out.end());
    return out;
}

/// The unrefined stretches bounded by refined frames: (last fix before, first fix after).
std::vector<std::pair<std::size_t, std::size_t>> unrefinedStretches(
    const std::vector<DriveFrame>& frames) {
    constexpr std::size_t kNone = std::size_t(-1);
    std::vector<std::pair<std::size_t, std::size_t>> out;
    std::size_t last_fix = kNone;
    for (std::size_t f = 0; f < frames.size(); ++f) {
        if (frames[f].state == DriveFrame::Unknown) {
            last_fix = kNone;  // a frame the run did not see: nothing bounds the stretch
        } else if (frames[f].state == DriveFrame::Refined) {
            if (last_fix != kNone && f > last_fix + 1) out.emplace_back(last_fix, f);
            last_fix = f;
        }
    }
    return out;
}

/// The posed frames kept as keyframes (the survey's spacing and image quality).
std::vector<Posed> keyframesOf(const std::vector<Posed>& posed, const TraverseData& d,
                               const SurveyOptions& o) {
    std::vector<KeyframeCandidate> candidates;
    for (const auto& p : posed) {
        candidates.push_back(
            {mrpt::Clock::toDouble(d.ceiling[p.frame]->timestamp), mrpt::poses::CPose3D(p.pose)});
    }
    const KeyframeSelection kept = selectKeyframes(candidates, o, [&](std::size_t c) {
        std::string problem;
        return ceilingQuality(*d.ceiling[posed[c].frame], nullptr, o.ceiling_max_width_px, problem);
    });
    std::vector<Posed> out;
    for (std::size_t k = 0; k < kept.kept.size(); ++k) {
        out.push_back(posed[kept.kept[k]]);
        out.back().quality = kept.kept_quality[k];
    }
    return out;
}

/// A stored image as the record the writer takes.
mrpt::obs::CObservationImage::Ptr storedImage(const std::string& label, double time_s,
                                              const mrpt::img::TCamera& camera,
                                              const mrpt::poses::CPose3D& on_vehicle,
                                              const std::string& path) {
    auto image = mrpt::obs::CObservationImage::Create();
    image->sensorLabel = label;
    image->timestamp = mrpt::Clock::fromDouble(time_s);
    image->cameraParams = camera;
    image->cameraPose = on_vehicle;
    if (!image->image.loadFromFile(path, 0)) {
        throw database::DatabaseError(path + ": unreadable reference image");
    }
    return image;
}

/// A database reference as the writer takes it: its records rebuilt from the stored images.
database::ReferenceInput inputOf(const database::Reference& ref, const database::DatabaseInfo& info,
                                 const std::string& superseded_by) {
    database::ReferenceInput in;
    in.traverse = ref.traverse;
    in.ceiling = storedImage(info.ceiling_camera_label, ref.time_s, ref.ceiling_camera,
                             ref.ceiling_camera_mount, ref.ceiling_image_path);
    if (ref.has_forward) {
        // The forward camera's map pose is what the database keeps: stored relative to the
        // vehicle at the ceiling image's time, it is composed back exactly.
        in.forward =
            storedImage(info.forward_camera_label, ref.forward_time_s, info.forward_camera,
                        ref.forward_camera_pose - ref.vehicle_pose, ref.forward_image_path);
        in.forward_vehicle_pose = ref.vehicle_pose;
    }
    in.vehicle_pose = ref.vehicle_pose;
    in.vehicle_cov = ref.vehicle_cov;
    in.sharpness = ref.sharpness;
    in.mean_intensity = ref.mean_intensity;
    in.travelled_m = ref.travelled_m;
    in.source = ref.source;
    in.superseded_by = superseded_by;
    return in;
}

database::ReferenceInput inputOf(const Posed& p, const TraverseData& d,
                                 const std::vector<DriveFrame>& frames, const std::string& name) {
    database::ReferenceInput in;
    in.traverse = name;
    in.ceiling = d.ceiling[p.frame];
    in.vehicle_pose = mrpt::poses::CPose3D(p.pose);
    in.vehicle_cov = p.cov;
    in.sharpness = p.quality.sharpness;
    in.mean_intensity = p.quality.mean_intensity;
    in.travelled_m = frames[p.frame].travelled_m;
    in.source = "refresh";
    return in;
}

std::string readText(const std::string& path) {
    std::ifstream f(path);
    std::stringstream s;
    s << f.rdbuf();
    return s.str();
}

/// Every stretch considered, and the drive's references to add.
std::vector<Posed> refreshedStretches(const std::vector<DriveFrame>& frames, const TraverseData& d,
                                      const SurveyOptions& o, RefreshResult& result) {
    std::vector<Posed> added;
    std::set<std::size_t> taken;
    for (const auto& [a, b] : unrefinedStretches(frames)) {
        RefreshStretch s;
        s.from_s = frames[a].time_s;
        s.to_s = frames[b].time_s;
        s.length_m = frames[b].travelled_m - frames[a].travelled_m;
        s.frames = b - a - 1;
        if (s.length_m < o.refresh.min_stretch_m) continue;
        const std::vector<Posed> posed = bridge(frames, a, b, o, s);
        if (s.refused.empty()) {
            std::vector<Posed> all = margin(frames, a, -1, o.refresh.margin_m);
            all.insert(all.end(), posed.begin(), posed.end());
            const auto after = margin(frames, b, +1, o.refresh.margin_m);
            all.insert(all.end(), after.begin(), after.end());
            for (Posed p : keyframesOf(all, d, o)) {
                if (!taken.insert(p.frame).second) continue;
                p.stretch = result.stretches.size();
                added.push_back(p);
                ++s.added;
            }
        }
        result.stretches.push_back(s);
    }
    return added;
}

}  // namespace

namespace {

/// Each survey reference's superseded_by after the refresh: as before, or the drive's name where
/// its camera stood within the radius of a bridged reference's camera (counted per stretch).
std::vector<std::string> supersededAfter(const std::vector<Posed>& added, const TraverseData& d,
                                         const database::ReferenceDatabase& db,
                                         const SurveyOptions& o, RefreshResult& result) {
    std::vector<std::string> superseded_by(db.size());
    for (std::size_t i = 0; i < db.size(); ++i) superseded_by[i] = db.reference(i).superseded_by;
    for (const auto& r : added) {
        if (!r.bridged) continue;
        const auto camera = mrpt::poses::CPose3D(r.pose) + d.ceiling[r.frame]->cameraPose;
        for (std::size_t i = 0; i < db.size(); ++i) {
            const auto& c = db.reference(i).ceiling_camera_pose;
            if (!superseded_by[i].empty() ||
                std::hypot(c.x() - camera.x(), c.y() - camera.y()) > o.refresh.supersede_radius_m) {
                continue;
            }
            superseded_by[i] = result.name;
            ++result.stretches[r.stretch].superseded;
            ++result.references_superseded;
        }
    }
    return superseded_by;
}

/// The refreshed database: every reference of `db` (superseded as marked), then the drive's,
/// the map and the reports; committed atomically to `out_dir`.
void writeRefreshed(const database::ReferenceDatabase& db,
                    const std::vector<std::string>& superseded_by, const std::vector<Posed>& added,
                    const TraverseData& d, const std::vector<DriveFrame>& frames,
                    const RefreshResult& result) {
    // The drive's images at the width the database's are stored at.
    database::DatabaseWriter writer(result.out_dir, int(db.info().ceiling_camera.ncols));
    for (std::size_t i = 0; i < db.size(); ++i) {
        writer.add(inputOf(db.reference(i), db.info(), superseded_by[i]));
    }
    for (const auto& p : added) writer.add(inputOf(p, d, frames, result.name));
    if (!db.info().map_file.empty()) {
        writer.setMap(loadGridMap(db.directory() + "/" + db.info().map_file));
    }
    if (fs::is_regular_file(db.directory() + "/" + database::kReport)) {
        writer.writeTextFile(database::kReport, readText(db.directory() + "/" + database::kReport));
    }
    writer.writeTextFile(kRefreshReport, result.toJson());
    database::DatabaseInfo info = db.info();
    info.source_rawlogs.push_back(fs::absolute(result.rawlog).string());
    info.heatmaps_dir.clear();
    writer.commit(info);
}

}  // namespace

RefreshResult refreshDatabase(const RefreshInputs& in, const SurveyOptions& o) {
    if (fs::exists(in.out_dir) && fs::exists(in.db_dir) &&
        fs::equivalent(fs::absolute(in.out_dir), fs::absolute(in.db_dir))) {
        throw common::ConfigError("--out " + in.out_dir +
                                  ": is the database being refreshed; give a new folder (the "
                                  "surveyed database is never overwritten)");
    }
    RefreshResult result;
    result.db_dir = in.db_dir;
    result.out_dir = in.out_dir;
    result.rawlog = in.rawlog;
    result.run_dir = in.run_dir;
    result.name = in.name.empty() ? fs::path(in.rawlog).stem().string() : in.name;
    const auto db = database::ReferenceDatabase::load(in.db_dir);
    const eval::Run run = eval::loadRun(in.run_dir);
    if (const std::string why = eval::runProblem(run); !why.empty()) {
        throw eval::RunError(in.run_dir + ": " + why);
    }
    const TraverseData d = readTraverse(in.rawlog, o, /*need_laser=*/false);
    const std::vector<DriveFrame> frames = driveFrames(d, run, in);
    result.frames = frames.size();
    result.refined = std::count_if(frames.begin(), frames.end(),
                                   [](const auto& f) { return f.state == DriveFrame::Refined; });
    result.references_before = db.size();

    const std::vector<Posed> added = refreshedStretches(frames, d, o, result);
    result.references_added = added.size();
    const auto superseded_by = supersededAfter(added, d, db, o, result);
    if (!db.info().heatmaps_dir.empty()) {
        const std::string model = db.directory() + "/fcn_model.pt";
        result.warnings.push_back("the FCN heat maps of " + in.db_dir + " are not carried over: " +
                                  (fs::is_regular_file(model)
                                       ? "write them with its model (lookup-train --db " +
                                             in.out_dir + " --heatmaps-only " + model +
                                             ") or train again"
                                       : "train again (lookup-train --db " + in.out_dir + ")"));
    }
    writeRefreshed(db, superseded_by, added, d, frames, result);
    return result;
}

std::string RefreshResult::summaryLine() const {
    std::size_t refused = 0;
    for (const auto& s : stretches) refused += s.refused.empty() ? 0 : 1;
    std::ostringstream o;
    o << "lookup-survey: refreshed " << out_dir << " from " << name << ": " << refined << " of "
      << frames << " frames refined, " << stretches.size() - refused << " changed stretches ("
      << refused << " left alone), " << references_added << " references added, "
      << references_superseded << " of " << references_before << " superseded";
    return o.str();
}

std::string RefreshResult::toJson() const {
    nlohmann::ordered_json j;
    j["database"] = db_dir;
    j["refreshed_database"] = out_dir;
    j["drive"] = {{"name", name}, {"rawlog", rawlog}, {"run", run_dir}};
    j["frames"] = frames;
    j["refined"] = refined;
    j["references_before"] = references_before;
    j["references_added"] = references_added;
    j["references_superseded"] = references_superseded;
    auto& list = j["stretches"] = nlohmann::ordered_json::array();
    for (const auto& s : stretches) {
        list.push_back({{"from_s", s.from_s},
                        {"to_s", s.to_s},
                        {"length_m", s.length_m},
                        {"closure_m", s.closure_m},
                        {"frames", s.frames},
                        {"added", s.added},
                        {"superseded", s.superseded},
                        {"refused", s.refused}});
    }
    j["warnings"] = warnings;
    return j.dump(2) + "\n";
}

}  // namespace lookup::survey

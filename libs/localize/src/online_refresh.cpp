// The localiser's online refresh (LocalizerOptions::online_refresh): where a fix closes a
// stretch that no reference refined, the drive's frames over it become references for the rest
// of the run. The stretch is bridged as lookup-survey --refresh bridges it after a drive
// (database::bridgeStretch); the frames are thinned to online_refresh_spacing_m as they arrive,
// so a stopped vehicle keeps one frame and memory stays bounded by refresh_max_stretch_m.

#include <opencv2/core.hpp>

#include <algorithm>
#include <cmath>

#include "lookup/common/grey.h"
#include "lookup/localize/localizer.h"

namespace lookup::localize {
namespace {

// (Templates: Localizer::DriveFrame is private.)
template <class Frame>
std::size_t firstUnrefined(const std::vector<Frame>& drive) {
    const auto it =
        std::find_if(drive.begin(), drive.end(), [](const Frame& f) { return !f.refined; });
    return std::size_t(it - drive.begin());
}

template <class Frame>
std::size_t firstRefined(const std::vector<Frame>& drive, std::size_t from) {
    const auto it = std::find_if(drive.begin() + std::ptrdiff_t(from), drive.end(),
                                 [](const Frame& f) { return f.refined; });
    return std::size_t(it - drive.begin());
}

template <class Frame>
database::Reference referenceOf(const Frame& f, const mrpt::poses::CPose2D& pose,
                                const mrpt::math::CMatrixDouble33& cov, cv::Mat& grey) {
    grey = common::greyOf(f.image);
    database::Reference r;
    r.traverse = r.source = database::kOnlineSource;
    r.time_s = f.time_s;
    r.vehicle_pose = mrpt::poses::CPose3D(pose);
    r.vehicle_cov = cov;
    r.ceiling_camera_mount = f.camera_on_vehicle;
    r.ceiling_camera_pose = r.vehicle_pose + f.camera_on_vehicle;
    r.ceiling_camera = f.camera;
    r.mean_intensity = cv::mean(grey)[0];
    r.travelled_m = f.posed.travelled_m;
    return r;
}

}  // namespace

void Localizer::refreshOnline(const mrpt::obs::CObservationImage& query, const FrameResult& out) {
    if (!options_.online_refresh) return;
    const auto odometry = odometryAt(out.time_s);
    if (!odometry) {  // nothing to bridge on
        drive_.clear();
        last_refined_.reset();
        drive_odometry_.reset();
        return;
    }
    if (drive_odometry_) drive_travelled_m_ += drive_odometry_->distanceTo(odometry->pose);
    drive_odometry_ = odometry->pose;

    DriveFrame f{out.time_s,
                 {},
                 query.cameraParams,
                 query.cameraPose,
                 out.status == FrameStatus::Refined,
                 {odometry->pose, drive_travelled_m_, {}, mrpt::math::CMatrixDouble33::Zero()}};
    if (f.refined) f.posed.pose = out.pose.mean, f.posed.cov = out.pose.cov;
    try {
        f.image = query.image.asCvMatRef();
    } catch (const std::exception&) {
        return;  // process() checked the image; one that cannot be read now is no reference
    }
    const double now_m = drive_travelled_m_;
    const auto spaced = [&] {
        return drive_.empty() ||
               now_m - drive_.back().posed.travelled_m >= options_.online_refresh_spacing_m;
    };
    std::size_t unrefined = firstUnrefined(drive_);
    if (f.refined && unrefined == drive_.size()) {  // tracking: the margin before a stretch
        if (spaced()) {
            drive_.push_back(std::move(f));
            last_refined_.reset();
            trimDrive();
        } else {
            last_refined_ = std::move(f);
        }
        return;
    }
    if (f.refined) {  // the fix that closes a stretch, or the margin after it
        const std::size_t fix = firstRefined(drive_, unrefined);
        if (fix == drive_.size() || spaced()) drive_.push_back(std::move(f));
        if (now_m - drive_[fix].posed.travelled_m >= options_.refresh.margin_m) {
            addStretch(unrefined, fix);
        }
        return;
    }
    if (unrefined < drive_.size() && drive_.back().refined) {
        // A new stretch begins before the last one's margin after it was passed.
        addStretch(unrefined, firstRefined(drive_, unrefined));
        unrefined = drive_.size();
    }
    if (unrefined == drive_.size()) {  // a stretch begins: the newest fix is its fix before
        if (last_refined_) drive_.push_back(std::move(*last_refined_));
        last_refined_.reset();
        if (drive_.empty()) return;  // no fix before it: nothing to bridge from
        unrefined = drive_.size();
    }
    if (now_m - drive_[unrefined - 1].posed.travelled_m > options_.refresh.max_stretch_m) {
        ++online_refresh_.refused;
        drive_.clear();  // too long to bridge: start again at the next fix
        return;
    }
    if (drive_.back().refined || spaced()) drive_.push_back(std::move(f));
}

void Localizer::addStretch(std::size_t first_unrefined, std::size_t fix_after) {
    // Shorter than refresh_min_stretch_m: a bad view (dust, a pipe), not a changed ceiling.
    const double length_m =
        drive_[fix_after].posed.travelled_m - drive_[first_unrefined - 1].posed.travelled_m;
    if (length_m >= options_.refresh.min_stretch_m) addBridged(first_unrefined, fix_after);
    drive_.erase(drive_.begin(), drive_.begin() + std::ptrdiff_t(fix_after));
    trimDrive();
}

void Localizer::addBridged(std::size_t first_unrefined, std::size_t b) {
    if (db_.inMemoryCount() + drive_.size() > options_.online_refresh_max_references) {
        ++online_refresh_.refused;
        return;
    }
    std::vector<database::DriveFramePose> between;
    for (std::size_t k = first_unrefined; k < b; ++k) between.push_back(drive_[k].posed);
    const auto bridge = database::bridgeStretch(drive_[first_unrefined - 1].posed, drive_[b].posed,
                                                between, options_.refresh);
    if (!bridge.refused.empty()) {
        ++online_refresh_.refused;
        return;
    }
    std::vector<std::pair<database::Reference, cv::Mat>> added;
    std::vector<bool> bridged;
    for (std::size_t k = 0; k < drive_.size(); ++k) {
        const bool inside = k >= first_unrefined && k < b;
        const auto& pose = inside ? bridge.poses[k - first_unrefined] : drive_[k].posed.pose;
        const auto& cov = inside ? bridge.covs[k - first_unrefined] : drive_[k].posed.cov;
        cv::Mat grey;
        auto ref = referenceOf(drive_[k], pose, cov, grey);
        added.emplace_back(std::move(ref), grey);
        bridged.push_back(inside);
    }
    const auto superseded = supersededBy(added, bridged);
    ++online_refresh_.stretches;
    online_refresh_.references += added.size();
    online_refresh_.superseded += superseded.size();
    db_.addInMemory(std::move(added), superseded, database::kOnlineSource);
}

std::vector<std::size_t> Localizer::supersededBy(
    const std::vector<std::pair<database::Reference, cv::Mat>>& added,
    const std::vector<bool>& bridged) const {
    // A reference no longer matches where the drive's frame nearest to it (by camera) was not
    // refined. Within the refresh radius of a bridged frame only: the margins' frames, refined,
    // keep the references around them, which matter most right now (the vehicle is there).
    const double r = options_.refresh.supersede_radius_m;
    double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
    for (const auto& [ref, image] : added) {
        x0 = std::min(x0, ref.ceiling_camera_pose.x() - r);
        x1 = std::max(x1, ref.ceiling_camera_pose.x() + r);
        y0 = std::min(y0, ref.ceiling_camera_pose.y() - r);
        y1 = std::max(y1, ref.ceiling_camera_pose.y() + r);
    }
    std::vector<std::size_t> out;
    for (std::size_t i = 0; i < db_.size(); ++i) {
        const auto& ref = db_.reference(i);
        const auto& c = ref.ceiling_camera_pose;
        if (!ref.current() || c.x() < x0 || c.x() > x1 || c.y() < y0 || c.y() > y1) continue;
        double nearest = INFINITY;
        bool nearest_bridged = false;
        for (std::size_t k = 0; k < added.size(); ++k) {
            const auto& camera = added[k].first.ceiling_camera_pose;
            const double d = std::hypot(c.x() - camera.x(), c.y() - camera.y());
            if (d < nearest) nearest = d, nearest_bridged = bridged[k];
        }
        if (nearest_bridged && nearest <= r) out.push_back(i);
    }
    return out;
}

void Localizer::trimDrive() {
    // Only refined frames are left here: the margin before the next stretch.
    const double newest = drive_.empty() ? 0.0 : drive_.back().posed.travelled_m;
    const auto old = std::find_if(drive_.begin(), drive_.end(), [&](const auto& g) {
        return newest - g.posed.travelled_m <= options_.refresh.margin_m;
    });
    drive_.erase(drive_.begin(), old);
}

}  // namespace lookup::localize

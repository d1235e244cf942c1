#include "lookup/database/reference_database.h"

#include <nanoflann.hpp>

#include <algorithm>
#include <array>
#include <filesystem>
#include <map>

#include "lookup/common/camera_params.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/image_cache.h"
#include "lookup/database/manifest.h"
#include "lookup/obs/observation_lookup_reference.h"
#include "lookup/obs/register_classes.h"

namespace lookup::database {
namespace fs = std::filesystem;
namespace {

// nanoflann adaptor over the reference vehicle positions.
struct PointCloud2D {
    std::vector<std::array<double, 2>> points;
    std::size_t kdtree_get_point_count() const { return points.size(); }
    double kdtree_get_pt(std::size_t i, std::size_t dim) const { return points[i][dim]; }
    template <class BBox>
    bool kdtree_get_bbox(BBox&) const {
        return false;
    }
};
using KdTree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<double, PointCloud2D>,
                                        PointCloud2D, 2, std::size_t>;

// The error for a missing database folder; a kill between lookup-survey's two renames leaves
// the database at <dir>.old-*, which the message then names.
DatabaseError missingFolderError(const std::string& dir, const std::string& absolute_dir) {
    std::string aside;
    std::error_code ec;
    const fs::path target(absolute_dir);
    for (const auto& e : fs::directory_iterator(target.parent_path(), ec)) {
        const std::string name = e.path().filename().string();
        if (name.rfind(target.filename().string() + ".old-", 0) == 0) aside = e.path().string();
    }
    return DatabaseError(dir + ": no such database folder" +
                         (aside.empty() ? std::string()
                                        : " (an interrupted lookup-survey left it at " + aside +
                                              "; the next lookup-survey run with --out " + dir +
                                              " restores it)"));
}

// The ceiling camera of a record (its own, or the database's), refused when malformed.
// All-zero focal lengths mean stored without a calibration (the localiser refuses it).
mrpt::img::TCamera ceilingCameraOf(const obs::CObservationLookupReference& rec,
                                   const DatabaseInfo& info, const std::string& where) {
    const auto camera = rec.has_ceiling_camera ? rec.ceiling_camera : info.ceiling_camera;
    const bool unset = camera.fx() == 0 && camera.fy() == 0;
    if (const auto why = common::cameraProblem(camera); !unset && !why.empty()) {
        throw DatabaseError(where + "ceiling camera: " + why);
    }
    return camera;
}

// One reference from its record; `where` ("<rawlog>: record <n>: ") prefixes every error.
Reference referenceFromRecord(const obs::CObservationLookupReference& rec, const DatabaseInfo& info,
                              const std::string& images_dir, const std::string& where) {
    Reference r;
    r.id = rec.reference_id;
    r.traverse = rec.traverse;
    r.time_s = mrpt::Clock::toDouble(rec.timestamp);
    r.vehicle_pose = rec.vehicle_pose;
    r.vehicle_cov = rec.vehicle_cov;
    r.ceiling_camera_pose = rec.ceiling_camera_pose;
    r.ceiling_camera_mount = rec.sensorPose;
    r.ceiling_camera = ceilingCameraOf(rec, info, where);
    r.ceiling_image_path = images_dir + "/" + rec.ceiling_image_file;
    if (!fs::is_regular_file(r.ceiling_image_path)) {
        throw DatabaseError(where + "missing ceiling image " + r.ceiling_image_path);
    }
    r.has_forward = !rec.forward_image_file.empty();
    if (r.has_forward) {
        r.forward_time_s = rec.forward_time_s;
        r.forward_image_path = images_dir + "/" + rec.forward_image_file;
        r.forward_camera_pose = rec.forward_camera_pose;
        if (!fs::is_regular_file(r.forward_image_path)) {
            throw DatabaseError(where + "missing forward image " + r.forward_image_path);
        }
    }
    r.sharpness = rec.sharpness;
    r.mean_intensity = rec.mean_intensity;
    r.travelled_m = rec.travelled_m;
    r.source = rec.source;
    r.superseded_by = rec.superseded_by;
    return r;
}

// Every reference record of refs.rawlog, in id order, as many as db.ini announces.
std::vector<Reference> readReferences(const std::string& rawlog_path, const DatabaseInfo& info) {
    const std::string images_dir = common::imagesDirectoryFor(rawlog_path);
    std::vector<Reference> refs;
    try {
        common::RawlogReader reader(rawlog_path);
        mrpt::obs::CObservation::Ptr o;
        while (reader.next(o)) {
            auto rec = std::dynamic_pointer_cast<obs::CObservationLookupReference>(o);
            if (!rec) continue;  // the image and pose records are for viewers
            const std::string where =
                rawlog_path + ": record " + std::to_string(reader.recordIndex()) + ": ";
            if (rec->reference_id != refs.size()) {
                throw DatabaseError(where + "reference id " + std::to_string(rec->reference_id) +
                                    " out of sequence");
            }
            refs.push_back(referenceFromRecord(*rec, info, images_dir, where));
        }
    } catch (const common::RawlogError& e) {
        throw DatabaseError(e.what());
    }
    if (refs.size() != info.reference_count) {
        throw DatabaseError(rawlog_path + ": holds " + std::to_string(refs.size()) +
                            " references but " + kDbIni + " says " +
                            std::to_string(info.reference_count));
    }
    return refs;
}

// The references the spatial queries return: all but the superseded ones.
std::vector<std::size_t> currentOf(const std::vector<Reference>& refs) {
    std::vector<std::size_t> current;
    for (std::size_t i = 0; i < refs.size(); ++i) {
        if (refs[i].current()) current.push_back(i);
    }
    return current;
}

// The positions (`pose`: the vehicle's or the ceiling camera's) of the references `which`.
PointCloud2D positionsOf(const std::vector<Reference>& refs, const std::vector<std::size_t>& which,
                         mrpt::poses::CPose3D Reference::*pose) {
    PointCloud2D cloud;
    for (std::size_t i : which) cloud.points.push_back({(refs[i].*pose).x(), (refs[i].*pose).y()});
    return cloud;
}

std::unique_ptr<KdTree> treeOver(const PointCloud2D& cloud) {
    if (cloud.points.empty()) return nullptr;  // every reference superseded
    auto tree = std::make_unique<KdTree>(2, cloud, nanoflann::KDTreeSingleIndexAdaptorParams(10));
    tree->buildIndex();
    return tree;
}

// The k nearest in `tree`, whose point j is reference `indices[j]`.
std::vector<Neighbour> nearestIn(const KdTree* tree, const std::vector<std::size_t>& indices,
                                 const mrpt::math::TPoint2D& p, std::size_t k) {
    k = std::min(k, indices.size());
    if (k == 0 || !tree) return {};
    std::vector<std::size_t> idx(k);
    std::vector<double> d2(k);
    const double query[2] = {p.x, p.y};
    k = tree->knnSearch(query, k, idx.data(), d2.data());
    std::vector<Neighbour> out(k);
    for (std::size_t i = 0; i < k; ++i) out[i] = {indices[idx[i]], std::sqrt(d2[i])};
    return out;
}

// Reference indices by time_s (stable: equal times keep id order).
std::vector<std::size_t> timeOrder(const std::vector<Reference>& refs) {
    std::vector<std::size_t> order(refs.size());
    for (std::size_t i = 0; i < refs.size(); ++i) order[i] = i;
    std::stable_sort(order.begin(), order.end(),
                     [&](std::size_t a, std::size_t b) { return refs[a].time_s < refs[b].time_s; });
    return order;
}

// The references with a forward image, by forward image time.
std::vector<std::size_t> forwardOrder(const std::vector<Reference>& refs) {
    std::vector<std::size_t> sequence;
    for (std::size_t i = 0; i < refs.size(); ++i) {
        if (refs[i].has_forward) sequence.push_back(i);
    }
    std::stable_sort(sequence.begin(), sequence.end(), [&](std::size_t a, std::size_t b) {
        return refs[a].forward_time_s < refs[b].forward_time_s;
    });
    return sequence;
}

}  // namespace

struct ReferenceDatabase::Impl {
    std::string dir;
    DatabaseInfo info;
    std::vector<Reference> refs;
    std::vector<std::size_t> current;  // the trees' points: indices of the current references
    PointCloud2D cloud, camera_cloud;
    std::unique_ptr<KdTree> tree, camera_tree;
    std::vector<std::size_t> by_time;  // reference indices sorted by time_s
    std::vector<std::size_t> forward_sequence;
    std::unique_ptr<ImageCache> cache;
    std::map<std::size_t, cv::Mat> in_memory;  // addInMemory's ceiling images by index

    // The spatial and time indices over `refs`.
    void index() {
        current = currentOf(refs);
        cloud = positionsOf(refs, current, &Reference::vehicle_pose);
        tree = treeOver(cloud);
        camera_cloud = positionsOf(refs, current, &Reference::ceiling_camera_pose);
        camera_tree = treeOver(camera_cloud);
        by_time = timeOrder(refs);
        forward_sequence = forwardOrder(refs);
    }
};

ReferenceDatabase::ReferenceDatabase(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
ReferenceDatabase::ReferenceDatabase(ReferenceDatabase&&) noexcept = default;
ReferenceDatabase& ReferenceDatabase::operator=(ReferenceDatabase&&) noexcept = default;
ReferenceDatabase::~ReferenceDatabase() = default;

ReferenceDatabase ReferenceDatabase::load(const std::string& dir, std::size_t cache_capacity) {
    obs::registerClasses();
    auto impl = std::make_unique<Impl>();
    impl->dir = fs::absolute(dir).lexically_normal().string();
    if (!fs::is_directory(dir)) throw missingFolderError(dir, impl->dir);
    verifyManifest(impl->dir);
    impl->info = readDatabaseInfo(impl->dir + "/" + kDbIni);
    verifyHeatMaps(impl->dir, impl->info.heatmaps_dir);
    impl->refs = readReferences(impl->dir + "/" + kRefsRawlog, impl->info);

    impl->index();
    impl->cache = std::make_unique<ImageCache>(std::max<std::size_t>(1, cache_capacity));
    return ReferenceDatabase(std::move(impl));
}

const std::string& ReferenceDatabase::directory() const { return impl_->dir; }
const DatabaseInfo& ReferenceDatabase::info() const { return impl_->info; }
std::size_t ReferenceDatabase::size() const { return impl_->refs.size(); }
const Reference& ReferenceDatabase::reference(std::size_t i) const { return impl_->refs.at(i); }
const std::vector<Reference>& ReferenceDatabase::references() const { return impl_->refs; }

std::vector<Neighbour> ReferenceDatabase::nearest(const mrpt::math::TPoint2D& p,
                                                  std::size_t k) const {
    return nearestIn(impl_->tree.get(), impl_->current, p, k);
}

std::vector<Neighbour> ReferenceDatabase::nearestCameras(const mrpt::math::TPoint2D& p,
                                                         std::size_t k) const {
    return nearestIn(impl_->camera_tree.get(), impl_->current, p, k);
}

std::vector<Neighbour> ReferenceDatabase::nearest(const mrpt::poses::CPose3D& pose,
                                                  std::size_t k) const {
    return nearest(mrpt::math::TPoint2D(pose.x(), pose.y()), k);
}

std::vector<Neighbour> ReferenceDatabase::withinRadius(const mrpt::math::TPoint2D& p,
                                                       double radius_m) const {
    if (impl_->current.empty() || !(radius_m >= 0)) return {};
    std::vector<std::pair<std::size_t, double>> matches;
    const double query[2] = {p.x, p.y};
    nanoflann::SearchParams params;
    params.sorted = true;
    impl_->tree->radiusSearch(query, radius_m * radius_m, matches, params);
    std::vector<Neighbour> out;
    out.reserve(matches.size());
    for (const auto& [i, d2] : matches) out.push_back({impl_->current[i], std::sqrt(d2)});
    return out;
}

std::vector<Neighbour> ReferenceDatabase::nearestInTime(double t, std::size_t k) const {
    const auto& order = impl_->by_time;
    const auto& refs = impl_->refs;
    // Merge outwards from the insertion point: the k nearest lie contiguously around it.
    auto hi = static_cast<std::ptrdiff_t>(
        std::lower_bound(order.begin(), order.end(), t,
                         [&](std::size_t i, double v) { return refs[i].time_s < v; }) -
        order.begin());
    auto lo = hi - 1;
    std::vector<Neighbour> out;
    const auto n = static_cast<std::ptrdiff_t>(order.size());
    while (out.size() < k && (lo >= 0 || hi < n)) {
        const double dl = lo >= 0 ? t - refs[order[lo]].time_s : INFINITY;
        const double dh = hi < n ? refs[order[hi]].time_s - t : INFINITY;
        if (dl <= dh) {
            out.push_back({order[lo--], dl});
        } else {
            out.push_back({order[hi++], dh});
        }
    }
    return out;
}

const std::vector<std::size_t>& ReferenceDatabase::forwardSequence() const {
    return impl_->forward_sequence;
}

void ReferenceDatabase::addInMemory(std::vector<std::pair<Reference, cv::Mat>> added,
                                    const std::vector<std::size_t>& superseded,
                                    const std::string& by) {
    for (std::size_t i : superseded) impl_->refs.at(i).superseded_by = by;
    for (auto& [ref, image] : added) {
        CV_Assert(image.type() == CV_8UC1);
        ref.id = static_cast<uint32_t>(impl_->refs.size());
        impl_->in_memory[ref.id] = std::move(image);
        impl_->refs.push_back(std::move(ref));
    }
    impl_->index();
}

std::size_t ReferenceDatabase::inMemoryCount() const { return impl_->in_memory.size(); }

cv::Mat ReferenceDatabase::ceilingImage(std::size_t i) const {
    if (const auto it = impl_->in_memory.find(i); it != impl_->in_memory.end()) return it->second;
    return impl_->cache->get(reference(i).ceiling_image_path);
}

cv::Mat ReferenceDatabase::forwardImage(std::size_t i) const {
    const auto& r = reference(i);
    if (!r.has_forward) return {};
    return impl_->cache->get(r.forward_image_path);
}

std::size_t ReferenceDatabase::imagesInMemory() const { return impl_->cache->size(); }
std::size_t ReferenceDatabase::imageDiskReads() const { return impl_->cache->diskReads(); }
std::size_t ReferenceDatabase::imageCacheCapacity() const { return impl_->cache->capacity(); }

}  // namespace lookup::database

#include "lookup/place/place_index.h"

#include <mrpt/system/CTicTac.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>
#include <opencv2/imgproc.hpp>

#include "lookup/common/grey.h"
#include "lookup/database/reference_database.h"
#include "lookup/refine/rectifier.h"
#include "lookup/refine/types.h"
#include "place_index_impl.h"

namespace lookup::place {

namespace {
// Within a quarter of the references' scale ORB's pyramid levels match the query as it is,
// better than resized (docs/place-index.md).
constexpr double kResizeAbove = 0.25;
}  // namespace

const char* toString(FeatureType t) {
    switch (t) {
        case FeatureType::Orb:
            return "orb";
        case FeatureType::Akaze:
            return "akaze";
        case FeatureType::Sift:
            return "sift";
    }
    return "?";
}

namespace detail {

cv::Ptr<cv::Feature2D> makeDetector(FeatureType type, int n) {
    switch (type) {
        case FeatureType::Orb:
            // Few pyramid levels: query and reference see the ceiling from nearly one height.
            return cv::ORB::create(n, 1.2f, 4, 31, 0, 2, cv::ORB::HARRIS_SCORE, 31, 12);
        case FeatureType::Akaze:
            return cv::AKAZE::create(cv::AKAZE::DESCRIPTOR_MLDB, 0, 3, 0.0005f, 3, 3);
        case FeatureType::Sift:
            return cv::SIFT::create(n);
    }
    return {};
}

cv::Mat detectionImage(const cv::Mat& grey, const PlaceIndexOptions& o) {
    // The ceiling's texture without the light on it, at one contrast: lamps switched off, the
    // vehicle's own light cone and another camera's exposure move the corners and their
    // strengths, not the rock (docs/benchmarks.md, "Place index on the ceiling's texture").
    if (o.illumination_sigma_px <= 0) return grey;
    const cv::Mat texture = refine::removeIllumination(grey, o.illumination_sigma_px);
    cv::Scalar mean, stddev;
    cv::meanStdDev(texture, mean, stddev);
    if (o.noisy_texture_to_noise <= 0 ||
        stddev[0] >= o.noisy_texture_to_noise * common::noiseSigma(grey)) {
        return refine::stretchContrast(texture);
    }
    // A dim camera: at the matcher's gain its texture stays below the detector's threshold, at
    // a higher gain the noise would make the corners; smoothed first, the rock's corners stand
    // out (docs/benchmarks.md, "The place index in the dark"). In floating point: stretched
    // that far, the grey levels of an 8-bit illumination would draw their steps as edges.
    cv::Mat smooth;
    grey.convertTo(smooth, CV_32F);
    cv::GaussianBlur(smooth, smooth, cv::Size(), o.noisy_blur_sigma_px);
    return refine::stretchContrast(refine::removeIllumination(smooth, o.illumination_sigma_px),
                                   o.noisy_max_gain);
}

void detect(const cv::Mat& grey, const PlaceIndexOptions& o, int n,
            std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors) {
    keypoints.clear();
    descriptors.release();
    if (grey.empty()) return;
    const FeatureType type = o.features;
    const cv::Mat image = detectionImage(grey, o);
    auto detector = makeDetector(type, n);
    detector->detect(image, keypoints);
    // AKAZE has no feature budget: keep the strongest n, as ORB and SIFT do.
    if (static_cast<int>(keypoints.size()) > n) {
        cv::KeyPointsFilter::retainBest(keypoints, n);
        keypoints.resize(static_cast<std::size_t>(n));
    }
    if (!keypoints.empty()) detector->compute(image, keypoints, descriptors);
}

bool isBinary(FeatureType type) { return type != FeatureType::Sift; }

void buildSearch(Impl& impl) {
    impl.search.reset();
    impl.lsh = BinaryLsh();
    if (impl.descriptors.empty()) return;
    const auto& o = impl.options;
    if (isBinary(o.features)) {
        impl.lsh.build(impl.descriptors, o.lsh_tables, o.lsh_key_bits, o.lsh_probe_level);
        return;
    }
    impl.search = std::make_unique<cv::flann::Index>();
    impl.search->build(impl.descriptors, cv::flann::KDTreeIndexParams(4), cvflann::FLANN_DIST_L2);
}

bool hasSearch(const Impl& impl) { return impl.search || impl.lsh.size() > 0; }

}  // namespace detail

using detail::Impl;

PlaceIndex::PlaceIndex() : impl_(std::make_unique<Impl>()) {}
PlaceIndex::PlaceIndex(PlaceIndex&&) noexcept = default;
PlaceIndex& PlaceIndex::operator=(PlaceIndex&&) noexcept = default;
PlaceIndex::~PlaceIndex() = default;

namespace {

/// Indices of the current references to index: per traverse, at least `spacing_m` apart along
/// it.
std::vector<std::size_t> thinnedReferences(const database::ReferenceDatabase& db,
                                           double spacing_m) {
    std::map<std::string, double> last_travelled;
    std::vector<std::size_t> out;
    for (std::size_t i = 0; i < db.size(); ++i) {
        const auto& ref = db.reference(i);
        if (!ref.current()) continue;
        auto it = last_travelled.find(ref.traverse);
        if (it != last_travelled.end() && std::abs(ref.travelled_m - it->second) < spacing_m) {
            continue;
        }
        last_travelled[ref.traverse] = ref.travelled_m;
        out.push_back(i);
    }
    return out;
}

}  // namespace

PlaceIndex PlaceIndex::build(const database::ReferenceDatabase& db, const PlaceIndexOptions& o,
                             const std::function<void(std::size_t, std::size_t)>& progress) {
    o.check();
    PlaceIndex index;
    Impl& impl = *index.impl_;
    impl.options = o;
    impl.fingerprint = referenceFingerprint(db);
    impl.database_references = db.size();
    const auto chosen = thinnedReferences(db, o.reference_spacing_m);
    // Features live in the database's ideal pinhole camera, as the localiser's rectified
    // queries and reference views do (refine::Rectifier).
    const refine::Rectifier rectifier(db.info().ceiling_camera);
    std::vector<cv::Mat> rows;
    for (std::size_t k = 0; k < chosen.size(); ++k) {
        std::vector<cv::KeyPoint> keypoints;
        cv::Mat descriptors;
        const cv::Mat image =
            rectifier.rectify(db.ceilingImage(chosen[k]), db.reference(chosen[k]).ceiling_camera);
        detail::detect(image, o, o.features_per_reference, keypoints, descriptors);
        for (const auto& kp : keypoints) {
            impl.features.push_back({static_cast<std::uint32_t>(chosen[k]), kp.pt.x, kp.pt.y});
        }
        if (!descriptors.empty()) rows.push_back(descriptors);
        ++impl.indexed_references;
        if (progress) progress(k + 1, chosen.size());
    }
    if (!rows.empty()) cv::vconcat(rows, impl.descriptors);
    detail::buildSearch(impl);
    return index;
}

std::vector<PlaceCandidate> PlaceIndex::query(const cv::Mat& grey, PlaceQueryTimes* times,
                                              double pixel_scale) const {
    const Impl& impl = *impl_;
    const auto& o = impl.options;
    PlaceQueryTimes local;
    PlaceQueryTimes& t = times ? *times : local;
    mrpt::system::CTicTac timer;
    // ORB's few pyramid levels hold the same corners across a small change of scale only. A
    // scale no candidate may have (a mount far off) is not worth the larger image.
    const bool resize = std::abs(pixel_scale - 1) > kResizeAbove &&
                        pixel_scale >= 1 / detail::kMaxPixelScale &&
                        pixel_scale <= detail::kMaxPixelScale;
    cv::Mat seen = grey;
    if (resize) {
        cv::resize(grey, seen, cv::Size(), pixel_scale, pixel_scale,
                   pixel_scale < 1 ? cv::INTER_AREA : cv::INTER_LINEAR);
    }
    std::vector<cv::KeyPoint> keypoints;
    cv::Mat descriptors;
    detail::detect(seen, o, o.query_features, keypoints, descriptors);
    t.query_features = static_cast<int>(keypoints.size());
    t.features_ms = 1e3 * timer.Tac();
    if (keypoints.empty() || !detail::hasSearch(impl)) return {};

    timer.Tic();
    const auto votes = detail::vote(impl, keypoints, descriptors);
    t.search_ms = 1e3 * timer.Tac();

    timer.Tic();
    auto candidates = detail::fitCandidates(impl, votes);
    if (resize) {
        for (auto& c : candidates) {
            for (int r = 0; r < 2; ++r) {
                c.query_to_reference(r, 0) *= pixel_scale;
                c.query_to_reference(r, 1) *= pixel_scale;
            }
            c.scale *= pixel_scale;
        }
    }
    t.geometry_ms = 1e3 * timer.Tac();
    return candidates;
}

std::size_t PlaceIndex::indexedReferences() const { return impl_->indexed_references; }
std::size_t PlaceIndex::featureCount() const { return impl_->features.size(); }
const PlaceIndexOptions& PlaceIndex::options() const { return impl_->options; }

std::size_t PlaceIndex::memoryBytes() const {
    const Impl& impl = *impl_;
    return impl.features.size() * sizeof(detail::Feature) +
           impl.descriptors.total() * impl.descriptors.elemSize() + impl.lsh.tableBytes();
}

std::uint64_t referenceFingerprint(const database::ReferenceDatabase& db) {
    // FNV-1a over what identifies each reference (not its file paths: a moved folder is fine).
    std::uint64_t h = 1469598103934665603ull;
    const auto mix = [&h](const void* data, std::size_t n) {
        const auto* p = static_cast<const unsigned char*>(data);
        for (std::size_t i = 0; i < n; ++i) h = (h ^ p[i]) * 1099511628211ull;
    };
    const std::uint64_t n = db.size();
    mix(&n, sizeof n);
    for (const auto& ref : db.references()) {
        const double values[] = {ref.time_s, ref.vehicle_pose.x(), ref.vehicle_pose.y(),
                                 ref.vehicle_pose.yaw()};
        mix(&ref.id, sizeof ref.id);
        mix(values, sizeof values);
        mix(ref.traverse.data(), ref.traverse.size());
        mix(ref.superseded_by.data(), ref.superseded_by.size());
    }
    return h;
}

}  // namespace lookup::place

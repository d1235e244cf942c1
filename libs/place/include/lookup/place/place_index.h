#pragma once
// The ceiling place index: local features of every reference ceiling image in one approximate
// nearest-neighbour index, so one query ceiling frame finds its references anywhere in the
// database at any heading (global acquisition, docs/place-index.md).
//
// Per query: features of the query image -> nearest database features (LSH for binary
// descriptors, detail::BinaryLsh; FLANN's KD-trees for float ones) -> votes per reference -> a
// RANSAC similarity transform (rotation, translation, scale near 1) per best-voted reference. A
// candidate is a reference and the query-to-reference pixel transform; placePose() turns it into a
// vehicle pose that the SAD refinement verifies.

#include <mrpt/config/CLoadableOptions.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <opencv2/core.hpp>

#include "lookup/common/options_table.h"

namespace lookup::database {
class ReferenceDatabase;
}

namespace lookup::place {
namespace detail {
struct Impl;
}

/// File name of the index inside a database folder.
inline constexpr const char* kPlaceIndexFile = "place_index.bin";

/// A place index file that cannot be used: the message names the file and the reason.
class PlaceIndexError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

enum class FeatureType { Orb, Akaze, Sift };
const char* toString(FeatureType t);  ///< "orb", "akaze", "sift"

/// Options of the index ([place_index] section of survey.ini and of lookup-localize's --ini).
/// The build options are stored in the index file; the query options apply per run.
struct PlaceIndexOptions : public common::TableOptions<PlaceIndexOptions> {
    // --- build -------------------------------------------------------------------------
    FeatureType features = FeatureType::Orb;
    int features_per_reference = 150;  ///< strongest features kept per reference image
    /// References are indexed at most this close along their traverse [m]: neighbours overlap
    /// by most of the image, and the SAD refinement uses the nearest references anyway.
    double reference_spacing_m = 0.75;
    /// Features are detected on the ceiling image with its illumination removed at this
    /// scale [px of the database's camera] and its contrast normalised, as the SAD matcher
    /// sees it (0: on the raw image, as indexes of format 1 were built).
    double illumination_sigma_px = 20;
    /// A ceiling image whose texture (standard deviation without the illumination) is below
    /// this many times its pixel noise is smoothed by a Gaussian of `noisy_blur_sigma_px` and
    /// stretched with a gain of up to `noisy_max_gain` (instead of the matcher's 4) before
    /// detection, so that a dim camera's corners are the rock's, not the noise's (0: never).
    double noisy_texture_to_noise = 3;
    double noisy_blur_sigma_px = 1.5;
    double noisy_max_gain = 32;
    // --- query -------------------------------------------------------------------------
    int query_features = 500;          ///< features detected in the query image
    int neighbours = 2;                ///< database features per query feature (votes)
    int max_descriptor_distance = 64;  ///< Hamming bits (binary) beyond which no vote
    int rerank_references = 12;        ///< best-voted references fitted geometrically
    double ransac_threshold_px = 4.0;  ///< similarity RANSAC inlier distance [px]
    int min_inliers = 12;              ///< fewer geometric inliers: not a candidate
    /// |scale - 1| allowed between the query's and the reference's view of the ceiling, in
    /// metres on the ceiling (place::vehiclePose): a camera nearer the ceiling sees it larger
    /// in pixels, not in metres.
    double max_scale_change = 0.25;
    int lsh_tables = 3;  ///< LSH tables (binary descriptors)
    int lsh_key_bits = 18;
    int lsh_probe_level = 0;
    int lsh_max_bucket = 0;  ///< LSH buckets holding more descriptors are skipped (0: none)
    int search_checks = 64;  ///< FLANN search checks (KD-trees of float descriptors)

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

/// One reference that explains the query: query pixel p maps to reference pixel
/// `query_to_reference * (p, 1)`.
struct PlaceCandidate {
    std::size_t reference = 0;  ///< database index
    cv::Matx23d query_to_reference;
    int votes = 0;    ///< feature matches before the geometric check
    int inliers = 0;  ///< matches agreeing with the transform
    double scale = 1;
    double rotation_rad = 0;
};

struct PlaceQueryTimes {
    double features_ms = 0;
    double search_ms = 0;
    double geometry_ms = 0;
    int query_features = 0;
};

class PlaceIndex {
  public:
    PlaceIndex();
    PlaceIndex(PlaceIndex&&) noexcept;
    PlaceIndex& operator=(PlaceIndex&&) noexcept;
    ~PlaceIndex();

    /// Features of the database's ceiling images (references thinned by
    /// reference_spacing_m). `progress(done, total)` is called per reference when given.
    static PlaceIndex build(const database::ReferenceDatabase& db, const PlaceIndexOptions& o,
                            const std::function<void(std::size_t, std::size_t)>& progress = {});
    /// Writes the index to `path` atomically (temporary beside it, fsync, rename);
    /// common::WriteError naming the file on failure.
    void save(const std::string& path) const;
    /// Reads an index written by save() for `db`: PlaceIndexError naming the file when it is
    /// missing, truncated, corrupt (CRC), of another format version or built from another
    /// database (the references' fingerprint differs). Query options come from `query`.
    static PlaceIndex load(const std::string& path, const database::ReferenceDatabase& db,
                           const PlaceIndexOptions& query);
    /// `<db>/place_index.bin` when it exists.
    static bool existsFor(const database::ReferenceDatabase& db);

    /// Candidates for one grey query image, most inliers first (several per place possible).
    /// `pixel_scale`: how much larger the references show the ceiling than the query does
    /// (place::expectedPixelScale); the query is resized by it before detection, so that its
    /// corners are found at the references' scale, and the candidates map the query's own
    /// pixels.
    std::vector<PlaceCandidate> query(const cv::Mat& grey, PlaceQueryTimes* times = nullptr,
                                      double pixel_scale = 1.0) const;

    std::size_t indexedReferences() const;
    std::size_t featureCount() const;
    /// Bytes of the features, descriptors and LSH tables (FLANN's KD-trees of float
    /// descriptors come on top).
    std::size_t memoryBytes() const;
    const PlaceIndexOptions& options() const;

  private:
    std::unique_ptr<detail::Impl> impl_;
};

/// A fingerprint of the database's references (ids, times, poses, image sizes): an index of
/// another database or of an older survey of the same folder does not match it.
std::uint64_t referenceFingerprint(const database::ReferenceDatabase& db);

}  // namespace lookup::place

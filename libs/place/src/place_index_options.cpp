#include "lookup/common/config.h"
#include "lookup/place/place_index.h"

namespace lookup::place {

void PlaceIndexOptions::declareKeys(common::OptionsTable& t) {
    t.add("features", features,
          common::EnumNames<FeatureType>{{toString(FeatureType::Orb), FeatureType::Orb},
                                         {toString(FeatureType::Akaze), FeatureType::Akaze},
                                         {toString(FeatureType::Sift), FeatureType::Sift}});
    t.add("features_per_reference", features_per_reference, 10, 100000);
    t.add("reference_spacing_m", reference_spacing_m, 0, 1000);
    t.add("query_features", query_features, 10, 100000);
    t.add("neighbours", neighbours, 1, 16);
    t.add("max_descriptor_distance", max_descriptor_distance, 1, 4096);
    t.add("rerank_references", rerank_references, 1, 100000);
    t.add("ransac_threshold_px", ransac_threshold_px, 0.1, 1000);
    t.add("min_inliers", min_inliers, 3, 100000);
    t.add("max_scale_change", max_scale_change, 0, 0.9);
    t.add("lsh_tables", lsh_tables, 1, 64);
    t.add("lsh_key_bits", lsh_key_bits, 4, 24);
    t.add("lsh_probe_level", lsh_probe_level, 0, 4);
    t.add("search_checks", search_checks, 1, 100000);
}

void PlaceIndexOptions::check() const {
    common::OptionsCheck c("place_index");
    c.require(features_per_reference >= 10, "features_per_reference", ">= 10");
    c.require(reference_spacing_m >= 0, "reference_spacing_m", ">= 0");
    c.require(query_features >= 10, "query_features", ">= 10");
    c.require(neighbours >= 1, "neighbours", ">= 1");
    c.require(min_inliers >= 3, "min_inliers", ">= 3 (a similarity needs 2 points, RANSAC more)");
    c.require(ransac_threshold_px > 0, "ransac_threshold_px", "> 0");
    c.require(max_scale_change >= 0 && max_scale_change < 1, "max_scale_change", "in [0, 1)");
    c.require(lsh_key_bits >= 4 && lsh_key_bits <= 24, "lsh_key_bits", "in [4, 24]");
    c.throwIfFailed();
}

}  // namespace lookup::place

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
    t.add("illumination_sigma_px", illumination_sigma_px, 0, 1000);
    t.add("noisy_texture_to_noise", noisy_texture_to_noise, 0, 1000);
    t.add("noisy_blur_sigma_px", noisy_blur_sigma_px, 0, 100);
    t.add("noisy_max_gain", noisy_max_gain, 1, 10000);
    t.add("query_features", query_features, 10, 100000);
    t.add("neighbours", neighbours, 1, 16);
    t.add("max_descriptor_distance", max_descriptor_distance, 1, 4096);
    t.add("rerank_references", rerank_references, 1, 100000);
    t.add("ransac_threshold_px", ransac_threshold_px, 0.1, 1000);
    t.add("min_inliers", min_inliers, 3, 100000);  // a similarity needs 2 points, RANSAC more
    t.add("max_scale_change", max_scale_change, 0, 0.9);
    t.add("lsh_tables", lsh_tables, 1, 64);
    t.add("lsh_key_bits", lsh_key_bits, 4, 24);
    t.add("lsh_probe_level", lsh_probe_level, 0, 4);
    t.add("lsh_max_bucket", lsh_max_bucket, 0, 100000000);
    t.add("search_checks", search_checks, 1, 100000);
}

void PlaceIndexOptions::check() const {
    common::OptionsCheck c("place_index");
    checkRanges(c);
    c.throwIfFailed();
}

}  // namespace lookup::place

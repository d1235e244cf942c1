#include "lookup/common/config.h"
#include "lookup/place/place_index.h"

namespace lookup::place {

namespace {

FeatureType parseFeatures(const common::IniSection& s, const std::string& fallback) {
    const std::string v = s.getString("features", fallback);
    for (auto t : {FeatureType::Orb, FeatureType::Akaze, FeatureType::Sift}) {
        if (v == toString(t)) return t;
    }
    throw common::ConfigError(s.where("features") + "'" + v + "' is not one of orb, akaze, sift");
}

}  // namespace

void PlaceIndexOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                           const std::string& section) {
    const common::IniSection s(source, section);
    s.rejectUnknownKeys({"features", "features_per_reference", "reference_spacing_m",
                         "query_features", "neighbours", "max_descriptor_distance",
                         "rerank_references", "ransac_threshold_px", "min_inliers",
                         "max_scale_change", "lsh_tables", "lsh_key_bits", "lsh_probe_level",
                         "search_checks"});
    features = parseFeatures(s, toString(features));
    features_per_reference = s.getInt("features_per_reference", features_per_reference, 10, 100000);
    reference_spacing_m = s.getDouble("reference_spacing_m", reference_spacing_m, 0, 1000);
    query_features = s.getInt("query_features", query_features, 10, 100000);
    neighbours = s.getInt("neighbours", neighbours, 1, 16);
    max_descriptor_distance = s.getInt("max_descriptor_distance", max_descriptor_distance, 1, 4096);
    rerank_references = s.getInt("rerank_references", rerank_references, 1, 100000);
    ransac_threshold_px = s.getDouble("ransac_threshold_px", ransac_threshold_px, 0.1, 1000);
    min_inliers = s.getInt("min_inliers", min_inliers, 3, 100000);
    max_scale_change = s.getDouble("max_scale_change", max_scale_change, 0, 0.9);
    lsh_tables = s.getInt("lsh_tables", lsh_tables, 1, 64);
    lsh_key_bits = s.getInt("lsh_key_bits", lsh_key_bits, 4, 24);
    lsh_probe_level = s.getInt("lsh_probe_level", lsh_probe_level, 0, 4);
    search_checks = s.getInt("search_checks", search_checks, 1, 100000);
    s.validate([&] { check(); });
}

void PlaceIndexOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                         const std::string& section) const {
    t.write(section, "features", std::string(toString(features)));
    t.write(section, "features_per_reference", features_per_reference);
    t.write(section, "reference_spacing_m", reference_spacing_m);
    t.write(section, "query_features", query_features);
    t.write(section, "neighbours", neighbours);
    t.write(section, "max_descriptor_distance", max_descriptor_distance);
    t.write(section, "rerank_references", rerank_references);
    t.write(section, "ransac_threshold_px", ransac_threshold_px);
    t.write(section, "min_inliers", min_inliers);
    t.write(section, "max_scale_change", max_scale_change);
    t.write(section, "lsh_tables", lsh_tables);
    t.write(section, "lsh_key_bits", lsh_key_bits);
    t.write(section, "lsh_probe_level", lsh_probe_level);
    t.write(section, "search_checks", search_checks);
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

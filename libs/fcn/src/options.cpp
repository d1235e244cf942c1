#include "lookup/fcn/options.h"

#include <mrpt/config/CConfigFile.h>

#include <cmath>
#include <sstream>

#include "lookup/common/config.h"

namespace lookup::fcn {
namespace {

using common::IniSection;
using common::OptionsCheck;

std::string sourceName(const mrpt::config::CConfigFileBase& source) {
    return common::configSourceName(source);
}

template <typename T>
void put(mrpt::config::CConfigFileBase& t, const std::string& s, const std::string& key, T v) {
    t.write(s, key, v, 0, 0, "");
}

}  // namespace

// ---------------------------------------------------------------- network
void NetworkOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                        const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys({"base_channels", "max_channels", "depth", "input_scale"});
    base_channels = s.getInt("base_channels", base_channels, 1, 256);
    max_channels = s.getInt("max_channels", max_channels, 1, 512);
    depth = s.getInt("depth", depth, 1, 6);
    input_scale = s.getDouble("input_scale", input_scale);
}

void NetworkOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                      const std::string& s) const {
    put(t, s, "base_channels", base_channels);
    put(t, s, "max_channels", max_channels);
    put(t, s, "depth", depth);
    put(t, s, "input_scale", input_scale);
}

void NetworkOptions::check() const {
    OptionsCheck c("fcn.network");
    c.require(base_channels >= 1 && base_channels <= 256, "base_channels", "in [1, 256]");
    c.require(max_channels >= base_channels && max_channels <= 512, "max_channels",
              "in [base_channels, 512]");
    c.require(depth >= 1 && depth <= 6, "depth", "in [1, 6]");
    c.require(std::isfinite(input_scale) && input_scale > 0 && input_scale <= 1, "input_scale",
              "in (0, 1]");
    c.throwIfFailed();
}

bool NetworkOptions::operator==(const NetworkOptions& o) const {
    return base_channels == o.base_channels && max_channels == o.max_channels && depth == o.depth &&
           input_scale == o.input_scale;
}

std::string NetworkOptions::describe() const {
    std::ostringstream s;
    s << "base_channels=" << base_channels << " max_channels=" << max_channels << " depth=" << depth
      << " input_scale=" << input_scale;
    return s.str();
}

// ---------------------------------------------------------------- labels
void LabelOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                      const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys({"grid_step_px", "references_per_query", "max_reference_distance_m",
                         "min_time_gap_s", "query_stride", "held_out_share", "min_pair_inliers",
                         "use_pose_prior", "precise_inlier_px", "min_references",
                         "min_training_pairs", "min_held_out_pairs"});
    grid_step_px = s.getInt("grid_step_px", grid_step_px, 2, 4096);
    references_per_query = s.getInt("references_per_query", references_per_query, 1, 1000);
    max_reference_distance_m = s.getDouble("max_reference_distance_m", max_reference_distance_m);
    min_time_gap_s = s.getDouble("min_time_gap_s", min_time_gap_s);
    query_stride = s.getInt("query_stride", query_stride, 1, 1000000);
    held_out_share = s.getDouble("held_out_share", held_out_share);
    min_pair_inliers = s.getInt("min_pair_inliers", min_pair_inliers, 4, 100000);
    use_pose_prior = s.getBool("use_pose_prior", use_pose_prior);
    precise_inlier_px = s.getDouble("precise_inlier_px", precise_inlier_px);
    min_references = s.getInt("min_references", min_references, 1, 100000000);
    min_training_pairs = s.getInt("min_training_pairs", min_training_pairs, 1, 100000000);
    min_held_out_pairs = s.getInt("min_held_out_pairs", min_held_out_pairs, 1, 100000000);
    if (source.sectionExists(section + ".matcher")) {
        matcher.loadFromConfigFile(source, section + ".matcher");
    }
    if (source.sectionExists(section + ".homography")) {
        homography.loadFromConfigFile(source, section + ".homography");
    }
}

void LabelOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t, const std::string& s) const {
    put(t, s, "grid_step_px", grid_step_px);
    put(t, s, "references_per_query", references_per_query);
    put(t, s, "max_reference_distance_m", max_reference_distance_m);
    put(t, s, "min_time_gap_s", min_time_gap_s);
    put(t, s, "query_stride", query_stride);
    put(t, s, "held_out_share", held_out_share);
    put(t, s, "min_pair_inliers", min_pair_inliers);
    put(t, s, "use_pose_prior", std::string(use_pose_prior ? "true" : "false"));
    put(t, s, "precise_inlier_px", precise_inlier_px);
    put(t, s, "min_references", min_references);
    put(t, s, "min_training_pairs", min_training_pairs);
    put(t, s, "min_held_out_pairs", min_held_out_pairs);
    matcher.saveToConfigFile(t, s + ".matcher");
    homography.saveToConfigFile(t, s + ".homography");
}

void LabelOptions::check() const {
    OptionsCheck c("fcn.labels");
    c.require(grid_step_px >= 2, "grid_step_px", ">= 2");
    c.require(references_per_query >= 1, "references_per_query", ">= 1");
    c.require(std::isfinite(max_reference_distance_m) && max_reference_distance_m > 0,
              "max_reference_distance_m", "> 0");
    c.require(std::isfinite(min_time_gap_s) && min_time_gap_s >= 0, "min_time_gap_s", ">= 0");
    c.require(query_stride >= 1, "query_stride", ">= 1");
    c.require(held_out_share > 0 && held_out_share < 1, "held_out_share", "in (0, 1)");
    c.require(std::isfinite(precise_inlier_px) && precise_inlier_px >= 0, "precise_inlier_px",
              ">= 0");
    c.require(min_pair_inliers >= 4, "min_pair_inliers", ">= 4 (a homography needs 4)");
    c.require(min_references >= 1, "min_references", ">= 1");
    c.require(min_training_pairs >= 1, "min_training_pairs", ">= 1");
    c.require(min_held_out_pairs >= 1, "min_held_out_pairs", ">= 1");
    c.throwIfFailed();
    matcher.check();
    homography.check();
}

// ---------------------------------------------------------------- training
void TrainingOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                         const std::string& section) {
    const IniSection s(source, section, sourceName(source));
    s.rejectUnknownKeys(
        {"epochs", "batch_size", "learning_rate", "weight_decay", "augment", "seed", "threads"});
    epochs = s.getInt("epochs", epochs, 1, 100000);
    batch_size = s.getInt("batch_size", batch_size, 1, 100000);
    learning_rate = s.getDouble("learning_rate", learning_rate);
    weight_decay = s.getDouble("weight_decay", weight_decay);
    augment = s.getBool("augment", augment);
    seed = s.getInt("seed", seed, 0, 2147483647);
    threads = s.getInt("threads", threads, 1, 1024);
}

void TrainingOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                       const std::string& s) const {
    put(t, s, "epochs", epochs);
    put(t, s, "batch_size", batch_size);
    put(t, s, "learning_rate", learning_rate);
    put(t, s, "weight_decay", weight_decay);
    put(t, s, "augment", std::string(augment ? "true" : "false"));
    put(t, s, "seed", seed);
    put(t, s, "threads", threads);
}

void TrainingOptions::check() const {
    OptionsCheck c("fcn.training");
    c.require(epochs >= 1, "epochs", ">= 1");
    c.require(batch_size >= 1, "batch_size", ">= 1");
    c.require(std::isfinite(learning_rate) && learning_rate > 0 && learning_rate < 1,
              "learning_rate", "in (0, 1)");
    c.require(std::isfinite(weight_decay) && weight_decay >= 0, "weight_decay", ">= 0");
    c.require(seed >= 0, "seed", ">= 0");
    c.require(threads >= 1, "threads", ">= 1");
    c.throwIfFailed();
}

// ---------------------------------------------------------------- all
void TrainOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                      const std::string& prefix) {
    // Absent sections keep their defaults (IniSection reads them as empty).
    network.loadFromConfigFile(source, prefix + ".network");
    labels.loadFromConfigFile(source, prefix + ".labels");
    training.loadFromConfigFile(source, prefix + ".training");
}

void TrainOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t,
                                    const std::string& prefix) const {
    network.saveToConfigFile(t, prefix + ".network");
    labels.saveToConfigFile(t, prefix + ".labels");
    training.saveToConfigFile(t, prefix + ".training");
}

void TrainOptions::check() const {
    network.check();
    labels.check();
    training.check();
}

}  // namespace lookup::fcn

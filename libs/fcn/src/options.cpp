#include "lookup/fcn/options.h"

#include <cmath>
#include <sstream>

#include "lookup/common/config.h"

namespace lookup::fcn {

using common::OptionsCheck;

// ---------------------------------------------------------------- network
void NetworkOptions::declareKeys(common::OptionsTable& t) {
    t.add("base_channels", base_channels, 1, 256);
    t.add("max_channels", max_channels, 1, 512);
    t.add("depth", depth, 1, 6);
    t.add("input_scale", input_scale);
}

void NetworkOptions::check() const {
    OptionsCheck c("fcn.network");
    checkRanges(c);
    c.require(max_channels >= base_channels && max_channels <= 512, "max_channels",
              "in [base_channels, 512]");
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
void LabelOptions::declareKeys(common::OptionsTable& t) {
    t.add("grid_step_px", grid_step_px, 2, 4096);
    t.add("references_per_query", references_per_query, 1, 1000);
    t.add("max_reference_distance_m", max_reference_distance_m, common::kPositive);
    t.add("min_time_gap_s", min_time_gap_s, 0.0);
    t.add("query_stride", query_stride, 1, 1000000);
    t.add("held_out_share", held_out_share);
    t.add("min_pair_inliers", min_pair_inliers, 4, 100000);
    t.add("use_pose_prior", use_pose_prior);
    t.add("precise_inlier_px", precise_inlier_px, 0.0);
    t.add("min_references", min_references, 1, 100000000);
    t.add("min_training_pairs", min_training_pairs, 1, 100000000);
    t.add("min_held_out_pairs", min_held_out_pairs, 1, 100000000);
}

void LabelOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                      const std::string& section) {
    TableOptions::loadFromConfigFile(source, section);
    matcher.loadFromConfigFile(source, section + ".matcher");  // absent: the defaults stay
    homography.loadFromConfigFile(source, section + ".homography");
}

void LabelOptions::saveToConfigFile(mrpt::config::CConfigFileBase& t, const std::string& s) const {
    TableOptions::saveToConfigFile(t, s);
    matcher.saveToConfigFile(t, s + ".matcher");
    homography.saveToConfigFile(t, s + ".homography");
}

void LabelOptions::check() const {
    OptionsCheck c("fcn.labels");
    checkRanges(c);
    c.require(held_out_share > 0 && held_out_share < 1, "held_out_share", "in (0, 1)");
    c.require(min_pair_inliers >= 4, "min_pair_inliers", ">= 4 (a homography needs 4)");
    c.throwIfFailed();
    matcher.check();
    homography.check();
}

// ---------------------------------------------------------------- training
void TrainingOptions::declareKeys(common::OptionsTable& t) {
    t.add("epochs", epochs, 1, 100000);
    t.add("batch_size", batch_size, 1, 100000);
    t.add("learning_rate", learning_rate);
    t.add("weight_decay", weight_decay, 0.0);
    t.add("augment", augment);
    t.add("seed", seed, 0, 2147483647);
    t.add("threads", threads, 1, 1024);
}

void TrainingOptions::check() const {
    OptionsCheck c("fcn.training");
    checkRanges(c);
    c.require(std::isfinite(learning_rate) && learning_rate > 0 && learning_rate < 1,
              "learning_rate", "in (0, 1)");
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

std::vector<std::string> TrainOptions::sectionNames(const std::string& prefix) {
    return {prefix + ".network", prefix + ".labels", prefix + ".labels.matcher",
            prefix + ".labels.homography", prefix + ".training"};
}

void TrainOptions::check() const {
    network.check();
    labels.check();
    training.check();
}

}  // namespace lookup::fcn

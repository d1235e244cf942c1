#pragma once
// Options of the FCN sample-point selector (paper Sec. III-B): how training labels are made,
// the network's architecture, and training. The paper has no Table I values for these (it used
// an ImageNet-pretrained VGG16 FCN); the defaults here are sized to train on 2 CPU cores.
// Loaded strictly (unknown keys and malformed values are refused, naming file, section, key);
// check() names every failing field. share/lookup/train.ini holds the defaults.

#include <mrpt/config/CLoadableOptions.h>

#include <cstdint>
#include <string>
#include <vector>

#include "lookup/common/options_table.h"
#include "lookup/refine/options.h"

namespace lookup::fcn {

/// Encoder-decoder with skip connections (the paper's FCN: VGG16 encoder, 1x1 conv, three
/// up-sampling layers with skips to layer3 / layer4; here small and from scratch).
struct NetworkOptions : public common::TableOptions<NetworkOptions> {
    int base_channels = 16;    ///< channels of the first encoder stage (doubled per stage)
    int max_channels = 64;     ///< cap on channels of any stage
    int depth = 4;             ///< encoder stages (each halves the resolution but the last)
    double input_scale = 0.5;  ///< image scale fed to the network, in (0, 1]

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
    bool operator==(const NetworkOptions& o) const;
    bool operator!=(const NetworkOptions& o) const { return !(*this == o); }
    /// "base_channels=16 max_channels=64 depth=4 input_scale=0.5", for messages.
    std::string describe() const;
};

/// Self-supervised labels (paper Sec. III-B: dense grid -> matcher -> RANSAC inliers).
struct LabelOptions : public common::TableOptions<LabelOptions> {
    int grid_step_px = 10;                  ///< spacing of the dense label grid [px]
    int references_per_query = 2;           ///< nearest references labelled per query frame
    double max_reference_distance_m = 1.5;  ///< references farther from the query are skipped [m]
    double min_time_gap_s = 20.0;     ///< references closer in time to the query are skipped [s]
                                      ///< (a training traverse that is also in the database)
    int query_stride = 2;             ///< every n-th ceiling frame of a training rawlog is used
    double held_out_share = 0.2;      ///< last share of each training rawlog's time span held out
                                      ///< for evaluation and validation (0, 1)
    int min_pair_inliers = 8;         ///< pairs with fewer RANSAC inliers are dropped (no reliable
                                      ///< labels: wrong overlap, failed match)
    bool use_pose_prior = true;       ///< centre each search window on the offset predicted by the
                                      ///< known poses (ceiling-plane homography) rather than 0
    double precise_inlier_px = 0.75;  ///< > 0: a point is a positive training target only when
                                      ///< it is a RANSAC inlier within this residual of the
                                      ///< fitted homography [px] (matches precisely, lies on the
                                      ///< ceiling plane); 0: every RANSAC inlier (the paper).
                                      ///< The held-out metric always uses RANSAC inliers.
    int min_references = 2;           ///< fewer references in the database: refused
    int min_training_pairs = 2;       ///< fewer usable training pairs: refused
    int min_held_out_pairs = 1;       ///< fewer usable held-out pairs: refused

    /// Matcher and RANSAC used to label (paper Table I; should match the localiser's).
    refine::MatcherOptions matcher;
    refine::HomographyOptions homography;

    /// The keys of `<section>` itself.
    void declareKeys(common::OptionsTable& t);
    /// Sections `<section>`, `<section>.matcher`, `<section>.homography`.
    void loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                            const std::string& section) override;
    void saveToConfigFile(mrpt::config::CConfigFileBase& target,
                          const std::string& section) const override;
    void check() const;
};

/// Adam on the class-balanced binary cross-entropy over the labelled points.
struct TrainingOptions : public common::TableOptions<TrainingOptions> {
    int epochs = 15;              ///< passes over the training references
    int batch_size = 8;           ///< reference images per Adam step
    double learning_rate = 2e-3;  ///< Adam step size
    double weight_decay = 1e-4;   ///< Adam L2 penalty
    bool augment = true;          ///< random horizontal / vertical flips of image and labels
    int seed = 1;                 ///< torch::manual_seed and shuffling (deterministic runs)
    int threads = 2;              ///< torch::set_num_threads

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    void check() const;
};

/// Everything lookup-train uses: sections `<prefix>.network`, `<prefix>.labels` (with
/// `.matcher`, `.homography`), `<prefix>.training`.
struct TrainOptions : public mrpt::config::CLoadableOptions {
    NetworkOptions network;
    LabelOptions labels;
    TrainingOptions training;

    void loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                            const std::string& prefix) override;
    void saveToConfigFile(mrpt::config::CConfigFileBase& target,
                          const std::string& prefix) const override;
    void check() const;
    /// The sections loadFromConfigFile reads for `prefix` (lookup-train refuses any other).
    static std::vector<std::string> sectionNames(const std::string& prefix);
};

}  // namespace lookup::fcn

#pragma once
// Training of the sample-point network (paper Sec. III-B: "the loss function is proportional to
// the number of misclassified sample points"): here the class-balanced binary cross-entropy of
// the network's logit, bilinearly sampled at each labelled grid point, against its RANSAC
// label; Adam; deterministic for a given seed. And the paper's evaluation: the share of held-out
// pairs whose single best point is an inlier.

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

#include "lookup/fcn/labels.h"
#include "lookup/fcn/model.h"
#include "lookup/fcn/options.h"

namespace lookup::fcn {

/// One training image: a reference and every label its pairs gave it.
struct TrainingSample {
    cv::Mat image;                     ///< CV_8UC1 reference image
    std::vector<cv::Point2f> points;   ///< labelled points [px, full resolution]
    std::vector<std::uint8_t> labels;  ///< 1 = inlier
};

/// Groups the usable pairs (held out or not, as asked) by reference. `image_of` returns a
/// reference's grey image by database index.
std::vector<TrainingSample> samplesFromPairs(const std::vector<LabelledPair>& pairs, bool held_out,
                                             const std::function<cv::Mat(std::size_t)>& image_of);

struct EpochStats {
    int epoch = 0;          ///< 1-based
    double train_loss = 0;  ///< mean class-balanced BCE over the epoch's steps
    double val_loss = 0;    ///< same loss on the validation samples after the epoch (eval mode)
    double seconds = 0;
};

struct TrainResult {
    std::vector<EpochStats> epochs;
    double initial_val_loss = 0;  ///< before the first step
    double positive_weight = 0;   ///< class weights: N / (2 N_inlier), N / (2 N_outlier)
    double negative_weight = 0;
    int steps = 0;
    double seconds = 0;
};

/// Called after each step with (epoch, step in epoch, steps per epoch, batch loss).
using TrainProgressFn = std::function<void(int, int, int, double)>;

/// Trains `model` in place. Throws std::invalid_argument when `train` is empty, holds only one
/// class of label, or images of different sizes.
TrainResult train(HeatMapModel& model, const std::vector<TrainingSample>& train,
                  const std::vector<TrainingSample>& validation, const TrainingOptions& options,
                  const TrainProgressFn& progress = {});

/// Class-balanced BCE of the model on `samples` with the given class weights (eval mode).
double evaluateLoss(const HeatMapModel& model, const std::vector<TrainingSample>& samples,
                    double positive_weight, double negative_weight);

/// The paper's metric on held-out pairs (Sec. IV: "best sample point classification").
struct PointEvaluation {
    std::size_t pairs = 0;                 ///< usable held-out pairs evaluated
    double best_point_inlier_share = 0;    ///< pairs whose best-scored labelled point is an
                                           ///< inlier
    double random_point_inlier_share = 0;  ///< expectation for a uniformly random labelled point
    double top12_inlier_share = 0;         ///< mean inlier share of the 12 best-scored points
    double heat_inlier_mean = 0;           ///< mean heat at inlier points
    double heat_outlier_mean = 0;          ///< mean heat at outlier points
};

/// Scores every usable pair with `held_out` == true (heat map of its reference, argmax among
/// its labelled points).
PointEvaluation evaluatePoints(const HeatMapModel& model, const std::vector<LabelledPair>& pairs,
                               const std::function<cv::Mat(std::size_t)>& image_of);

}  // namespace lookup::fcn

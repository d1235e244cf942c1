#include "lookup/fcn/trainer.h"

#include <algorithm>
#include <chrono>
#include <map>
#include <numeric>
#include <random>
#include <stdexcept>

#include "model_impl.h"

namespace lookup::fcn {
namespace {

namespace F = torch::nn::functional;

struct Prepared {
    torch::Tensor input;   ///< [1, 1, h, w]
    torch::Tensor grid;    ///< [1, 1, N, 2]
    torch::Tensor target;  ///< [N]
    torch::Tensor weight;  ///< [N]
};

std::vector<Prepared> prepare(const HeatMapModel& model, const std::vector<TrainingSample>& s,
                              double wp, double wn) {
    std::vector<Prepared> out;
    out.reserve(s.size());
    for (const auto& sample : s) {
        Prepared p;
        p.input = model.impl().toInput(sample.image);
        p.grid = normalisedGrid(sample.points, sample.image.size());
        p.target = torch::empty({std::int64_t(sample.labels.size())}, torch::kFloat32);
        p.weight = torch::empty_like(p.target);
        auto t = p.target.accessor<float, 1>();
        auto w = p.weight.accessor<float, 1>();
        for (std::size_t i = 0; i < sample.labels.size(); ++i) {
            t[i] = sample.labels[i] ? 1.f : 0.f;
            w[i] = float(sample.labels[i] ? wp : wn);
        }
        out.push_back(std::move(p));
    }
    return out;
}

// Sum of weighted BCE and sum of weights over the given prepared samples (one forward pass).
std::pair<torch::Tensor, double> batchLoss(SamplePointNet& net, const std::vector<Prepared>& data,
                                           const std::vector<std::size_t>& idx,
                                           const std::vector<std::pair<bool, bool>>& flips) {
    std::vector<torch::Tensor> inputs;
    for (std::size_t k = 0; k < idx.size(); ++k) {
        auto x = data[idx[k]].input;
        if (flips[k].first) x = x.flip({3});
        if (flips[k].second) x = x.flip({2});
        inputs.push_back(x);
    }
    const auto logits = net->forward(torch::cat(inputs, 0));
    torch::Tensor sum = torch::zeros({}, torch::kFloat32);
    double weights = 0;
    for (std::size_t k = 0; k < idx.size(); ++k) {
        const auto& p = data[idx[k]];
        auto grid = p.grid;
        if (flips[k].first || flips[k].second) {
            grid = grid.clone();
            if (flips[k].first) grid.select(3, 0).neg_();
            if (flips[k].second) grid.select(3, 1).neg_();
        }
        const auto at_points = F::grid_sample(logits.narrow(0, std::int64_t(k), 1), grid,
                                              F::GridSampleFuncOptions()
                                                  .mode(torch::kBilinear)
                                                  .padding_mode(torch::kBorder)
                                                  .align_corners(false))
                                   .view({-1});
        sum = sum + F::binary_cross_entropy_with_logits(
                        at_points, p.target,
                        F::BinaryCrossEntropyWithLogitsFuncOptions().weight(p.weight).reduction(
                            torch::kSum));
        weights += p.weight.sum().item<double>();
    }
    return {sum, weights};
}

double meanLoss(SamplePointNet& net, const std::vector<Prepared>& data) {
    if (data.empty()) return 0;
    torch::NoGradGuard no_grad;
    net->eval();
    double sum = 0, weights = 0;
    for (std::size_t i = 0; i < data.size(); ++i) {
        const auto [s, w] = batchLoss(net, data, {i}, {{false, false}});
        sum += s.item<double>();
        weights += w;
    }
    return weights > 0 ? sum / weights : 0;
}

}  // namespace

std::vector<TrainingSample> samplesFromPairs(const std::vector<LabelledPair>& pairs, bool held_out,
                                             const std::function<cv::Mat(std::size_t)>& image_of) {
    std::map<std::size_t, TrainingSample> by_reference;
    for (const auto& p : pairs) {
        if (!p.usable || p.held_out != held_out) continue;
        auto& s = by_reference[p.reference];
        if (s.image.empty()) s.image = image_of(p.reference);
        s.points.insert(s.points.end(), p.points.begin(), p.points.end());
        // Trained on the targets (precise inliers when asked for), never on the metric's labels.
        const auto& labels = p.target.size() == p.points.size() ? p.target : p.inlier;
        s.labels.insert(s.labels.end(), labels.begin(), labels.end());
    }
    std::vector<TrainingSample> out;
    for (auto& [index, s] : by_reference) out.push_back(std::move(s));
    return out;
}

TrainResult train(HeatMapModel& model, const std::vector<TrainingSample>& train_samples,
                  const std::vector<TrainingSample>& validation, const TrainingOptions& options,
                  const TrainProgressFn& progress) {
    options.check();
    if (train_samples.empty()) throw std::invalid_argument("no training samples");
    std::size_t positives = 0, total = 0;
    for (const auto& s : train_samples) {
        if (s.image.size() != train_samples.front().image.size()) {
            throw std::invalid_argument("training images differ in size");
        }
        if (s.points.size() != s.labels.size()) {
            throw std::invalid_argument(
                "a training sample has points and labels of different counts");
        }
        positives += std::count(s.labels.begin(), s.labels.end(), 1);
        total += s.labels.size();
    }
    if (positives == 0 || positives == total) {
        throw std::invalid_argument(std::string("every labelled training point is an ") +
                                    (positives ? "inlier" : "outlier") + ": nothing to learn");
    }
    const auto t0 = std::chrono::steady_clock::now();
    torch::set_num_threads(options.threads);
    torch::manual_seed(options.seed);
    std::mt19937 rng(static_cast<std::uint32_t>(options.seed));

    TrainResult result;
    result.positive_weight = double(total) / (2.0 * positives);
    result.negative_weight = double(total) / (2.0 * (total - positives));
    const auto data = prepare(model, train_samples, result.positive_weight, result.negative_weight);
    const auto val = prepare(model, validation, result.positive_weight, result.negative_weight);

    auto& net = model.impl().net;
    torch::optim::Adam adam(
        net->parameters(),
        torch::optim::AdamOptions(options.learning_rate).weight_decay(options.weight_decay));
    result.initial_val_loss = meanLoss(net, val);
    std::vector<std::size_t> order(data.size());
    std::iota(order.begin(), order.end(), 0);
    const int steps = int((data.size() + options.batch_size - 1) / options.batch_size);
    std::bernoulli_distribution coin(0.5);
    for (int epoch = 1; epoch <= options.epochs; ++epoch) {
        const auto e0 = std::chrono::steady_clock::now();
        net->train();
        std::shuffle(order.begin(), order.end(), rng);
        double epoch_sum = 0, epoch_weights = 0;
        for (int step = 0; step < steps; ++step) {
            const std::size_t begin = std::size_t(step) * options.batch_size;
            const std::size_t end = std::min(order.size(), begin + options.batch_size);
            std::vector<std::size_t> idx(order.begin() + begin, order.begin() + end);
            std::vector<std::pair<bool, bool>> flips;
            for (std::size_t k = 0; k < idx.size(); ++k) {
                flips.emplace_back(options.augment && coin(rng), options.augment && coin(rng));
            }
            adam.zero_grad();
            auto [sum, weights] = batchLoss(net, data, idx, flips);
            const auto loss = sum / weights;
            loss.backward();
            adam.step();
            epoch_sum += sum.item<double>();
            epoch_weights += weights;
            ++result.steps;
            if (progress) progress(epoch, step + 1, steps, loss.item<double>());
        }
        EpochStats e;
        e.epoch = epoch;
        e.train_loss = epoch_sum / epoch_weights;
        e.val_loss = meanLoss(net, val);
        e.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - e0).count();
        result.epochs.push_back(e);
    }
    net->eval();
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return result;
}

double evaluateLoss(const HeatMapModel& model, const std::vector<TrainingSample>& samples,
                    double positive_weight, double negative_weight) {
    auto data = prepare(model, samples, positive_weight, negative_weight);
    auto net = model.impl().net;
    return meanLoss(net, data);
}

PointEvaluation evaluatePoints(const HeatMapModel& model, const std::vector<LabelledPair>& pairs,
                               const std::function<cv::Mat(std::size_t)>& image_of) {
    PointEvaluation ev;
    std::map<std::size_t, cv::Mat> heat;
    double best = 0, random = 0, top = 0, heat_in = 0, heat_out = 0;
    std::size_t n_in = 0, n_out = 0;
    for (const auto& p : pairs) {
        if (!p.usable || !p.held_out || p.points.empty()) continue;
        auto it = heat.find(p.reference);
        if (it == heat.end())
            it = heat.emplace(p.reference, model.predict(image_of(p.reference))).first;
        const auto scores = sampleAt(it->second, p.points);
        std::vector<std::size_t> rank(scores.size());
        std::iota(rank.begin(), rank.end(), 0);
        // Ties (equal scores) go to the first point, so the result is deterministic.
        std::stable_sort(rank.begin(), rank.end(),
                         [&](std::size_t a, std::size_t b) { return scores[a] > scores[b]; });
        best += p.inlier[rank[0]];
        random += double(p.inliers) / p.points.size();
        const std::size_t k = std::min<std::size_t>(12, rank.size());
        double top_inliers = 0;
        for (std::size_t i = 0; i < k; ++i) top_inliers += p.inlier[rank[i]];
        top += top_inliers / k;
        for (std::size_t i = 0; i < scores.size(); ++i) {
            (p.inlier[i] ? heat_in : heat_out) += scores[i];
            ++(p.inlier[i] ? n_in : n_out);
        }
        ++ev.pairs;
    }
    if (ev.pairs) {
        ev.best_point_inlier_share = best / ev.pairs;
        ev.random_point_inlier_share = random / ev.pairs;
        ev.top12_inlier_share = top / ev.pairs;
    }
    ev.heat_inlier_mean = n_in ? heat_in / n_in : 0;
    ev.heat_outlier_mean = n_out ? heat_out / n_out : 0;
    return ev;
}

}  // namespace lookup::fcn

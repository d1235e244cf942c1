#include <c10/util/Exception.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <opencv2/imgproc.hpp>

#include "lookup/common/errors.h"
#include "lookup/common/grey.h"
#include "model_impl.h"

namespace lookup::fcn {
namespace {

constexpr std::int64_t kFormatVersion = 1;
constexpr const char* kFormatKey = "lookup_fcn_format";
constexpr const char* kArchKey = "lookup_fcn_architecture";
constexpr const char* kScaleKey = "lookup_fcn_input_scale";

torch::nn::Sequential convBlock(int in, int out) {
    namespace nn = torch::nn;
    return nn::Sequential(nn::Conv2d(nn::Conv2dOptions(in, out, 3).padding(1)), nn::ReLU(),
                          nn::Conv2d(nn::Conv2dOptions(out, out, 3).padding(1)), nn::ReLU());
}

int stageChannels(const NetworkOptions& o, int stage) {
    return std::min(o.max_channels, o.base_channels << stage);
}

}  // namespace

SamplePointNetImpl::SamplePointNetImpl(const NetworkOptions& o) {
    int in = 1;
    for (int i = 0; i < o.depth; ++i) {
        encoder.push_back(
            register_module("enc" + std::to_string(i), convBlock(in, stageChannels(o, i))));
        in = stageChannels(o, i);
    }
    decoder.resize(std::max(0, o.depth - 1));
    for (int i = o.depth - 2; i >= 0; --i) {
        decoder[i] = register_module(
            "dec" + std::to_string(i),
            convBlock(stageChannels(o, i + 1) + stageChannels(o, i), stageChannels(o, i)));
    }
    head = register_module("head",
                           torch::nn::Conv2d(torch::nn::Conv2dOptions(stageChannels(o, 0), 1, 1)));
}

torch::Tensor SamplePointNetImpl::forward(torch::Tensor x) {
    namespace F = torch::nn::functional;
    std::vector<torch::Tensor> skips;
    for (std::size_t i = 0; i < encoder.size(); ++i) {
        if (i > 0) x = F::max_pool2d(x, F::MaxPool2dFuncOptions(2).ceil_mode(true));
        x = encoder[i]->forward(x);
        skips.push_back(x);
    }
    for (int i = int(decoder.size()) - 1; i >= 0; --i) {
        const auto& skip = skips[i];
        x = F::interpolate(x, F::InterpolateFuncOptions()
                                  .size(std::vector<int64_t>{skip.size(2), skip.size(3)})
                                  .mode(torch::kBilinear)
                                  .align_corners(false));
        x = decoder[i]->forward(torch::cat({x, skip}, 1));
    }
    return head->forward(x);
}

torch::Tensor HeatMapModel::Impl::toInput(const cv::Mat& image) const {
    const cv::Mat grey = common::greyOf(image);
    CV_Assert(grey.type() == CV_8UC1 && !grey.empty());
    cv::Mat small;
    const cv::Size size(std::max(1, int(std::lround(grey.cols * options.input_scale))),
                        std::max(1, int(std::lround(grey.rows * options.input_scale))));
    if (size == grey.size()) {
        small = grey;
    } else {
        cv::resize(grey, small, size, 0, 0, cv::INTER_AREA);
    }
    cv::Mat f;
    small.convertTo(f, CV_32F, 1.0 / 255.0);
    cv::Scalar mean, dev;
    cv::meanStdDev(f, mean, dev);
    f = (f - mean[0]) / (dev[0] + 1e-2);
    return torch::from_blob(f.data, {1, 1, f.rows, f.cols}, torch::kFloat32).clone();
}

torch::Tensor normalisedGrid(const std::vector<cv::Point2f>& points, cv::Size image_size) {
    auto grid = torch::empty({1, 1, std::int64_t(points.size()), 2}, torch::kFloat32);
    auto a = grid.accessor<float, 4>();
    for (std::size_t i = 0; i < points.size(); ++i) {
        a[0][0][i][0] = (points[i].x + 0.5f) / float(image_size.width) * 2.f - 1.f;
        a[0][0][i][1] = (points[i].y + 0.5f) / float(image_size.height) * 2.f - 1.f;
    }
    return grid;
}

HeatMapModel::HeatMapModel() : impl_(std::make_unique<Impl>()) {}

HeatMapModel::HeatMapModel(const NetworkOptions& options, int seed) : HeatMapModel() {
    options.check();
    impl_->options = options;
    torch::manual_seed(seed);
    impl_->net = SamplePointNet(options);
}

HeatMapModel::~HeatMapModel() = default;
HeatMapModel::HeatMapModel(HeatMapModel&&) noexcept = default;
HeatMapModel& HeatMapModel::operator=(HeatMapModel&&) noexcept = default;

const NetworkOptions& HeatMapModel::options() const { return impl_->options; }

std::size_t HeatMapModel::parameterCount() const {
    std::size_t n = 0;
    for (const auto& p : impl_->net->parameters()) n += p.numel();
    return n;
}

cv::Mat HeatMapModel::predictAtNetworkScale(const cv::Mat& image) const {
    torch::NoGradGuard no_grad;
    impl_->net->eval();
    const auto logits = impl_->net->forward(impl_->toInput(image));
    const auto prob = torch::sigmoid(logits).contiguous();
    return cv::Mat(int(prob.size(2)), int(prob.size(3)), CV_32FC1, prob.data_ptr<float>()).clone();
}

cv::Mat HeatMapModel::predict(const cv::Mat& image) const {
    const cv::Mat small = predictAtNetworkScale(image);
    if (small.size() == image.size()) return small;
    cv::Mat heat;
    cv::resize(small, heat, image.size(), 0, 0, cv::INTER_LINEAR);
    return heat;
}

void HeatMapModel::save(const std::string& path) const {
    const std::string tmp = path + ".tmp";
    try {
        torch::serialize::OutputArchive archive;
        const auto& o = impl_->options;
        archive.write(kFormatKey, torch::tensor({kFormatVersion}, torch::kInt64));
        archive.write(kArchKey, torch::tensor({std::int64_t(o.base_channels),
                                               std::int64_t(o.max_channels), std::int64_t(o.depth)},
                                              torch::kInt64));
        archive.write(kScaleKey, torch::tensor({o.input_scale}, torch::kFloat64));
        impl_->net->save(archive);
        archive.save_to(tmp);
        std::filesystem::rename(tmp, path);
    } catch (const std::exception& e) {
        std::error_code ec;
        std::filesystem::remove(tmp, ec);
        throw common::WriteError(path, std::string("cannot write the model: ") + e.what());
    }
}

HeatMapModel HeatMapModel::load(const std::string& path, const NetworkOptions* expected) {
    if (!std::filesystem::is_regular_file(path)) throw ModelError(path + ": no such model file");
    torch::serialize::InputArchive archive;
    try {
        archive.load_from(path);
    } catch (const std::exception& e) {
        // c10::Error messages carry a C++ backtrace; its first line says enough.
        std::string what = e.what();
        what = what.substr(0, what.find('\n'));
        throw ModelError(path + ": not a readable model file (corrupt or truncated): " + what);
    }
    torch::Tensor format, arch, scale;
    if (!archive.try_read(kFormatKey, format) || !archive.try_read(kArchKey, arch) ||
        !archive.try_read(kScaleKey, scale) || arch.numel() != 3 || scale.numel() != 1) {
        throw ModelError(path + ": not a LookUP FCN model (architecture header missing)");
    }
    if (format.item<std::int64_t>() != kFormatVersion) {
        throw ModelError(path + ": unsupported model format version " +
                         std::to_string(format.item<std::int64_t>()));
    }
    NetworkOptions options;
    options.base_channels = int(arch[0].item<std::int64_t>());
    options.max_channels = int(arch[1].item<std::int64_t>());
    options.depth = int(arch[2].item<std::int64_t>());
    options.input_scale = scale.item<double>();
    try {
        options.check();
    } catch (const std::exception& e) {
        throw ModelError(path + ": invalid architecture header: " + e.what());
    }
    if (expected && *expected != options) {
        throw ModelError(path + ": model of another architecture (" + options.describe() +
                         ") where " + expected->describe() + " is configured");
    }
    HeatMapModel model(options);
    try {
        model.impl_->net->load(archive);
    } catch (const std::exception& e) {
        std::string what = e.what();
        what = what.substr(0, what.find('\n'));
        throw ModelError(path + ": weights do not fit the architecture in its header: " + what);
    }
    return model;
}

std::vector<float> sampleAt(const cv::Mat& map, const std::vector<cv::Point2f>& points) {
    CV_Assert(map.type() == CV_32FC1 && !map.empty());
    std::vector<float> out;
    out.reserve(points.size());
    for (const auto& p : points) {
        const float x = std::clamp(p.x, 0.f, float(map.cols - 1));
        const float y = std::clamp(p.y, 0.f, float(map.rows - 1));
        const int x0 = std::min(int(x), map.cols - 2 < 0 ? 0 : map.cols - 2);
        const int y0 = std::min(int(y), map.rows - 2 < 0 ? 0 : map.rows - 2);
        const int x1 = std::min(x0 + 1, map.cols - 1), y1 = std::min(y0 + 1, map.rows - 1);
        const float ax = x - x0, ay = y - y0;
        out.push_back((1 - ay) * ((1 - ax) * map.at<float>(y0, x0) + ax * map.at<float>(y0, x1)) +
                      ay * ((1 - ax) * map.at<float>(y1, x0) + ax * map.at<float>(y1, x1)));
    }
    return out;
}

}  // namespace lookup::fcn

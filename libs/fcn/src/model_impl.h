#pragma once
// Private: the LibTorch side of HeatMapModel, shared by model.cpp and trainer.cpp.

#include <torch/torch.h>

#include <opencv2/core.hpp>

#include "lookup/fcn/model.h"

namespace lookup::fcn {

/// Encoder stages of two 3x3 conv + ReLU (channels base * 2^i, capped), 2x2 max-pooling
/// between stages; decoder stages upsample (bilinear) to the skip's size, concatenate the skip
/// and apply two 3x3 conv + ReLU; a 1x1 conv gives the logit (the paper's FCN: VGG16 encoder,
/// 1x1 conv, up-sampling with skips to layer3 / layer4).
struct SamplePointNetImpl : torch::nn::Module {
    explicit SamplePointNetImpl(const NetworkOptions& options);
    /// x: [B, 1, h, w] normalised grey; returns logits [B, 1, h, w].
    torch::Tensor forward(torch::Tensor x);

    std::vector<torch::nn::Sequential> encoder;
    std::vector<torch::nn::Sequential> decoder;  ///< decoder[i] produces stage i's resolution
    torch::nn::Conv2d head{nullptr};
};
TORCH_MODULE(SamplePointNet);

struct HeatMapModel::Impl {
    NetworkOptions options;
    SamplePointNet net{nullptr};

    /// Grey image -> [1, 1, h, w] float tensor at options.input_scale, zero mean, unit
    /// deviation (exposure invariance).
    torch::Tensor toInput(const cv::Mat& image) const;
};

/// Normalised grid_sample coordinates (align_corners = false) of full-resolution pixels.
torch::Tensor normalisedGrid(const std::vector<cv::Point2f>& points, cv::Size image_size);

}  // namespace lookup::fcn

#pragma once
// The sample-point quality network (paper Sec. III-B, Fig. 3 "Sample Point Selector"): a small
// fully convolutional encoder-decoder with skip connections that maps a grey ceiling image to
// one logit per pixel; sigmoid(logit) is the heat map the localiser samples from. LibTorch is
// hidden behind this pImpl so that no public header needs it.

#include <cstddef>
#include <memory>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <string>
#include <vector>

#include "lookup/fcn/options.h"

namespace lookup::fcn {

/// A model file that cannot be used: the message names the file and the reason (corrupt,
/// truncated, not a LookUP FCN, or another architecture).
class ModelError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

class HeatMapModel {
  public:
    /// A freshly initialised network (weights drawn after torch::manual_seed(seed)).
    /// Throws common::ConfigError when `options` are invalid.
    explicit HeatMapModel(const NetworkOptions& options, int seed = 1);
    ~HeatMapModel();
    HeatMapModel(HeatMapModel&&) noexcept;
    HeatMapModel& operator=(HeatMapModel&&) noexcept;

    /// Loads a file written by save(). With `expected`, a file of another architecture is
    /// refused. Throws ModelError naming `path`.
    static HeatMapModel load(const std::string& path, const NetworkOptions* expected = nullptr);
    /// Writes the architecture header and the weights (torch::serialize archive) to `path`
    /// via `<path>.tmp` + rename. Throws common::WriteError naming `path` on failure.
    void save(const std::string& path) const;

    const NetworkOptions& options() const;
    std::size_t parameterCount() const;

    /// Heat map of a grey image (CV_8UC1, or CV_8UC3 converted): CV_32FC1 of the image's size,
    /// values sigmoid(logit) in [0, 1], larger = better sample point.
    cv::Mat predict(const cv::Mat& image) const;
    /// The same map at the network's resolution (the image scaled by input_scale): what the
    /// database stores; predict() is it resized (bilinear) to the image.
    cv::Mat predictAtNetworkScale(const cv::Mat& image) const;

    struct Impl;  ///< LibTorch module and helpers (src/model_impl.h)
    Impl& impl() { return *impl_; }
    const Impl& impl() const { return *impl_; }

  private:
    HeatMapModel();
    std::unique_ptr<Impl> impl_;
};

/// Bilinear value of a CV_32FC1 map at each point (clamped to the map).
std::vector<float> sampleAt(const cv::Mat& map, const std::vector<cv::Point2f>& points);

}  // namespace lookup::fcn

#pragma once
// Sample Point Selector (paper Sec. III-B): a regular grid, or greedy selection on a sample
// quality heat map: take the best pixel, multiply its l_n x l_n neighbourhood by rho, repeat
// until N distinct points. Points keep border_margin_px (heat map: SamplerOptions::heatMapMargin)
// from the image border. Deterministic.

#include <opencv2/core.hpp>
#include <vector>

#include "lookup/refine/options.h"

namespace lookup::refine {

/// `count` points on a regular grid (cell centres, columns/rows following the aspect ratio)
/// inside the image shrunk by `margin_px`. Empty when the shrunk image is empty.
std::vector<cv::Point2f> gridPoints(cv::Size image_size, int count, int margin_px);

/// Greedy heat-map selection of `count` distinct points. `heat_map` is CV_32FC1 (values >= 0;
/// larger is better). Empty when the map holds a non-finite value or the shrunk map is empty.
std::vector<cv::Point2f> heatMapPoints(const cv::Mat& heat_map, int count, double damping_ratio,
                                       int damping_side_px, int margin_px);

/// True when `a` and `b` select the same points from the same image and heat map.
bool sameSelection(const SamplerOptions& a, const SamplerOptions& b);

/// Applies `options.mode`: the heat map unless Grid or `heat_map` is empty, else the grid.
std::vector<cv::Point2f> selectSamplePoints(cv::Size image_size, const cv::Mat& heat_map,
                                            const SamplerOptions& options);

}  // namespace lookup::refine

#include "lookup/refine/sampler.h"

#include <cmath>
#include <limits>

namespace lookup::refine {

std::vector<cv::Point2f> gridPoints(cv::Size image_size, int count, int margin_px) {
    std::vector<cv::Point2f> points;
    const double w = image_size.width - 2.0 * margin_px;
    const double h = image_size.height - 2.0 * margin_px;
    if (count <= 0 || w < 1.0 || h < 1.0) return points;
    // Pick cols x rows >= count whose cells are closest to square, fewest spare cells first.
    int best_cols = 1, best_rows = count;
    double best_cost = std::numeric_limits<double>::max();
    for (int cols = 1; cols <= count; ++cols) {
        const int rows = (count + cols - 1) / cols;
        const double cell_aspect = (w / cols) / (h / rows);
        const double cost = std::abs(std::log(cell_aspect)) + 0.5 * (cols * rows - count);
        if (cost < best_cost) {
            best_cost = cost;
            best_cols = cols;
            best_rows = rows;
        }
    }
    for (int r = 0; r < best_rows && int(points.size()) < count; ++r) {
        for (int c = 0; c < best_cols && int(points.size()) < count; ++c) {
            points.emplace_back(float(std::floor(margin_px + (c + 0.5) * w / best_cols)),
                                float(std::floor(margin_px + (r + 0.5) * h / best_rows)));
        }
    }
    return points;
}

std::vector<cv::Point2f> heatMapPoints(const cv::Mat& heat_map, int count, double damping_ratio,
                                       int damping_side_px, int margin_px) {
    std::vector<cv::Point2f> points;
    if (heat_map.empty() || heat_map.type() != CV_32FC1 || count <= 0) return points;
    if (!cv::checkRange(heat_map)) return points;  // NaN or infinity
    const cv::Rect inner(margin_px, margin_px, heat_map.cols - 2 * margin_px,
                         heat_map.rows - 2 * margin_px);
    if (inner.width <= 0 || inner.height <= 0) return points;
    cv::Mat map = heat_map(inner).clone();
    double lo = 0.0;
    cv::minMaxLoc(map, &lo);
    if (lo < 0.0) map -= lo;  // damping by a factor needs non-negative values
    const int half = damping_side_px / 2;
    for (int i = 0; i < count; ++i) {
        cv::Point best;
        double value = 0.0;
        cv::minMaxLoc(map, nullptr, &value, nullptr, &best);
        if (value < 0.0) break;  // every pixel taken
        points.emplace_back(float(best.x + margin_px), float(best.y + margin_px));
        const cv::Rect hood =
            cv::Rect(best.x - half, best.y - half, damping_side_px, damping_side_px) &
            cv::Rect(0, 0, map.cols, map.rows);
        map(hood) *= damping_ratio;
        map.at<float>(best) = -1.0f;  // chosen: never again (values are >= 0)
    }
    return points;
}

std::vector<cv::Point2f> selectSamplePoints(cv::Size image_size, const cv::Mat& heat_map,
                                            const SamplerOptions& o) {
    const bool use_heat =
        o.mode == SamplingMode::HeatMap || (o.mode == SamplingMode::Auto && !heat_map.empty());
    if (use_heat) {
        if (heat_map.size() != image_size) return {};
        return heatMapPoints(heat_map, o.heat_map_points, o.damping_ratio, o.damping_side_px,
                             o.heatMapMargin());
    }
    return gridPoints(image_size, o.grid_points, o.border_margin_px);
}

bool sameSelection(const SamplerOptions& a, const SamplerOptions& b) {
    return a.mode == b.mode && a.grid_points == b.grid_points &&
           a.heat_map_points == b.heat_map_points && a.damping_ratio == b.damping_ratio &&
           a.damping_side_px == b.damping_side_px && a.border_margin_px == b.border_margin_px &&
           a.heatMapMargin() == b.heatMapMargin();
}

}  // namespace lookup::refine

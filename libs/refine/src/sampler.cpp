#include "lookup/refine/sampler.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

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
    // NaN or infinity anywhere refuses the map: exponent bits all set (cv::checkRange's
    // generic pass cost more than the selection below).
    std::uint32_t non_finite = 0;
    for (int y = 0; y < heat_map.rows; ++y) {
        const auto* row = heat_map.ptr<std::uint32_t>(y);
        for (int x = 0; x < heat_map.cols; ++x) non_finite |= (row[x] & 0x7f800000u) == 0x7f800000u;
    }
    if (non_finite) return points;
    const cv::Rect inner(margin_px, margin_px, heat_map.cols - 2 * margin_px,
                         heat_map.rows - 2 * margin_px);
    if (inner.width <= 0 || inner.height <= 0) return points;
    cv::Mat map = heat_map(inner).clone();
    // Greedy: the highest pixel, then its neighbourhood damped. The maximum is kept per tile,
    // so each pick rescans only the tiles its damping touched: the same points as cv::minMaxLoc
    // over the whole map per pick (first maximum in row-major order on ties), which cost 1.4 ms
    // per 640x480 reference for 12 points (each new reference of a heat-map run pays it;
    // lookup-bench HeatMapPoints_640x480_12pts).
    constexpr int kTile = 16;
    const int tiles_x = (map.cols + kTile - 1) / kTile, tiles_y = (map.rows + kTile - 1) / kTile;
    struct TileBest {
        float value;
        int index;  // y * cols + x of its first maximum
        float low;  // its minimum
    };
    std::vector<TileBest> tiles(static_cast<std::size_t>(tiles_x) * tiles_y);
    const auto rescan = [&](int tx, int ty) {
        const int x0 = tx * kTile, y0 = ty * kTile;
        const int x1 = std::min(map.cols, x0 + kTile), y1 = std::min(map.rows, y0 + kTile);
        // Maximum and minimum first, in independent lanes (a compare-and-index chain does not
        // vectorise), then the first pixel holding the maximum.
        float hi = -std::numeric_limits<float>::infinity(), low = -hi;
        for (int y = y0; y < y1; ++y) {
            const float* row = map.ptr<float>(y);
            int x = x0;
#if defined(__SSE2__)
            __m128 vhi = _mm_set1_ps(hi), vlo = _mm_set1_ps(low);
            for (; x + 4 <= x1; x += 4) {
                const __m128 v = _mm_loadu_ps(row + x);
                vhi = _mm_max_ps(vhi, v);
                vlo = _mm_min_ps(vlo, v);
            }
            alignas(16) float h[4], l[4];
            _mm_store_ps(h, vhi);
            _mm_store_ps(l, vlo);
            for (int k = 0; k < 4; ++k) hi = std::max(hi, h[k]), low = std::min(low, l[k]);
#endif
            for (; x < x1; ++x) hi = std::max(hi, row[x]), low = std::min(low, row[x]);
        }
        int index = -1;
        for (int y = y0; y < y1 && index < 0; ++y) {
            const float* row = map.ptr<float>(y);
            for (int x = x0; x < x1; ++x) {
                if (row[x] == hi) {
                    index = y * map.cols + x;
                    break;
                }
            }
        }
        tiles[static_cast<std::size_t>(ty) * tiles_x + tx] = {hi, index, low};
    };
    const auto rescanAll = [&] {
        for (int ty = 0; ty < tiles_y; ++ty)
            for (int tx = 0; tx < tiles_x; ++tx) rescan(tx, ty);
    };
    rescanAll();
    float lo = 0.0f;
    for (const TileBest& t : tiles) lo = std::min(lo, t.low);
    if (lo < 0.0f) {  // damping by a factor needs non-negative values
        map -= lo;
        rescanAll();
    }

    const int half = damping_side_px / 2;
    for (int i = 0; i < count; ++i) {
        const TileBest* top = &tiles.front();
        for (const TileBest& t : tiles) {
            if (t.value > top->value || (t.value == top->value && t.index < top->index)) top = &t;
        }
        if (top->index < 0 || top->value < 0.0f) break;  // every pixel taken
        const cv::Point best(top->index % map.cols, top->index / map.cols);
        points.emplace_back(float(best.x + margin_px), float(best.y + margin_px));
        const cv::Rect hood =
            cv::Rect(best.x - half, best.y - half, damping_side_px, damping_side_px) &
            cv::Rect(0, 0, map.cols, map.rows);
        map(hood) *= damping_ratio;
        map.at<float>(best) = -1.0f;  // chosen: never again (values are >= 0)
        const cv::Rect touched = hood | cv::Rect(best, cv::Size(1, 1));
        for (int ty = touched.y / kTile; ty <= (touched.br().y - 1) / kTile; ++ty)
            for (int tx = touched.x / kTile; tx <= (touched.br().x - 1) / kTile; ++tx)
                rescan(tx, ty);
    }
    return points;
}

std::vector<cv::Point2f> selectSamplePoints(cv::Size image_size, const cv::Mat& heat_map,
                                            const SamplerOptions& o) {
    if (o.mode != SamplingMode::Grid && !heat_map.empty()) {
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

#include <gtest/gtest.h>

#include <cmath>
#include <set>
#include <tuple>
#include <vector>

#include "lookup/refine/sampler.h"

using namespace lookup::refine;

TEST(Sampler, GridHasCountPointsInsideTheMarginAndSpread) {
    const auto pts = gridPoints(cv::Size(640, 480), 24, 30);
    ASSERT_EQ(pts.size(), 24u);
    std::set<float> xs, ys;
    for (const auto& p : pts) {
        EXPECT_GE(p.x, 30);
        EXPECT_LT(p.x, 640 - 30);
        EXPECT_GE(p.y, 30);
        EXPECT_LT(p.y, 480 - 30);
        xs.insert(p.x);
        ys.insert(p.y);
    }
    EXPECT_EQ(xs.size() * ys.size(), 24u);  // 6 x 4 on a 4:3 image
    EXPECT_EQ(xs.size(), 6u);
    EXPECT_TRUE(gridPoints(cv::Size(40, 40), 12, 20).empty());
}

TEST(Sampler, HeatMapPicksPeaksThenDampsNeighbourhood) {
    cv::Mat heat(100, 100, CV_32F, cv::Scalar(0.1f));
    heat.at<float>(50, 50) = 1.0f;
    heat.at<float>(52, 52) = 0.9f;  // inside l_n of the first: damped to 0.45 after it
    heat.at<float>(20, 70) = 0.8f;
    const auto pts = heatMapPoints(heat, 3, 0.5, 10, 10);
    ASSERT_EQ(pts.size(), 3u);
    EXPECT_EQ(pts[0], cv::Point2f(50, 50));
    EXPECT_EQ(pts[1], cv::Point2f(70, 20));
    EXPECT_EQ(pts[2], cv::Point2f(52, 52));
    // Deterministic.
    EXPECT_EQ(heatMapPoints(heat, 3, 0.5, 10, 10), pts);
}

namespace {
/// The selection as first written: cv::minMaxLoc over the whole map for every point.
std::vector<cv::Point2f> wholeMapSelection(const cv::Mat& heat, int count, double ratio, int side,
                                           int margin) {
    std::vector<cv::Point2f> points;
    cv::Mat map =
        heat(cv::Rect(margin, margin, heat.cols - 2 * margin, heat.rows - 2 * margin)).clone();
    double lo = 0.0;
    cv::minMaxLoc(map, &lo);
    if (lo < 0.0) map -= lo;
    for (int i = 0; i < count; ++i) {
        cv::Point best;
        double value = 0.0;
        cv::minMaxLoc(map, nullptr, &value, nullptr, &best);
        if (value < 0.0) break;
        points.emplace_back(float(best.x + margin), float(best.y + margin));
        map(cv::Rect(best.x - side / 2, best.y - side / 2, side, side) &
            cv::Rect(0, 0, map.cols, map.rows)) *= ratio;
        map.at<float>(best) = -1.0f;
    }
    return points;
}
}  // namespace

TEST(Sampler, HeatMapSelectionEqualsAWholeMapSearchPerPoint) {
    // Tiles of maxima must pick exactly what a search of the whole map picks, ties included
    // (values quantised to 8 levels: many equal maxima), on sizes that are not whole tiles,
    // with negative values, and when more points are asked than pixels exist.
    cv::RNG rng(5);
    for (const auto& [size, count, ratio, side, margin] :
         std::vector<std::tuple<cv::Size, int, double, int, int>>{{{640, 480}, 12, 0.5, 40, 20},
                                                                  {{203, 151}, 30, 0.8, 25, 7},
                                                                  {{37, 29}, 20, 0.3, 9, 3},
                                                                  {{20, 18}, 500, 0.9, 5, 2}}) {
        cv::Mat heat(size, CV_32F);
        rng.fill(heat, cv::RNG::UNIFORM, -0.2, 1.0);
        cv::Mat coarse = heat * 8;
        for (int y = 0; y < heat.rows; ++y)
            for (int x = 0; x < heat.cols; ++x)
                heat.at<float>(y, x) = std::floor(coarse.at<float>(y, x)) / 8.0f;
        const auto expected = wholeMapSelection(heat, count, ratio, side, margin);
        EXPECT_EQ(heatMapPoints(heat, count, ratio, side, margin), expected)
            << size << " " << count << " points";
        EXPECT_EQ(expected.size(), std::min<std::size_t>(count, (size.width - 2 * margin) *
                                                                    (size.height - 2 * margin)));
    }
}

TEST(Sampler, HeatMapRespectsMarginAndRefusesNaN) {
    cv::Mat heat(100, 100, CV_32F, cv::Scalar(0.0f));
    heat.at<float>(2, 2) = 5.0f;  // inside the margin: never chosen
    const auto pts = heatMapPoints(heat, 5, 0.5, 10, 20);
    ASSERT_EQ(pts.size(), 5u);
    for (const auto& p : pts) {
        EXPECT_GE(p.x, 20);
        EXPECT_LT(p.x, 80);
    }
    heat.at<float>(50, 50) = std::numeric_limits<float>::quiet_NaN();
    EXPECT_TRUE(heatMapPoints(heat, 5, 0.5, 10, 20).empty());
}

TEST(Sampler, HeatMapMarginMovesOnlyHeatMapPoints) {
    SamplerOptions o;
    o.border_margin_px = 20;
    o.heat_map_margin_px = 40;
    cv::Mat heat(120, 160, CV_32F, cv::Scalar(0.0f));
    heat.at<float>(25, 80) = 1.0f;  // best value, but 25 px from the top: outside 40 px
    const auto pts = selectSamplePoints(heat.size(), heat, o);
    ASSERT_EQ(pts.size(), size_t(o.heat_map_points));
    for (const auto& p : pts) {
        EXPECT_GE(p.x, 40);
        EXPECT_GE(p.y, 40);
        EXPECT_LT(p.x, 120);
        EXPECT_LT(p.y, 80);
    }
    // The grid keeps border_margin_px; a heat-map margin below it changes nothing.
    EXPECT_EQ(selectSamplePoints(heat.size(), cv::Mat(), o),
              gridPoints(heat.size(), o.grid_points, 20));
    SamplerOptions below = o;
    below.heat_map_margin_px = 10;
    EXPECT_EQ(below.heatMapMargin(), 20);
    EXPECT_EQ(selectSamplePoints(heat.size(), heat, below)[0], cv::Point2f(80, 25));
    // Cached points are reused only for the same margins.
    EXPECT_FALSE(sameSelection(o, below));
}

TEST(Sampler, AutoModeUsesHeatMapWhenPresent) {
    SamplerOptions o;
    cv::Mat heat(120, 160, CV_32F, cv::Scalar(0.0f));
    heat.at<float>(60, 80) = 1.0f;
    EXPECT_EQ(selectSamplePoints(heat.size(), heat, o).size(), size_t(o.heat_map_points));
    EXPECT_EQ(selectSamplePoints(heat.size(), heat, o)[0], cv::Point2f(80, 60));
    EXPECT_EQ(selectSamplePoints(heat.size(), cv::Mat(), o).size(), size_t(o.grid_points));
}

// A reference without a heat map in a heat-map run (one the localiser's online refresh added):
// the grid, not no points at all.
TEST(Sampler, HeatMapModeWithoutAHeatMapUsesTheGrid) {
    SamplerOptions o;
    o.mode = SamplingMode::HeatMap;
    const cv::Size size(160, 120);
    EXPECT_EQ(selectSamplePoints(size, cv::Mat(), o),
              gridPoints(size, o.grid_points, o.border_margin_px));
    cv::Mat heat(size, CV_32F, cv::Scalar(0.0f));
    heat.at<float>(60, 80) = 1.0f;
    EXPECT_EQ(selectSamplePoints(size, heat, o).size(), size_t(o.heat_map_points));
    o.mode = SamplingMode::Grid;
    EXPECT_EQ(selectSamplePoints(size, heat, o).size(), size_t(o.grid_points));
}

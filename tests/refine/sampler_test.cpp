#include <gtest/gtest.h>

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

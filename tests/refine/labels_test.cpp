#include <gtest/gtest.h>

#include "lookup/refine/labels.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

using namespace lookup::refine;
using mrpt::poses::CPose3D;

// Dense grid -> match -> RANSAC on a pair with an object pasted into the query: points whose
// match falls on the object are labelled outliers, the rest of the ceiling inliers.
TEST(Labels, GridPointsOnAnObjectAreOutliers) {
    const auto ceiling = synthetic::SyntheticCeiling::make(5.0, 10.0, 0.01, 5);
    const auto cam = synthetic::makeCamera(320, 240, 250);
    const CPose3D on = synthetic::ceilingCameraOnVehicle();
    const cv::Mat ref = ceiling.render(cam, CPose3D() + on);
    cv::Mat qry = ceiling.render(cam, CPose3D(0.07, 0.0, 0, 0, 0, 0) + on);  // 5 px left
    const cv::Rect object(200, 60, 90, 90);
    synthetic::makeNoiseTexture(object.size(), 31).copyTo(qry(object));

    MatcherOptions m;
    HomographyResult fit;
    const auto labels = labelGridPoints(ref, qry, 20, m, HomographyOptions(), &fit);
    ASSERT_TRUE(fit.ok) << fit.reason;
    int inside = 0, inside_inliers = 0, outside = 0, outside_inliers = 0;
    for (const auto& p : labels) {
        const cv::Point2f where = p.reference_px - cv::Point2f(5, 0);
        // A patch fully on the object / fully off it (patch half-side 20 px).
        const bool on_object = where.x - 20 >= object.x && where.x + 20 <= object.br().x &&
                               where.y - 20 >= object.y && where.y + 20 <= object.br().y;
        // ... and whose search window is not clipped by the image border (there the peak lies
        // on the clipped border and the matcher rightly refuses it).
        const bool off_object =
            (cv::Rect(where.x - 20, where.y - 20, 40, 40) & object).area() == 0 &&
            p.reference_px.x >= 40 && p.reference_px.y >= 40 && p.reference_px.x <= 280 &&
            p.reference_px.y <= 200;
        if (on_object) {
            ++inside;
            inside_inliers += p.inlier ? 1 : 0;
        } else if (off_object) {
            ++outside;
            outside_inliers += p.inlier ? 1 : 0;
        }
    }
    EXPECT_GE(inside, 4);
    EXPECT_EQ(inside_inliers, 0);
    EXPECT_GT(outside_inliers, outside * 9 / 10);
}

#include <gtest/gtest.h>

#include <cmath>

#include "lookup/refine/estimator.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

using namespace lookup::refine;
using mrpt::poses::CPose3D;

namespace {

const double kTrueHeight = 5.3;

Pinhole camera() { return {250, 250, 159.5, 119.5}; }

// Exact correspondences: grid pixels of the reference -> ceiling (true height) -> query.
ReferenceView view(const CPose3D& ref_vehicle, const CPose3D& query_vehicle) {
    const CPose3D on_vehicle = synthetic::ceilingCameraOnVehicle();
    ReferenceView v;
    v.camera = camera();
    v.camera_in_map = ref_vehicle + on_vehicle;
    for (int y = 20; y < 240; y += 40) {
        for (int x = 20; x < 320; x += 40) {
            const auto p = backProjectToCeiling(v.camera, v.camera_in_map, {double(x), double(y)},
                                                kTrueHeight);
            const auto q = projectToImage(camera(), query_vehicle + on_vehicle, *p);
            if (!q || q->x < 0 || q->y < 0 || q->x > 319 || q->y > 239) continue;
            v.reference_px.emplace_back(x, y);
            v.query_px.push_back(*q);
        }
    }
    return v;
}

EstimatorInput input(const CPose3D& truth, const std::vector<CPose3D>& refs) {
    EstimatorInput in;
    for (const auto& r : refs) in.views.push_back(view(r, truth));
    in.query_camera = camera();
    in.query_camera_on_vehicle = synthetic::ceilingCameraOnVehicle();
    in.ceiling_height_m = 5.0;  // prior 6 % low
    return in;
}

}  // namespace

TEST(Estimator, TwoReferencesMakeTheScaleObservable) {
    const CPose3D truth(0.25, 0.1, 0, 0.05, 0, 0);
    EstimatorOptions o;
    o.ceiling_height_sigma_m = 1.0;  // weak prior: the images must fix h
    const auto e = estimateQueryPose(input(truth, {CPose3D(), CPose3D(0.6, -0.1, 0, 0, 0, 0)}), o);
    ASSERT_TRUE(e.ok) << e.reason;
    EXPECT_NEAR(e.ceiling_height_m, kTrueHeight, 0.01 * kTrueHeight);
    EXPECT_NEAR(e.vehicle_in_map.x(), 0.25, 1e-3);
    EXPECT_NEAR(e.vehicle_in_map.y(), 0.1, 1e-3);
    EXPECT_NEAR(e.vehicle_in_map.yaw(), 0.05, 1e-4);
    EXPECT_LT(e.ceiling_height_sigma_m, 0.2 * o.ceiling_height_sigma_m);
    EXPECT_LT(e.rms_residual_px, 0.05);
}

TEST(Estimator, OneReferenceTakesTheScaleFromThePrior) {
    const CPose3D truth(0.25, 0.1, 0, 0.05, 0, 0);
    EstimatorOptions o;
    o.ceiling_height_sigma_m = 1.0;
    auto in = input(truth, {CPose3D()});
    const auto e = estimateQueryPose(in, o);
    ASSERT_TRUE(e.ok) << e.reason;
    // Offset and h trade off: h stays near the prior and its sigma near the prior's.
    EXPECT_NEAR(e.ceiling_height_m, 5.0, 0.05);
    EXPECT_GT(e.ceiling_height_sigma_m, 0.8 * o.ceiling_height_sigma_m);
    EXPECT_NEAR(e.vehicle_in_map.yaw(), 0.05, 1e-3);
    // With the right prior the pose is exact.
    in.ceiling_height_m = kTrueHeight;
    const auto exact = estimateQueryPose(in, o);
    ASSERT_TRUE(exact.ok);
    EXPECT_NEAR(exact.vehicle_in_map.x(), 0.25, 1e-3);
    EXPECT_NEAR(exact.vehicle_in_map.y(), 0.1, 1e-3);
    // Covariance is a usable 3x3 (x, y, yaw) Gaussian.
    const auto& C = exact.pose.cov;
    EXPECT_GT(C(0, 0), 0);
    EXPECT_GT(C(1, 1), 0);
    EXPECT_GT(C(2, 2), 0);
    EXPECT_GT(C.det(), 0);
}

TEST(Estimator, TooFewCorrespondencesIsAReasonNotACrash) {
    auto in = input(CPose3D(0.1, 0, 0, 0, 0, 0), {CPose3D()});
    in.views[0].reference_px.resize(3);
    in.views[0].query_px.resize(3);
    const auto e = estimateQueryPose(in, EstimatorOptions());
    EXPECT_FALSE(e.ok);
    EXPECT_NE(e.reason.find("only 3"), std::string::npos) << e.reason;
    EstimatorInput empty;
    EXPECT_FALSE(estimateQueryPose(empty, EstimatorOptions()).ok);
}

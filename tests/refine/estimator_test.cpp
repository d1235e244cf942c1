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

namespace {

// 40 km/h on a gentle bend, a 30 ms readout stamped at the first row.
RowTiming rollingShutter() {
    RowTiming t;
    t.readout_s = 0.030;
    t.stamp_row = 0;
    t.rows = 240;
    t.velocity = {40 / 3.6, 0.0, 0.2};
    return t;
}

// Exact correspondences into a rolling-shutter query: each ceiling point is seen from the
// camera at its own row's time (a fixed point over the row it lands on).
ReferenceView rollingView(const CPose3D& ref_vehicle, const CPose3D& query_vehicle,
                          const CPose3D& on_vehicle, const RowTiming& timing) {
    ReferenceView v;
    v.camera = camera();
    v.camera_in_map = ref_vehicle + on_vehicle;
    const CPose3D query_cam = query_vehicle + on_vehicle;
    for (int y = 20; y < 240; y += 40) {
        for (int x = 20; x < 320; x += 40) {
            const auto p = backProjectToCeiling(v.camera, v.camera_in_map, {double(x), double(y)},
                                                kTrueHeight);
            auto q = projectToImage(camera(), query_cam, *p);
            for (int k = 0; k < 20 && q; ++k) {
                q = projectToImage(camera(), timing.cameraAtRow(query_cam, on_vehicle, q->y), *p);
            }
            if (!q || q->x < 0 || q->y < 0 || q->x > 319 || q->y > 239) continue;
            v.reference_px.emplace_back(x, y);
            v.query_px.push_back(*q);
        }
    }
    return v;
}

struct RollingOutcome {
    double with_model_m, without_model_m;  ///< position error
    double with_rms_px, without_rms_px;
    std::optional<RowTravel> with_travel, without_travel;  ///< what the rows show
};

// The estimate with the per-row model against the stamp's pose, and without it (today's
// central-row offset) against the middle row's pose, which is then the best it can give.
RollingOutcome estimateRolling(const CPose3D& on_vehicle) {
    const RowTiming timing = rollingShutter();
    const CPose3D truth(0.25, 0.1, 0, 0.05, 0, 0);
    EstimatorInput in;
    for (const auto& r : {CPose3D(), CPose3D(0.6, -0.1, 0, 0, 0, 0)}) {
        in.views.push_back(rollingView(r, truth, on_vehicle, timing));
    }
    in.query_camera = camera();
    in.query_camera_on_vehicle = on_vehicle;
    in.ceiling_height_m = 5.0;
    in.query_rows = timing.rows;
    EstimatorOptions o;
    o.ceiling_height_sigma_m = 1.0;
    const auto without = estimateQueryPose(in, o);
    in.query_timing = timing;
    const auto with = estimateQueryPose(in, o);
    EXPECT_TRUE(with.ok && without.ok) << with.reason << without.reason;
    const CPose3D middle = truth + CPose3D(timing.motionAtRow(119.5));
    const auto error = [](const PoseEstimate& e, const CPose3D& p) {
        return std::hypot(e.vehicle_in_map.x() - p.x(), e.vehicle_in_map.y() - p.y());
    };
    EXPECT_NEAR(with.ceiling_height_m, kTrueHeight, 0.005);
    return {error(with, truth),      error(without, middle), with.rms_residual_px,
            without.rms_residual_px, with.row_travel,        without.row_travel};
}

}  // namespace

TEST(Estimator, RollingShutterRowsAcrossTheDriveAreSeenFromTheirOwnPoses) {
    // Rows across the drive (camera x ahead): the readout shears the image by 27 px.
    const auto r = estimateRolling(synthetic::ceilingCameraOnVehicle());
    EXPECT_LT(r.with_model_m, 1e-3);
    EXPECT_LT(r.with_rms_px, 0.02);
    EXPECT_GT(r.without_model_m, 0.03);
    EXPECT_GT(r.without_rms_px, 0.5);
}

TEST(Estimator, RollingShutterRowsAlongTheDriveAreSeenFromTheirOwnPoses) {
    // Rows along the drive (camera turned 90 deg, as on mine-b's vehicle): the readout
    // stretches the image along the drive, which the ceiling height cannot absorb.
    const auto r = estimateRolling(CPose3D(0, 0, 1.5, M_PI / 2, 0, 0));
    EXPECT_LT(r.with_model_m, 1e-3);
    EXPECT_LT(r.with_rms_px, 0.02);
    EXPECT_GT(r.without_model_m, 0.03);
    EXPECT_GT(r.without_rms_px, 0.5);
}

TEST(Estimator, TheRowsShowTheTravelOfAReadoutTheModelDoesNotCarry) {
    // 40 km/h x 30 ms: 0.333 m from the first row to the last, along the drive or across it.
    for (const CPose3D& mount :
         {synthetic::ceilingCameraOnVehicle(), CPose3D(0, 0, 1.5, M_PI / 2, 0, 0)}) {
        const auto r = estimateRolling(mount);
        ASSERT_TRUE(r.without_travel && r.with_travel);
        EXPECT_NEAR(r.without_travel->travel_m, 40 / 3.6 * 0.030, 0.01);
        EXPECT_LT(r.without_travel->sigma_m, 0.02);
        EXPECT_NEAR(r.with_travel->travel_m, 0.0, 0.005);  // the model carries it
    }
    // A global shutter shows none.
    const CPose3D truth(0.25, 0.1, 0, 0.05, 0, 0);
    auto in = input(truth, {CPose3D(), CPose3D(0.6, -0.1, 0, 0, 0, 0)});
    in.query_rows = 240;
    const auto e = estimateQueryPose(in, EstimatorOptions());
    ASSERT_TRUE(e.ok && e.row_travel);
    EXPECT_NEAR(e.row_travel->travel_m, 0.0, 0.005);
}

TEST(Estimator, GlobalShutterOrStandstillChangesNothing) {
    const CPose3D truth(0.25, 0.1, 0, 0.05, 0, 0);
    const auto plain = estimateQueryPose(input(truth, {CPose3D(), CPose3D(0.6, -0.1, 0, 0, 0, 0)}),
                                         EstimatorOptions());
    for (RowTiming t : {RowTiming{}, rollingShutter()}) {
        if (t.readout_s > 0) t.velocity = {};  // standing still
        auto in = input(truth, {CPose3D(), CPose3D(0.6, -0.1, 0, 0, 0, 0)});
        in.query_timing = t;
        const auto e = estimateQueryPose(in, EstimatorOptions());
        ASSERT_TRUE(e.ok);
        EXPECT_EQ(e.vehicle_in_map.x(), plain.vehicle_in_map.x());  // bit for bit
        EXPECT_EQ(e.vehicle_in_map.y(), plain.vehicle_in_map.y());
        EXPECT_EQ(e.ceiling_height_m, plain.ceiling_height_m);
    }
}

TEST(Estimator, RollingShutterReferenceIsSeenFromTheSurveyVehiclesRowPoses) {
    // The survey camera reads its rows while the survey vehicle moves; the query is global.
    const RowTiming timing = rollingShutter();
    const CPose3D on_vehicle = synthetic::ceilingCameraOnVehicle();
    const CPose3D truth(0.25, 0.1, 0, 0.05, 0, 0), ref_vehicle(0.6, -0.1, 0, 0, 0, 0);
    // Reference pixels: where each ceiling point seen by the global query lands in the
    // rolling-shutter reference (the view's roles swapped).
    const ReferenceView swapped = rollingView(truth, ref_vehicle, on_vehicle, timing);
    EstimatorInput in;
    ReferenceView v;
    v.camera = camera();
    v.camera_in_map = ref_vehicle + on_vehicle;
    v.reference_px = swapped.query_px;
    v.query_px = swapped.reference_px;
    v.camera_on_vehicle = on_vehicle;
    in.views.push_back(v);
    in.query_camera = camera();
    in.query_camera_on_vehicle = on_vehicle;
    in.ceiling_height_m = kTrueHeight;
    const auto error = [&](const PoseEstimate& e) {
        return std::hypot(e.vehicle_in_map.x() - truth.x(), e.vehicle_in_map.y() - truth.y());
    };
    const auto without = estimateQueryPose(in, EstimatorOptions());
    in.views[0].timing = timing;
    const auto with = estimateQueryPose(in, EstimatorOptions());
    ASSERT_TRUE(with.ok && without.ok);
    EXPECT_LT(error(with), 1e-3);
    EXPECT_GT(error(without), 0.03);
}

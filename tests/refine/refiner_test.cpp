#include <gtest/gtest.h>
#include <mrpt/img/CImage.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>

#include "lookup/refine/refiner.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

using namespace lookup::refine;
using mrpt::poses::CPose3D;

namespace {

CoarseHint hintAt(const CPose3D& vehicle, std::vector<std::int64_t> reference_ids = {}) {
    CoarseHint hint;
    hint.reference_ids = std::move(reference_ids);
    hint.vehicle_pose = vehicle;
    return hint;
}

struct Scene {
    synthetic::SyntheticCeiling ceiling = synthetic::SyntheticCeiling::make(5.3, 10.0, 0.01, 3);
    mrpt::img::TCamera camera = synthetic::makeCamera(320, 240, 250);
    CPose3D on_vehicle = synthetic::ceilingCameraOnVehicle();

    ReferenceImage reference(std::int64_t id, const CPose3D& vehicle) const {
        return ceiling.reference(id, camera, on_vehicle, vehicle);
    }
    cv::Mat query(const CPose3D& vehicle) const {
        return ceiling.render(camera, vehicle + on_vehicle);
    }
};

const Scene& scene() {
    static const Scene s;
    return s;
}

RefinerOptions optionsWithHeight(double h) {
    RefinerOptions o;
    o.estimator.ceiling_height_m = h;
    return o;
}

double distanceXY(const mrpt::poses::CPosePDFGaussian& p, const CPose3D& truth) {
    return std::hypot(p.mean.x() - truth.x(), p.mean.y() - truth.y());
}

}  // namespace

TEST(Refiner, OneReferenceWithTheRightPriorGivesMillimetres) {
    const Scene& s = scene();
    const CPose3D truth(0.18, -0.12, 0, 0.04, 0, 0);
    const Refiner refiner(optionsWithHeight(5.3));
    const auto r = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hintAt(CPose3D(), {7}),
                                  {s.reference(7, CPose3D())});
    ASSERT_TRUE(r.accepted()) << r.reason;
    EXPECT_EQ(r.source, PoseSource::Refined);
    EXPECT_LT(distanceXY(r.pose, truth), 0.005);
    EXPECT_NEAR(r.pose.mean.phi(), 0.04, 0.002);
    EXPECT_GT(r.inlier_share, 0.9);
    ASSERT_EQ(r.references.size(), 1u);
    EXPECT_EQ(r.references[0].matches.size(), 24u);
    EXPECT_GT(r.pose.cov(0, 0), 0.0);
    EXPECT_LT(std::sqrt(r.pose.cov(0, 0)), 0.05);  // confident, and rightly so
    EXPECT_GT(r.times.match_ms, 0.0);
}

TEST(Refiner, TwoReferencesRecoverTheCeilingHeightWithinOnePercent) {
    const Scene& s = scene();
    const CPose3D truth(0.25, 0.1, 0, 0.03, 0, 0);
    RefinerOptions o = optionsWithHeight(5.0);  // prior 6 % low
    o.estimator.ceiling_height_sigma_m = 1.0;
    const Refiner refiner(o);
    CoarseHint hint;
    hint.vehicle_pose = CPose3D(0.2, 0.05, 0, 0, 0, 0);
    const auto r = refiner.refine(
        s.query(truth), s.camera, s.on_vehicle, hint,
        {s.reference(1, CPose3D()), s.reference(2, CPose3D(0.5, 0.0, 0, 0.02, 0, 0))});
    ASSERT_TRUE(r.accepted()) << r.reason;
    EXPECT_NEAR(r.estimate.ceiling_height_m, 5.3, 0.053);
    EXPECT_LT(distanceXY(r.pose, truth), 0.01);
    EXPECT_EQ(r.references.size(), 2u);
}

TEST(Refiner, QueryHeightAndTiltComeFromTheReferencesNotThePlanarHint) {
    // Surveyed references on a bump of the floor, 0.12 m up and tilted by 0.5 deg, as is the
    // query beside them; the coarse hint is planar (z = 0, level), as a coarse stage gives it.
    // Taken from the hint, the query's view of the ceiling was scaled by 0.12 / 2.9 and its
    // tilt prior off by 0.5 deg: centimetres of error.
    const Scene& s = scene();
    const double z = 0.12, pitch = mrpt::DEG2RAD(0.5), roll = mrpt::DEG2RAD(-0.4);
    const CPose3D truth(0.35, 0.2, z, 0.03, pitch, roll);
    CoarseHint hint;
    hint.vehicle_pose = CPose3D(0.3, 0.15, 0, 0.03, 0, 0);
    const Refiner refiner(optionsWithHeight(5.3));
    const auto r = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint,
                                  {s.reference(1, CPose3D(0, 0, z, 0, pitch, roll)),
                                   s.reference(2, CPose3D(0.6, 0.1, z, 0.02, pitch, roll))});
    ASSERT_TRUE(r.accepted()) << r.reason;
    EXPECT_LT(distanceXY(r.pose, truth), 0.004);
}

TEST(Refiner, ReferencesOnAGradeSeeTheirCeilingParallelToTheirFloor) {
    // The scene of the other tests moved as a whole 5 m down and onto an 8 deg grade: 3-D
    // surveyed references down a decline, the ceiling following the floor. The images are the
    // same; the query's pose must be the same pose, moved likewise. With the ceiling taken as
    // the horizontal plane z = h of the map the references' rays missed it by metres.
    const Scene& s = scene();
    const CPose3D grade(2.0, -1.0, -5.0, 0.3, mrpt::DEG2RAD(8.0), mrpt::DEG2RAD(0.5));
    const CPose3D truth(0.25, 0.1, 0, 0.03, 0, 0), hint_on_floor(0.2, 0.05, 0, 0, 0, 0);
    RefinerOptions o = optionsWithHeight(5.0);
    o.estimator.ceiling_height_sigma_m = 1.0;
    const Refiner refiner(o);
    const CPose3D planar_hint(mrpt::poses::CPose2D(grade + hint_on_floor));  // z 0, level
    std::vector<ReferenceImage> refs{s.reference(1, CPose3D()),
                                     s.reference(2, CPose3D(0.5, 0.0, 0, 0.02, 0, 0))};
    for (auto& ref : refs) ref.vehicle_in_map = grade + ref.vehicle_in_map;
    const auto r =
        refiner.refine(s.query(truth), s.camera, s.on_vehicle, hintAt(planar_hint), refs);
    ASSERT_TRUE(r.accepted()) << r.reason;
    const CPose3D expected = grade + truth;
    EXPECT_LT(distanceXY(r.pose, expected), 0.005);
    EXPECT_NEAR(mrpt::math::wrapToPi(r.pose.mean.phi() - expected.yaw()), 0.0, 0.002);
    EXPECT_NEAR(r.estimate.vehicle_in_map.z(), expected.z(), 0.01);
    EXPECT_NEAR(r.estimate.vehicle_in_map.pitch(), expected.pitch(), mrpt::DEG2RAD(0.3));
    EXPECT_NEAR(r.estimate.ceiling_height_m, 5.3, 0.053);  // above the floor, not the map's z = 0
}

TEST(FloorFrame, OnAGradeTheCeilingHomographyIsTheLevelOnes) {
    // Two cameras on vehicles 0.6 m apart on an 8 deg grade, 5 m down: in their floor's frame
    // the homography the ceiling induces is the one of the same vehicles on the level; a planar
    // pose (a coarse or tracked one: z 0, level) is put on that floor first.
    const Scene& s = scene();
    Pinhole cam;
    ASSERT_TRUE(pinholeFrom(s.camera, cam, nullptr));
    const CPose3D a(0, 0, 0, 0.1, 0, 0), b(0.6, 0.1, 0, 0.15, 0, 0);
    const CPose3D grade(2.0, -1.0, -5.0, 0.3, mrpt::DEG2RAD(8.0), mrpt::DEG2RAD(0.5));
    EXPECT_FALSE(floorFrame({a, b}).has_value());
    const auto floor = floorFrame({grade + a, grade + b});
    ASSERT_TRUE(floor.has_value());
    const auto level = ceilingHomography(cam, a + s.on_vehicle, cam, b + s.on_vehicle, 5.3);
    const auto local = [&](const CPose3D& p) { return inFloorFrame(p, *floor) + s.on_vehicle; };
    const auto graded = ceilingHomography(cam, local(grade + a), cam, local(grade + b), 5.3);
    const auto planar_b = CPose3D(mrpt::poses::CPose2D(grade + b));
    const auto planar = ceilingHomography(cam, local(grade + a), cam, local(planar_b), 5.3);
    for (const cv::Point2d p :
         {cv::Point2d(20, 20), cv::Point2d(160, 120), cv::Point2d(300, 220)}) {
        cv::Point2d q_level, q_graded, q_planar;
        ASSERT_TRUE(applyHomography(level, p, q_level));
        ASSERT_TRUE(applyHomography(graded, p, q_graded));
        ASSERT_TRUE(applyHomography(planar, p, q_planar));
        EXPECT_LT(cv::norm(q_graded - q_level), 0.01);
        EXPECT_LT(cv::norm(q_planar - q_level), 1.0);  // its heading turned onto the grade
    }
}

TEST(Refiner, AProbeThatPassesChangesNothingAndOneThatFailsStopsEarly) {
    const Scene& s = scene();
    const CPose3D truth(0.35, 0.2, 0, 0.03, 0, 0);
    // The presets' distinctiveness test: an unrelated texture's best SAD is rarely distinct.
    auto options = optionsWithHeight(5.3);
    options.matcher.min_distinctiveness = 0.2;
    const Refiner refiner(options);
    CoarseHint hint;
    hint.vehicle_pose = CPose3D(0.3, 0.15, 0, 0.03, 0, 0);
    const std::vector<ReferenceImage> refs{s.reference(1, CPose3D(0, 0, 0, 0, 0, 0))};
    const auto full = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint, refs);
    ASSERT_TRUE(full.accepted()) << full.reason;

    // The right place: the probe's points match, and the result is the full match's.
    CoarseHint probed = hint;
    probed.probe_points = 8;
    probed.probe_min_matched = 4;
    const auto same = refiner.refine(s.query(truth), s.camera, s.on_vehicle, probed, refs);
    ASSERT_TRUE(same.accepted()) << same.reason;
    EXPECT_EQ(same.inliers, full.inliers);
    EXPECT_EQ(same.sample_points, full.sample_points);
    EXPECT_DOUBLE_EQ(same.pose.mean.x(), full.pose.mean.x());
    EXPECT_DOUBLE_EQ(same.pose.mean.y(), full.pose.mean.y());
    EXPECT_DOUBLE_EQ(same.pose.mean.phi(), full.pose.mean.phi());

    // A wrong place (an unrelated ceiling): refused after the probe, with its reason.
    const cv::Mat unrelated = synthetic::makeNoiseTexture(cv::Size(320, 240), 77);
    const auto wrong = refiner.refine(unrelated, s.camera, s.on_vehicle, probed, refs);
    EXPECT_EQ(wrong.status, RefineStatus::TooFewMatches);
    EXPECT_NE(wrong.reason.find("probe: "), std::string::npos) << wrong.reason;
    EXPECT_NE(wrong.reason.find("of 8 probe points"), std::string::npos) << wrong.reason;
    EXPECT_TRUE(wrong.references.empty());  // the full match never ran
}

TEST(Refiner, OccludingObjectPointsAreOutliers) {
    const Scene& s = scene();
    const CPose3D truth(0.1, 0.05, 0, 0.0, 0, 0);
    cv::Mat query = s.query(truth);
    // A pipe-like object of another texture over the left third of the query.
    const cv::Mat other = synthetic::makeNoiseTexture(cv::Size(100, 240), 1234);
    other.copyTo(query(cv::Rect(0, 0, 100, 240)));
    const Refiner refiner(optionsWithHeight(5.3));
    auto o = refiner.options();
    const auto r = refiner.refine(query, s.camera, s.on_vehicle, hintAt(CPose3D()),
                                  {s.reference(1, CPose3D())});
    ASSERT_EQ(r.references.size(), 1u);
    int occluded = 0, occluded_inliers = 0;
    for (const auto& m : r.references[0].matches) {
        if (m.reference_px.x + 7 < 100 - o.matcher.patch_px / 2) {  // its match lies in the object
            ++occluded;
            occluded_inliers += m.inlier ? 1 : 0;
        }
    }
    EXPECT_GE(occluded, 4);
    EXPECT_EQ(occluded_inliers, 0);
    EXPECT_LT(distanceXY(r.estimate.pose, truth), 0.01) << r.reason;
}

TEST(Refiner, MismatchedImageFallsBackToTheCoarsePose) {
    const Scene& s = scene();
    const cv::Mat unrelated = synthetic::makeNoiseTexture(cv::Size(320, 240), 77);
    const CPose3D coarse(1.0, 2.0, 0, 0.1, 0, 0);
    const Refiner refiner;
    const auto r =
        refiner.refine(unrelated, s.camera, s.on_vehicle, hintAt(coarse), {s.reference(1, coarse)});
    EXPECT_FALSE(r.accepted());
    EXPECT_FALSE(r.reason.empty());
    EXPECT_EQ(r.source, PoseSource::Coarse);
    EXPECT_NEAR(r.pose.mean.x(), 1.0, 1e-12);
    EXPECT_NEAR(std::sqrt(r.pose.cov(0, 0)), refiner.options().acceptance.fallback_sigma_xy_m,
                1e-9);
}

TEST(Refiner, BadInputIsARejectionWithAReason) {
    const Scene& s = scene();
    const Refiner refiner;
    const CPose3D coarse(0.3, 0.0, 0, 0, 0, 0);
    const std::vector<ReferenceImage> refs = {s.reference(1, CPose3D())};
    const cv::Mat good = s.query(coarse);

    // Blank query.
    const cv::Mat blank(240, 320, CV_8UC1, cv::Scalar(90));
    auto r = refiner.refine(blank, s.camera, s.on_vehicle, hintAt(coarse), refs);
    EXPECT_EQ(r.status, RefineStatus::TooFewMatches) << r.reason;
    EXPECT_NE(r.reason.find("inliers 0 of 24"), std::string::npos) << r.reason;
    // The reason says why the points failed: on a flat query the SAD surface is flat and its
    // first minimum is the window's corner.
    EXPECT_NE(r.reason.find("(24 peak on the search-window border)"), std::string::npos)
        << r.reason;
    EXPECT_EQ(r.source, PoseSource::Coarse);

    // NaN in the query intrinsics.
    auto nan_camera = s.camera;
    nan_camera.fx(std::numeric_limits<double>::quiet_NaN());
    r = refiner.refine(good, nan_camera, s.on_vehicle, hintAt(coarse), refs);
    EXPECT_EQ(r.status, RefineStatus::InvalidQuery);
    EXPECT_NE(r.reason.find("fx=nan"), std::string::npos) << r.reason;

    // NaN in a reference's intrinsics: that reference is skipped, naming it.
    auto bad_ref = refs;
    bad_ref[0].camera.cy(std::numeric_limits<double>::quiet_NaN());
    r = refiner.refine(good, s.camera, s.on_vehicle, hintAt(coarse), bad_ref);
    EXPECT_EQ(r.status, RefineStatus::NoReferences);
    EXPECT_NE(r.reason.find("reference 1"), std::string::npos) << r.reason;

    // Empty reference set, with and without a coarse pose.
    r = refiner.refine(good, s.camera, s.on_vehicle, hintAt(coarse), {});
    EXPECT_EQ(r.status, RefineStatus::NoReferences);
    EXPECT_EQ(r.source, PoseSource::Coarse);
    r = refiner.refine(good, s.camera, s.on_vehicle, {}, {});
    EXPECT_EQ(r.status, RefineStatus::NoReferences);
    EXPECT_EQ(r.source, PoseSource::None);
    EXPECT_GT(r.pose.cov(0, 0), 1e6);  // no confident pose out of nothing

    // A heat map with a NaN.
    auto nan_heat = refs;
    nan_heat[0].heat_map = cv::Mat(good.size(), CV_32F, cv::Scalar(1.0f));
    nan_heat[0].heat_map.at<float>(5, 5) = std::numeric_limits<float>::quiet_NaN();
    r = refiner.refine(good, s.camera, s.on_vehicle, hintAt(coarse), nan_heat);
    EXPECT_EQ(r.status, RefineStatus::NoReferences);
    EXPECT_NE(r.reason.find("heat map"), std::string::npos) << r.reason;

    // Hint naming an id that is not in the set.
    r = refiner.refine(good, s.camera, s.on_vehicle, hintAt(coarse, {42}), refs);
    EXPECT_EQ(r.status, RefineStatus::NoReferences);

    // Reference too small for any sample point away from the border.
    auto tiny = refs;
    tiny[0].image = refs[0].image(cv::Rect(0, 0, 40, 40)).clone();
    r = refiner.refine(good, s.camera, s.on_vehicle, hintAt(coarse), tiny);
    EXPECT_EQ(r.status, RefineStatus::TooFewMatches) << r.reason;

    // Empty query image.
    r = refiner.refine(cv::Mat(), s.camera, s.on_vehicle, hintAt(coarse), refs);
    EXPECT_EQ(r.status, RefineStatus::InvalidQuery);
}

TEST(Refiner, OffsetBeyondDthIsRejected) {
    const Scene& s = scene();
    RefinerOptions o = optionsWithHeight(5.3);
    o.acceptance.max_offset_m = 0.1;
    const CPose3D truth(0.2, 0.1, 0, 0, 0, 0);
    const auto r =
        Refiner(o).refine(s.query(truth), s.camera, s.on_vehicle, {}, {s.reference(1, CPose3D())});
    EXPECT_EQ(r.status, RefineStatus::OffsetTooLarge) << r.reason;
    EXPECT_NEAR(r.offset_m, std::hypot(0.2, 0.1), 0.01);
    EXPECT_EQ(r.source, PoseSource::Reference);
    EXPECT_TRUE(r.estimate.ok);  // the estimate itself is still reported
}

TEST(Refiner, ObservationEntryPointMatchesTheMatEntryPoint) {
    const Scene& s = scene();
    const CPose3D truth(-0.1, 0.15, 0, -0.03, 0, 0);
    mrpt::obs::CObservationImage obs;
    obs.sensorLabel = "CEILING_CAM";
    obs.image = mrpt::img::CImage(s.query(truth), mrpt::img::DEEP_COPY);
    obs.cameraParams = s.camera;
    obs.cameraPose = s.on_vehicle;
    const Refiner refiner(optionsWithHeight(5.3));
    const std::vector<ReferenceImage> refs = {s.reference(1, CPose3D())};
    const CoarseHint hint = hintAt(CPose3D());
    const auto a = refiner.refine(obs, hint, refs);
    const auto b = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint, refs);
    ASSERT_TRUE(a.accepted()) << a.reason;
    EXPECT_EQ(a.pose.mean, b.pose.mean);
    EXPECT_LT(distanceXY(a.pose, truth), 0.005);
}

TEST(Refiner, HeatMapSamplingUsesTheBestRegionsAndIsDeterministic) {
    const Scene& s = scene();
    const CPose3D truth(0.12, 0.08, 0, 0.02, 0, 0);
    ReferenceImage ref = s.reference(1, CPose3D());
    // Heat map of sharp blobs (as an FCN gives) in the right half, one weak blob on the left:
    // every chosen point must lie on the right.
    ref.heat_map = cv::Mat(ref.image.size(), CV_32F, cv::Scalar(0.0f));
    cv::RNG rng(3);
    for (int i = 0; i < 16; ++i) {
        ref.heat_map.at<float>(rng.uniform(40, 200), rng.uniform(180, 290)) =
            float(rng.uniform(0.5, 1.0));
    }
    ref.heat_map.at<float>(120, 60) = 0.05f;
    cv::GaussianBlur(ref.heat_map, ref.heat_map, cv::Size(0, 0), 3);
    ref.prepare(MatcherOptions{});
    const Refiner refiner(optionsWithHeight(5.3));
    const CoarseHint hint = hintAt(CPose3D());
    const auto a = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint, {ref});
    ASSERT_TRUE(a.accepted()) << a.reason;
    ASSERT_EQ(a.references[0].matches.size(), 12u);  // heat_map_points
    for (const auto& m : a.references[0].matches) EXPECT_GE(m.reference_px.x, 170.f);
    EXPECT_LT(distanceXY(a.pose, truth), 0.01);  // 12 points on one side: less leverage
    const auto b = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint, {ref});
    EXPECT_EQ(a.pose.mean, b.pose.mean);
    EXPECT_EQ(a.pose.cov, b.pose.cov);

    // Points cached on the reference (the localiser's reference views) give the same result...
    ref.prepareSamplePoints(refiner.options().sampler);
    const auto c = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint, {ref});
    EXPECT_EQ(a.pose.mean, c.pose.mean);
    // ...and a cache built with other sampler options is not used.
    SamplerOptions other = refiner.options().sampler;
    other.heat_map_points = 5;
    ref.prepareSamplePoints(other);
    const auto d = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint, {ref});
    EXPECT_EQ(d.references[0].matches.size(), 12u);
    EXPECT_EQ(a.pose.mean, d.pose.mean);
    // With the same options the cached points are the ones matched.
    SamplerOptions five = other;
    RefinerOptions five_points = optionsWithHeight(5.3);
    five_points.sampler = five;
    const auto e = Refiner(five_points).refine(s.query(truth), s.camera, s.on_vehicle, hint, {ref});
    ASSERT_EQ(e.references[0].matches.size(), 5u);
    EXPECT_EQ(e.references[0].matches[0].reference_px, ref.sample_points->points[0]);

    // A heat map with a NaN gets no cached points, and the Refiner refuses it, saying why.
    ReferenceImage broken = ref;
    broken.heat_map = ref.heat_map.clone();
    broken.heat_map.at<float>(10, 10) = std::numeric_limits<float>::quiet_NaN();
    broken.prepareSamplePoints(refiner.options().sampler);
    EXPECT_FALSE(broken.sample_points);
    const auto f = refiner.refine(s.query(truth), s.camera, s.on_vehicle, hint, {broken});
    EXPECT_EQ(f.status, RefineStatus::NoReferences);
    EXPECT_NE(f.reason.find("heat map"), std::string::npos) << f.reason;
}

TEST(ReferenceImage, FromObservationConvertsToGreyAndKeepsPoses) {
    const Scene& s = scene();
    const cv::Mat grey = s.query(CPose3D());
    cv::Mat bgr;
    cv::cvtColor(grey, bgr, cv::COLOR_GRAY2BGR);
    mrpt::obs::CObservationImage obs;
    obs.sensorLabel = "CEILING_CAM";
    obs.image = mrpt::img::CImage(bgr, mrpt::img::DEEP_COPY);
    obs.cameraParams = s.camera;
    obs.cameraPose = s.on_vehicle;
    const CPose3D vehicle(1, 2, 0, 0.3, 0, 0);
    const ReferenceImage r = ReferenceImage::fromObservation(9, obs, vehicle);
    EXPECT_EQ(r.id, 9);
    ASSERT_EQ(r.image.type(), CV_8UC1);
    EXPECT_EQ(cv::norm(r.image, grey, cv::NORM_INF), 0.0);
    EXPECT_EQ(r.vehicle_in_map, vehicle);
    EXPECT_EQ(r.cameraInMap(), vehicle + s.on_vehicle);
    EXPECT_DOUBLE_EQ(r.camera.fx(), s.camera.fx());

    mrpt::obs::CObservationImage empty;
    empty.sensorLabel = "CEILING_CAM";
    EXPECT_THROW(ReferenceImage::fromObservation(3, empty, vehicle), std::runtime_error);
}

TEST(Refiner, GlobalBrightnessChangeIsNormalisedAway) {
    const Scene& s = scene();
    const CPose3D truth(0.15, -0.05, 0, 0.02, 0, 0);
    cv::Mat darker;
    s.query(truth).convertTo(darker, CV_8U, 0.55, 20.0);  // exposure / lighting change
    const std::vector<ReferenceImage> refs = {s.reference(1, CPose3D())};
    const CoarseHint hint = hintAt(CPose3D());
    RefinerOptions o = optionsWithHeight(5.3);
    const auto r = Refiner(o).refine(darker, s.camera, s.on_vehicle, hint, refs);
    ASSERT_TRUE(r.accepted()) << r.reason;
    EXPECT_LT(distanceXY(r.pose, truth), 0.005);
    // Without normalisation the SAD peaks are weaker: quality drops on the same pair.
    o.matcher.normalize_brightness = false;
    const auto raw = Refiner(o).refine(darker, s.camera, s.on_vehicle, hint, refs);
    double q_norm = 0, q_raw = 0;
    for (const auto& m : r.references[0].matches) q_norm += m.quality;
    for (const auto& m : raw.references[0].matches) q_raw += m.quality;
    EXPECT_GT(q_norm, q_raw);
}

TEST(Refiner, RollingShutterQueryIsRefinedRowByRowWithTheVehiclesVelocity) {
    // 40 km/h with a 30 ms readout stamped at the first row: the vehicle moves 0.33 m while the
    // rows are read (27 px of shear). The per-row model recovers the stamp's pose; without it
    // the best is the middle row's, and the shear costs centimetres.
    const Scene& s = scene();
    RowTiming timing;
    timing.readout_s = 0.030;
    timing.velocity = {40 / 3.6, 0.0, 0.3};
    const CPose3D truth(0.25, 0.1, 0, 0.03, 0, 0);
    const cv::Mat image = s.ceiling.renderRollingShutter(s.camera, s.on_vehicle, truth, timing);
    const std::vector<ReferenceImage> refs = {s.reference(1, CPose3D()),
                                              s.reference(2, CPose3D(0.5, 0.0, 0, 0.02, 0, 0))};
    CoarseHint hint;
    hint.vehicle_pose = CPose3D(0.3, 0.05, 0, 0, 0, 0);
    hint.vehicle_motion = timing.velocity;

    RefinerOptions o = optionsWithHeight(5.3);
    const auto without = Refiner(o).refine(image, s.camera, s.on_vehicle, hint, refs);
    o.rolling_shutter.readout_ms = 30;
    const auto with = Refiner(o).refine(image, s.camera, s.on_vehicle, hint, refs);
    ASSERT_TRUE(with.accepted()) << with.reason;
    ASSERT_TRUE(without.accepted()) << without.reason;
    timing.rows = 240;
    const CPose3D middle = truth + CPose3D(timing.motionAtRow(119.5));
    EXPECT_LT(distanceXY(with.pose, truth), 0.005);
    EXPECT_GT(distanceXY(without.pose, middle), 0.05);
    EXPECT_LT(with.estimate.rms_residual_px, 0.5);
    EXPECT_GT(without.estimate.rms_residual_px, 2.0);
}

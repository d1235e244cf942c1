// The real camera's effects are really in the images: lens distortion where OpenCV's model of
// the recorded calibration puts a point, rolling-shutter skew by speed x readout, the response
// curve, bloom, lens dirt and drops, dust haze.

#include "test_worlds.h"

#include <gtest/gtest.h>
#include <lookup/common/config.h>
#include <lookup/sim/camera_renderer.h>
#include <lookup/sim/simulator.h>
#include <lookup/sim/world.h>
#include <opencv2/calib3d.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>
#include <vector>

namespace {

using lookup::sim::CameraOptions;
using lookup::sim::CameraRenderer;
using lookup::sim::FrameConditions;
using lookup::sim::ScenarioOptions;
using lookup::sim::TunnelWorld;
using lookup::sim::testing::straightTunnel;

CameraOptions noiselessCeilingCamera() {
    CameraOptions cam = ScenarioOptions().ceiling_camera;
    cam.noise_std_dn = 0;
    return cam;
}

cv::Mat toMat(const mrpt::img::CImage& img) {
    cv::Mat m;
    img.asCvMat(m, mrpt::img::DEEP_COPY);
    return m;
}

cv::Point2d brightCentroid(const cv::Mat& img) {
    const cv::Moments m = cv::moments(img >= 250, true);
    if (m.m00 == 0) return {-1, -1};
    return {m.m10 / m.m00, m.m01 / m.m00};
}

/// The marker at `world_xy` on a 5 m ceiling, seen from `camera`: measured centroid and the
/// projection OpenCV computes from the renderer's recorded intrinsics and distortion.
void measureAndPredict(const CameraOptions& cam, const mrpt::poses::CPose3D& camera,
                       const cv::Point2d& world_xy, cv::Point2d* measured, cv::Point2d* predicted,
                       cv::Point2d* pinhole) {
    TunnelWorld world(straightTunnel(true), 1);
    world.addMarker({world_xy.x, world_xy.y, 0.04, 10.0});
    const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 2);
    *measured = brightCentroid(toMat(r.render(camera, FrameConditions{})));
    const mrpt::math::TPoint3D pc = camera.inverseComposePoint(
        mrpt::math::TPoint3D(world_xy.x, world_xy.y, world.options().ceiling_height_m));
    const auto& K = r.intrinsics();
    const cv::Matx33d Km(K.fx(), 0, K.cx(), 0, K.fy(), K.cy(), 0, 0, 1);
    const std::vector<cv::Point3d> obj{{pc.x, pc.y, pc.z}};
    std::vector<cv::Point2d> img;
    if (K.distortion == mrpt::img::DistortionModel::kannala_brandt) {
        const cv::Vec4d D(K.k1(), K.k2(), K.k3(), K.k4());
        cv::fisheye::projectPoints(obj, img, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), Km, D);
    } else {
        const std::vector<double> D{K.k1(), K.k2(), K.p1(), K.p2(), K.k3()};
        cv::projectPoints(obj, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), Km, D, img);
    }
    *predicted = img[0];
    *pinhole = {K.cx() + K.fx() * pc.x / pc.z, K.cy() + K.fy() * pc.y / pc.z};
}

TEST(CameraEffects, RadialTangentialDistortionIsRenderedAndRecorded) {
    CameraOptions cam = noiselessCeilingCamera();
    cam.distortion = "plumb_bob";
    cam.dist_k1 = -0.25;
    cam.dist_k2 = 0.05;
    cam.dist_p1 = 0.002;
    cam.dist_p2 = -0.001;
    const mrpt::poses::CPose3D vehicle(12.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    const mrpt::poses::CPose3D camera = vehicle + cam.mount.pose();
    const TunnelWorld world(straightTunnel(true), 1);
    const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 1);
    EXPECT_EQ(r.intrinsics().distortion, mrpt::img::DistortionModel::plumb_bob);
    EXPECT_DOUBLE_EQ(r.intrinsics().k1(), -0.25);
    EXPECT_DOUBLE_EQ(r.intrinsics().p2(), -0.001);
    for (const auto& offset :
         {cv::Point2d(0.2, 0.1), cv::Point2d(1.5, 1.2), cv::Point2d(-1.4, -1.1)}) {
        SCOPED_TRACE(offset);
        cv::Point2d m, p, pin;
        measureAndPredict(cam, camera, {camera.x() + offset.x, camera.y() + offset.y}, &m, &p,
                          &pin);
        ASSERT_GE(m.x, 0) << "marker not seen";
        EXPECT_NEAR(m.x, p.x, 0.6);
        EXPECT_NEAR(m.y, p.y, 0.6);
        // Far off-axis the barrel distortion pulls the point inwards by many pixels.
        if (std::abs(offset.x) > 1) EXPECT_GT(cv::norm(p - pin), 10.0);
    }
}

TEST(CameraEffects, FisheyeDistortionIsRenderedAndRecorded) {
    CameraOptions cam = noiselessCeilingCamera();
    cam.distortion = "kannala_brandt";
    cam.hfov_deg = 150;
    cam.dist_k1 = 0.04;
    cam.dist_k2 = -0.01;
    cam.dist_k3 = 0.002;
    cam.dist_k4 = 0.0;
    const mrpt::poses::CPose3D camera =
        mrpt::poses::CPose3D(12.0, 0.0, 0.0, 0, 0, 0) + cam.mount.pose();
    const TunnelWorld world(straightTunnel(true), 1);
    const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 1);
    EXPECT_EQ(r.intrinsics().distortion, mrpt::img::DistortionModel::kannala_brandt);
    EXPECT_DOUBLE_EQ(r.intrinsics().k3(), 0.002);
    for (const auto& offset : {cv::Point2d(0.3, -0.2), cv::Point2d(2.6, 1.1)}) {
        SCOPED_TRACE(offset);
        cv::Point2d m, p, pin;
        measureAndPredict(cam, camera, {camera.x() + offset.x, camera.y() + offset.y}, &m, &p,
                          &pin);
        ASSERT_GE(m.x, 0) << "marker not seen";
        EXPECT_NEAR(m.x, p.x, 0.6);
        EXPECT_NEAR(m.y, p.y, 0.6);
    }
}

TEST(CameraEffects, DistortionThatFoldsInsideTheImageIsRefused) {
    CameraOptions cam = noiselessCeilingCamera();
    cam.distortion = "plumb_bob";
    cam.dist_k1 = -1.5;  // r (1 + k1 r^2) turns back inside the 95 deg view
    const TunnelWorld world(straightTunnel(true), 1);
    EXPECT_THROW(CameraRenderer renderer(world, cam, CameraRenderer::Kind::Ceiling, 1),
                 lookup::common::ConfigError);
    ScenarioOptions sc;
    sc.traverses.resize(1);
    sc.traverses[0].name = "t";
    sc.traverses[0].roles = "reference";
    sc.world.length_m = 20;
    sc.traverses[0].ceiling_camera = cam;
    try {
        lookup::sim::Simulator sim(sc);
        ADD_FAILURE() << "accepted";
    } catch (const lookup::common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("[traverse_0.ceiling_camera] distortion"),
                  std::string::npos)
            << e.what();
    }
}

TEST(CameraEffects, RollingShutterSkewsALineBySpeedTimesReadout) {
    // The vehicle moves sideways at 10 m/s (the camera looks up, image up = vehicle forward,
    // image right = vehicle left) while the 30 ms readout runs down the rows: two marks on one
    // line along the vehicle appear shifted against each other by f * v * dt(rows) / range.
    CameraOptions cam = noiselessCeilingCamera();
    cam.readout_ms = 30;
    const mrpt::poses::CPose3D vehicle(12.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    const double speed = 10, readout = 0.030;
    std::vector<mrpt::poses::CPose3D> rows;
    for (int v = 0; v < cam.height_px; ++v) {
        const double dy = speed * readout * v / (cam.height_px - 1);
        rows.push_back(mrpt::poses::CPose3D(12.0, dy, 0, 0, 0, 0) + cam.mount.pose());
    }
    const mrpt::poses::CPose3D camera0 = vehicle + cam.mount.pose();
    const double range = 5.0 - camera0.z();
    std::vector<cv::Point2d> seen;
    std::vector<double> predicted_u;
    for (const double ahead : {1.2, -1.2}) {
        TunnelWorld world(straightTunnel(true), 1);
        world.addMarker({camera0.x() + ahead, 0.3, 0.04, 10.0});
        const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 2);
        const cv::Point2d m = brightCentroid(toMat(r.render(rows, FrameConditions{})));
        ASSERT_GE(m.x, 0);
        seen.push_back(m);
        // Camera at the marker's row: y shifted by speed * readout * row / (rows - 1).
        const double dy = speed * readout * m.y / (cam.height_px - 1);
        // Image right = vehicle left (+y): a point at y = 0.3 seen from y = dy.
        predicted_u.push_back(r.intrinsics().cx() + r.intrinsics().fx() * (0.3 - dy) / range);
    }
    const double skew = seen[1].x - seen[0].x, predicted = predicted_u[1] - predicted_u[0];
    EXPECT_GT(std::abs(predicted), 8.0);  // a skew far above the measuring error
    EXPECT_NEAR(skew, predicted, 0.6) << "rows " << seen[0].y << ", " << seen[1].y;
}

/// A plain (untextured but shaded) ceiling view, noiseless.
cv::Mat plainView(const CameraOptions& cam, const TunnelWorld& world, double x = 12.0) {
    const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 2);
    return toMat(
        r.render(mrpt::poses::CPose3D(x, 0.2, 0, 0.1, 0, 0) + cam.mount.pose(), FrameConditions{}));
}

TEST(CameraEffects, ResponseCurveMapsLevelsAsSpecified) {
    const TunnelWorld world(straightTunnel(false), 1);
    CameraOptions cam = noiselessCeilingCamera();
    cam.exposure_ms = 0;
    const cv::Mat linear = plainView(cam, world);
    cam.response_gamma = 2.2;
    const cv::Mat gamma = plainView(cam, world);
    cam.response_gamma = 1;
    cam.response_knee_dn = 100;
    cam.response_knee_slope = 0.25;
    const cv::Mat knee = plainView(cam, world);
    int checked = 0;
    for (int i = 0; i < static_cast<int>(linear.total()); ++i) {
        const double x = linear.data[i];
        if (x < 30 || x > 250) continue;
        ++checked;
        ASSERT_NEAR(gamma.data[i], 255 * std::pow(x / 255, 1 / 2.2), 1.6) << "level " << x;
        ASSERT_NEAR(knee.data[i], x > 100 ? 100 + (x - 100) * 0.25 : x, 1.0) << "level " << x;
    }
    EXPECT_GT(checked, 1000);
    EXPECT_GT(cv::mean(gamma)[0], cv::mean(linear)[0] + 20);
}

TEST(CameraEffects, BloomSpreadsSaturatedLampsIntoTheirNeighbourhood) {
    auto opt = straightTunnel(true);
    opt.light_spacing_m = 6;
    const TunnelWorld world(opt, 1);
    CameraOptions cam = ScenarioOptions().forward_camera;
    cam.noise_std_dn = 0;
    const mrpt::poses::CPose3D camera =
        mrpt::poses::CPose3D(8.0, 0.0, 0.0, 0, 0, 0) + cam.mount.pose();
    const cv::Mat plain =
        toMat(CameraRenderer(world, cam, CameraRenderer::Kind::Forward, 1).render(camera, {}));
    cam.bloom_strength = 0.3;
    cam.bloom_radius_px = 4;
    const cv::Mat bloom =
        toMat(CameraRenderer(world, cam, CameraRenderer::Kind::Forward, 1).render(camera, {}));
    // Ring of pixels 2-8 px from the saturated lamp pixels: brighter; far from them: unchanged.
    cv::Mat lamp = plain >= 254, near, far;
    ASSERT_GT(cv::countNonZero(lamp), 3);
    cv::dilate(lamp, near, cv::Mat(), cv::Point(-1, -1), 8);
    cv::dilate(lamp, far, cv::Mat(), cv::Point(-1, -1), 25);
    cv::Mat ring;
    cv::dilate(lamp, ring, cv::Mat(), cv::Point(-1, -1), 2);
    ring = near & ~ring;
    cv::Mat diff;
    cv::subtract(bloom, plain, diff, cv::noArray(), CV_32F);
    EXPECT_GT(cv::mean(diff, ring)[0], 3.0);
    EXPECT_LT(cv::mean(cv::abs(diff), ~far)[0], 0.5);
}

TEST(CameraEffects, LensDirtIsFixedToTheLensAndDropsDefocus) {
    const TunnelWorld world(straightTunnel(false), 1);
    CameraOptions cam = noiselessCeilingCamera();
    cam.exposure_ms = 0;
    CameraOptions dirty = cam;
    dirty.dirt_spots = 6;
    dirty.dirt_opacity = 0.6;
    cv::Mat ratio[2], valid(cam.height_px, cam.width_px, CV_8U, cv::Scalar(255));
    for (int k = 0; k < 2; ++k) {
        const double x = 10.0 + 3.0 * k;  // another part of the ceiling
        cv::Mat clean, d;
        plainView(cam, world, x).convertTo(clean, CV_32F);
        plainView(dirty, world, x).convertTo(d, CV_32F);
        ratio[k] = d / cv::max(clean, 1.0);
        valid &= clean > 40;
    }
    // The transmission map (dirty / clean) is the same wherever the camera looks.
    ASSERT_GT(cv::countNonZero((ratio[0] < 0.85) & valid), 200) << "no visible dirt";
    cv::Scalar m0, s0, m1, s1;
    cv::meanStdDev(ratio[0], m0, s0, valid);
    cv::meanStdDev(ratio[1], m1, s1, valid);
    const cv::Mat centred0 = ratio[0] - m0[0], centred1 = ratio[1] - m1[0];
    const double corr = cv::mean(centred0.mul(centred1), valid)[0] / (s0[0] * s1[0]);
    EXPECT_GT(corr, 0.9) << "dirt moved with the scene";

    CameraOptions wet = cam;
    wet.water_drops = 8;
    wet.drop_radius_px = 14;
    const cv::Mat dry = plainView(cam, world), drops = plainView(wet, world);
    // Inside the drops (where the images differ, rims left out) the detail is blurred away.
    cv::Mat inside;
    cv::absdiff(drops, dry, inside);
    inside = inside > 0;
    cv::erode(inside, inside, cv::Mat(), cv::Point(-1, -1), 3);
    ASSERT_GT(cv::countNonZero(inside), 100) << "no drops";
    auto sharpness = [&inside](const cv::Mat& img) {
        cv::Mat lap;
        cv::Laplacian(img, lap, CV_32F);
        return cv::mean(cv::abs(lap), inside)[0];
    };
    EXPECT_LT(sharpness(drops), 0.6 * sharpness(dry));
}

TEST(CameraEffects, DustHazeVeilsTheForwardView) {
    const TunnelWorld world(straightTunnel(false), 1);
    CameraOptions cam = ScenarioOptions().forward_camera;
    cam.noise_std_dn = 0;
    const mrpt::poses::CPose3D camera =
        mrpt::poses::CPose3D(5.0, 0.0, 0.0, 0, 0, 0) + cam.mount.pose();
    auto view = [&](double beta) {
        CameraOptions c = cam;
        c.haze_extinction_per_m = beta;
        return toMat(CameraRenderer(world, c, CameraRenderer::Kind::Forward, 1).render(camera, {}));
    };
    cv::Scalar m0, s0, m1, s1;
    cv::meanStdDev(view(0), m0, s0);
    cv::meanStdDev(view(0.3), m1, s1);
    EXPECT_LT(s1[0], 0.7 * s0[0]) << "haze must lower the contrast";
}

}  // namespace

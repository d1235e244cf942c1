// The ceiling camera's rendering agrees with its own camera model (intrinsics + cameraPose).

#include "test_worlds.h"

#include <gtest/gtest.h>
#include <lookup/sim/camera_renderer.h>
#include <lookup/sim/world.h>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <cmath>

namespace {

using lookup::sim::CameraRenderer;
using lookup::sim::FrameConditions;
using lookup::sim::ScenarioOptions;
using lookup::sim::TunnelWorld;
using lookup::sim::testing::straightTunnel;

lookup::sim::CameraOptions noiselessCeilingCamera() {
    lookup::sim::CameraOptions cam = ScenarioOptions().ceiling_camera;
    cam.noise_std_dn = 0;
    return cam;
}

cv::Mat toMat(const mrpt::img::CImage& img) {
    cv::Mat m;
    img.asCvMat(m, mrpt::img::DEEP_COPY);
    return m;
}

/// Centroid of the saturated pixels, or (-1, -1) if there are none.
cv::Point2d brightCentroid(const cv::Mat& img, int* count) {
    cv::Mat mask = img >= 250;
    const cv::Moments m = cv::moments(mask, true);
    *count = static_cast<int>(m.m00);
    if (m.m00 == 0) return {-1, -1};
    return {m.m10 / m.m00, m.m01 / m.m00};
}

TEST(CeilingCamera, IntrinsicsFollowTheFieldOfView) {
    const TunnelWorld world(straightTunnel(true), 1);
    const auto cam = noiselessCeilingCamera();
    const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 1);
    const double f = (cam.width_px / 2.0) / std::tan(cam.hfov_deg * M_PI / 360);
    EXPECT_NEAR(r.intrinsics().fx(), f, 1e-9);
    EXPECT_NEAR(r.intrinsics().fy(), f, 1e-9);
    EXPECT_NEAR(r.intrinsics().cx(), (cam.width_px - 1) / 2.0, 1e-9);
    EXPECT_EQ(r.intrinsics().ncols, static_cast<uint32_t>(cam.width_px));
}

TEST(CeilingCamera, CeilingPointProjectsWhereTheCameraModelSays) {
    const auto opt = straightTunnel(true);
    const auto cam = noiselessCeilingCamera();
    const mrpt::poses::CPose3D vehicle(12.0, 0.4, 0.0, 0.35, 0.01, -0.02);
    const mrpt::poses::CPose3D camera = vehicle + cam.mount.pose();
    // Near the principal point, and out towards a corner of the wide-angle view.
    for (const auto& offset :
         {cv::Point2d(0.3, 0.2), cv::Point2d(1.1, -0.7), cv::Point2d(-0.9, 0.5)}) {
        TunnelWorld world(opt, 1);
        const double x = camera.x() + offset.x, y = camera.y() + offset.y;
        world.addMarker({x, y, 0.05, 10.0});
        const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 2);
        const cv::Mat img = toMat(r.render(camera, FrameConditions{}));
        // MRPT pinhole model: point in the camera frame, then u = cx + fx X/Z, v = cy + fy Y/Z.
        const mrpt::math::TPoint3D pc =
            camera.inverseComposePoint(mrpt::math::TPoint3D(x, y, opt.ceiling_height_m));
        ASSERT_GT(pc.z, 0);
        const auto& K = r.intrinsics();
        const cv::Point2d expected(K.cx() + K.fx() * pc.x / pc.z, K.cy() + K.fy() * pc.y / pc.z);
        int count = 0;
        const cv::Point2d found = brightCentroid(img, &count);
        EXPECT_GT(count, 10) << "marker not visible";
        EXPECT_NEAR(found.x, expected.x, 0.35) << "offset " << offset;
        EXPECT_NEAR(found.y, expected.y, 0.35) << "offset " << offset;
    }
}

TEST(CeilingCamera, TranslationShiftsContentByFocalTimesDistanceOverRange) {
    const auto opt = straightTunnel(false);  // textured, flat, no objects
    const TunnelWorld world(opt, 3);
    const auto cam = noiselessCeilingCamera();
    const CameraRenderer r(world, cam, CameraRenderer::Kind::Ceiling, 2);
    const double delta = 0.10;  // vehicle moves 10 cm forward
    const mrpt::poses::CPose3D v0(15.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    const mrpt::poses::CPose3D v1(15.0 + delta, 0.0, 0.0, 0.0, 0.0, 0.0);
    cv::Mat a, b;
    toMat(r.render(v0 + cam.mount.pose(), {})).convertTo(a, CV_64F);
    toMat(r.render(v1 + cam.mount.pose(), {})).convertTo(b, CV_64F);
    cv::Mat window;
    cv::createHanningWindow(window, a.size(), CV_64F);
    const cv::Point2d shift = cv::phaseCorrelate(a, b, window);
    const double expected = r.intrinsics().fx() * delta / (opt.ceiling_height_m - cam.mount.z_m);
    // Mount yaw 90 deg: image up is vehicle forward, so the ceiling slides down the image.
    EXPECT_NEAR(shift.y, expected, 0.15) << "expected " << expected << " px";
    EXPECT_NEAR(shift.x, 0.0, 0.15);
}

TEST(CeilingCamera, OutputDoesNotDependOnThreadCount) {
    const TunnelWorld world(straightTunnel(false), 5);
    const auto cam = ScenarioOptions().ceiling_camera;  // with noise
    const mrpt::poses::CPose3D pose =
        mrpt::poses::CPose3D(10, 0.5, 0, 0.2, 0, 0) + cam.mount.pose();
    FrameConditions fc;
    fc.noise_key = 42;
    fc.blur_v_px = 2.5;
    const cv::Mat one =
        toMat(CameraRenderer(world, cam, CameraRenderer::Kind::Ceiling, 1).render(pose, fc));
    const cv::Mat two =
        toMat(CameraRenderer(world, cam, CameraRenderer::Kind::Ceiling, 2).render(pose, fc));
    EXPECT_EQ(cv::norm(one, two, cv::NORM_INF), 0.0);
    // The texture carries detail at the matcher's patch scale (40-60 px): a patch is not flat.
    cv::Scalar mean, stddev;
    cv::meanStdDev(one(cv::Rect(130, 90, 60, 60)), mean, stddev);
    EXPECT_GT(stddev[0], 8.0);
}

TEST(ForwardCamera, SeesATunnelDarkeningWithDistance) {
    auto opt = straightTunnel(false);
    const TunnelWorld world(opt, 1);
    auto cam = ScenarioOptions().forward_camera;
    cam.noise_std_dn = 0;
    const CameraRenderer r(world, cam, CameraRenderer::Kind::Forward, 2);
    const cv::Mat img =
        toMat(r.render(mrpt::poses::CPose3D(5, 0, 0, 0, 0, 0) + cam.mount.pose(), {}));
    // The vanishing point (far along the tunnel) is darker than the near walls at the borders.
    const double centre = cv::mean(img(cv::Rect(70, 50, 20, 20)))[0];
    const double left = cv::mean(img(cv::Rect(0, 40, 20, 40)))[0];
    EXPECT_LT(centre + 20, left);
}

}  // namespace

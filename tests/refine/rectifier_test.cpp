// Rectifier: images of distorted or other cameras land where the ideal pinhole camera would
// have seen the same rays; maps are cached per camera; bad calibrations are refused.
#include "lookup/refine/rectifier.h"

#include <gtest/gtest.h>
#include <mrpt/img/CImage.h>

#include <limits>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include "lookup/common/camera_params.h"
#include "lookup/refine/geometry.h"

using namespace lookup::refine;

namespace {

mrpt::img::TCamera pinhole(double f, int w = 320, int h = 240) {
    mrpt::img::TCamera c;
    c.ncols = w;
    c.nrows = h;
    c.setIntrinsicParamsFromValues(f, f, (w - 1) / 2.0, (h - 1) / 2.0);
    c.distortion = mrpt::img::DistortionModel::none;
    return c;
}

// Smooth texture (blurred noise) as the ideal camera sees it.
cv::Mat idealTexture() {
    cv::Mat noise(240, 320, CV_8UC1);
    cv::RNG rng(5);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    cv::Mat smooth;
    cv::GaussianBlur(noise, smooth, cv::Size(), 2.5);
    cv::normalize(smooth, smooth, 0, 255, cv::NORM_MINMAX);
    return smooth;
}

// What `camera` records of the scene `ideal` shows through pinhole(f): each camera pixel
// samples the ideal image along its own ray (the distortion inverted by OpenCV).
cv::Mat seenThrough(const mrpt::img::TCamera& camera, const cv::Mat& ideal, double f) {
    std::vector<cv::Point2f> px;
    for (int v = 0; v < int(camera.nrows); ++v)
        for (int u = 0; u < int(camera.ncols); ++u) px.emplace_back(float(u), float(v));
    const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
    const mrpt::img::TCamera t = pinhole(f, ideal.cols, ideal.rows);
    const cv::Matx33d P(t.fx(), 0, t.cx(), 0, t.fy(), t.cy(), 0, 0, 1);
    std::vector<cv::Point2f> in_ideal;
    if (camera.distortion == mrpt::img::DistortionModel::kannala_brandt) {
        const cv::Vec4d d(camera.k1(), camera.k2(), camera.k3(), camera.k4());
        cv::fisheye::undistortPoints(px, in_ideal, K, d, cv::noArray(), P);
    } else {
        const std::vector<double> d(camera.dist.begin(), camera.dist.end());
        cv::undistortPoints(px, in_ideal, K, d, cv::noArray(), P);
    }
    cv::Mat map(int(camera.nrows), int(camera.ncols), CV_32FC2, in_ideal.data());
    cv::Mat out;
    cv::remap(ideal, out, map.clone(), cv::noArray(), cv::INTER_LINEAR, cv::BORDER_CONSTANT, 0);
    return out;
}

// Mean absolute difference over the central `fraction` of the image.
double centralDifference(const cv::Mat& a, const cv::Mat& b, double fraction) {
    const int w = int(a.cols * fraction), h = int(a.rows * fraction);
    const cv::Rect roi((a.cols - w) / 2, (a.rows - h) / 2, w, h);
    return cv::mean(cv::abs(cv::Mat(a(roi)) - cv::Mat(b(roi))))[0];
}

}  // namespace

TEST(Rectifier, IdealCameraPassesThroughWithoutACopy) {
    const Rectifier r(pinhole(146.6));
    const cv::Mat img = idealTexture();
    EXPECT_EQ(r.rectify(img, pinhole(146.6)).data, img.data);
    auto zero_plumb_bob = pinhole(146.6);
    zero_plumb_bob.setDistortionPlumbBob(0, 0, 0, 0, 0);  // the simulator's "none"
    EXPECT_TRUE(r.isIdentity(zero_plumb_bob));
    auto from_db_ini = pinhole(146.61299);  // db.ini's 5 decimals of 146.612994...
    EXPECT_TRUE(Rectifier(pinhole(146.612994)).isIdentity(from_db_ini));
    EXPECT_FALSE(r.isIdentity(pinhole(146.7)));
    EXPECT_EQ(r.cachedCameras(), 0u);
}

TEST(Rectifier, StrongBarrelAndFisheyeLandOnTheIdealPinholeImage) {
    const cv::Mat ideal = idealTexture();
    auto barrel = pinhole(146.6);
    barrel.setDistortionPlumbBob(-0.40, 0.12, 0.0005, -0.0005);
    auto fisheye = pinhole(131.0);
    fisheye.setDistortionKannalaBrandt(0.01, -0.005, 0.002, -0.001);
    for (const auto& camera : {barrel, fisheye}) {
        const double f = camera.fx();
        const cv::Mat raw = seenThrough(camera, ideal, f);
        const Rectifier r(camera);  // the database camera: its pinhole twin is the target
        const cv::Mat rectified = r.rectify(raw, camera);
        ASSERT_EQ(rectified.size(), ideal.size());
        EXPECT_EQ(r.target().distortion, mrpt::img::DistortionModel::none);
        // Resampled twice (bilinear): a few grey levels; unrectified: tens.
        EXPECT_LT(centralDifference(rectified, ideal, 0.7), 4.0);
        EXPECT_GT(centralDifference(raw, ideal, 0.7), 15.0);
    }
}

TEST(Rectifier, AnotherFocalLengthIsScaledIntoTheTargetWithABlackBorder) {
    const cv::Mat ideal = idealTexture();
    const auto longer = pinhole(146.6 * 1.1);
    const cv::Mat raw = seenThrough(longer, ideal, 146.6);
    const Rectifier r(pinhole(146.6));
    const cv::Mat rectified = r.rectify(raw, longer);
    EXPECT_LT(centralDifference(rectified, ideal, 0.8), 4.0);
    EXPECT_EQ(rectified.at<uint8_t>(120, 2), 0);  // the longer lens does not see that far
    EXPECT_EQ(r.cachedCameras(), 1u);
    r.rectify(raw, longer);
    EXPECT_EQ(r.cachedCameras(), 1u);  // maps built once per camera
}

TEST(Rectifier, AFinerCameraIsAveragedDownIntoTheTarget) {
    // The same scene through a 1280x960 camera of four times the focal length, a pinhole and a
    // barrel lens, rectified into the 320x240 target.
    cv::Mat fine_ideal;
    cv::resize(idealTexture(), fine_ideal, cv::Size(1280, 960), 0, 0, cv::INTER_CUBIC);
    const auto target = pinhole(146.6);
    const auto fine = pinhole(4 * 146.6, 1280, 960);
    const auto as_stored = lookup::common::resizedCamera(fine, 320, 240);
    EXPECT_NEAR(as_stored.cx(), target.cx(), 1e-9);  // pixel centres, as cv::resize maps them
    const Rectifier r(target);
    cv::Mat averaged;
    cv::resize(fine_ideal, averaged, cv::Size(320, 240), 0, 0, cv::INTER_AREA);
    const cv::Mat from_pinhole = r.rectify(fine_ideal, fine);
    EXPECT_EQ(cv::norm(from_pinhole, averaged, cv::NORM_INF), 0.0);  // no second resampling
    EXPECT_LT(centralDifference(from_pinhole, idealTexture(), 0.8), 2.0);
    auto barrel = fine;
    barrel.setDistortionPlumbBob(-0.40, 0.12, 0.0005, -0.0005);
    const cv::Mat rectified = r.rectify(seenThrough(barrel, fine_ideal, 4 * 146.6), barrel);
    ASSERT_EQ(rectified.size(), cv::Size(320, 240));
    EXPECT_LT(centralDifference(rectified, idealTexture(), 0.7), 4.0);
    // Texture finer than the target's pixels is averaged, not aliased: pixel noise of the
    // fine camera keeps a quarter of its spread (4x4 pixels averaged), where sampling every
    // fourth pixel would keep it all.
    cv::Mat noise(960, 1280, CV_8UC1);
    cv::RNG rng(7);
    rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
    cv::Scalar mean, stddev;
    cv::meanStdDev(r.rectify(noise, barrel)(cv::Rect(80, 60, 160, 120)), mean, stddev);
    EXPECT_LT(stddev[0], 30.0);
}

TEST(Rectifier, ObservationAndReferenceCarryTheTargetCamera) {
    auto barrel = pinhole(146.6);
    barrel.setDistortionPlumbBob(-0.40, 0.12, 0, 0);
    const Rectifier r(barrel);
    mrpt::obs::CObservationImage obs;
    obs.sensorLabel = "CEILING_CAM";
    obs.cameraParams = barrel;
    obs.cameraPose = mrpt::poses::CPose3D(0.5, 0, 2.4, 0, 0, 0);
    obs.image = mrpt::img::CImage(idealTexture(), mrpt::img::DEEP_COPY);
    const auto out = r.rectify(obs);
    EXPECT_EQ(out.cameraParams.distortion, mrpt::img::DistortionModel::none);
    EXPECT_DOUBLE_EQ(out.cameraParams.fx(), 146.6);
    EXPECT_EQ(out.cameraPose, obs.cameraPose);
    EXPECT_EQ(obs.cameraParams.distortion, mrpt::img::DistortionModel::plumb_bob);  // untouched

    ReferenceImage ref;
    ref.camera = barrel;
    ref.image = idealTexture();
    ref.heat_map = cv::Mat(240, 320, CV_32FC1, cv::Scalar(1.0f));
    r.rectify(ref);
    EXPECT_EQ(ref.camera.distortion, mrpt::img::DistortionModel::none);
    EXPECT_EQ(ref.heat_map.type(), CV_32FC1);
    EXPECT_EQ(ref.heat_map.size(), ref.image.size());
    EXPECT_FLOAT_EQ(ref.heat_map.at<float>(120, 160), 1.0f);
}

TEST(Rectifier, CalibrationsThatCannotDescribeTheImageAreRefused) {
    const Rectifier r(pinhole(146.6));
    const cv::Mat img = idealTexture();
    const auto refused = [&](const mrpt::img::TCamera& c, const std::string& expected) {
        try {
            r.rectify(img, c);
            ADD_FAILURE() << "accepted: " << expected;
        } catch (const std::invalid_argument& e) {
            EXPECT_NE(std::string(e.what()).find(expected), std::string::npos) << e.what();
        }
    };
    refused(pinhole(146.6, 640, 480), "intrinsics are for 640x480 px but the image is 320x240");
    auto unknown = pinhole(146.6);
    unknown.distortion = static_cast<mrpt::img::DistortionModel>(9);
    refused(unknown, "distortion model 9 is not one MRPT knows");
    auto nan = pinhole(146.6);
    nan.setDistortionPlumbBob(-0.3, std::numeric_limits<double>::quiet_NaN(), 0, 0);
    refused(nan, "dist[1] = nan is not finite");
    EXPECT_THROW(Rectifier(pinhole(0.0)), std::invalid_argument);
}

// The rectifier's point maps both ways: a pixel undistorted into the pinhole twin and distorted
// back lands where it was, for a strong barrel (also at 100 deg, where OpenCV's five default
// iterations leave the corners a pixel short) and a fisheye lens.
TEST(Rectifier, PixelsUndistortAndDistortBackToThemselves) {
    mrpt::img::TCamera barrel = pinhole(260), wide = pinhole(134), fisheye = pinhole(200);
    barrel.setDistortionPlumbBob(-0.30, 0.09, 0.0005, -0.0005);
    wide.setDistortionPlumbBob(-0.40, 0.12, 0.0005, -0.0005);
    fisheye.setDistortionKannalaBrandt(0.05, -0.01, 0.002, -0.001);
    std::vector<cv::Point2f> px;
    for (int y = 10; y < 240; y += 37)
        for (int x = 10; x < 320; x += 41) px.emplace_back(float(x), float(y));
    for (const auto& camera : {barrel, wide, fisheye}) {
        const auto ideal = lookup::refine::undistortPixels(px, camera);
        const std::vector<cv::Point2f> ideal_f(ideal.begin(), ideal.end());
        const auto back = lookup::refine::distortPixels(ideal_f, camera);
        double moved = 0;
        for (std::size_t i = 0; i < px.size(); ++i) {
            EXPECT_NEAR(back[i].x, px[i].x, 1e-3) << i;
            EXPECT_NEAR(back[i].y, px[i].y, 1e-3) << i;
            moved = std::max(moved, cv::norm(ideal[i] - cv::Point2d(px[i])));
        }
        EXPECT_GT(moved, 5.0);  // the lens does move the rim
    }
}

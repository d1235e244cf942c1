#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "lookup/common/camera_params.h"
#include "lookup/common/config.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using lookup::common::applyCameraParams;
using lookup::common::ConfigError;
using lookup::common::sensorCameraParams;

namespace {

// A sensors.ini path in a fresh folder holding `calib.ini` with `calib_text`.
std::string sensorsPathWithCalib(const std::string& name, const std::string& calib_text) {
    const fs::path dir = lookup::test::freshDir("camera_params_" + name);
    std::ofstream(dir / "calib.ini") << calib_text;
    return (dir / "sensors.ini").string();
}

const char* kCalib =
    "[CAMERA_PARAMS]\nresolution = [640 480]\ncx = 318.5\ncy = 241.25\nfx = 402.5\n"
    "fy = 401.75\ndistortion_model = plumb_bob\ndist = [-0.29 0.09 0.0003 -0.0002 0]\n";

}  // namespace

TEST(CameraParams, ReadsTheCalibrationFileNamedBySensorSection) {
    const std::string sensors = sensorsPathWithCalib("reads", kCalib);
    mrpt::config::CConfigFileMemory ini(
        "[CAM]\ndriver = CCameraSensor\n"
        "camera_params_file = calib.ini\n[OTHER]\ndriver = X\n");
    const auto cam = sensorCameraParams(ini, "CAM", sensors);
    ASSERT_TRUE(cam.has_value());
    EXPECT_EQ(cam->ncols, 640u);
    EXPECT_EQ(cam->nrows, 480u);
    EXPECT_DOUBLE_EQ(cam->fx(), 402.5);
    EXPECT_DOUBLE_EQ(cam->fy(), 401.75);
    EXPECT_DOUBLE_EQ(cam->cx(), 318.5);
    EXPECT_DOUBLE_EQ(cam->cy(), 241.25);
    EXPECT_DOUBLE_EQ(cam->k1(), -0.29);
    EXPECT_DOUBLE_EQ(cam->p1(), 0.0003);
    EXPECT_FALSE(sensorCameraParams(ini, "OTHER", sensors).has_value());
}

TEST(CameraParams, MissingOrIncompleteCalibrationIsAClearError) {
    const std::string sensors = sensorsPathWithCalib("bad", "[CAMERA_PARAMS]\ncx = 1\n");
    mrpt::config::CConfigFileMemory missing("[CAM]\ncamera_params_file = nowhere.ini\n");
    try {
        sensorCameraParams(missing, "CAM", sensors);
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("[CAM]"), std::string::npos) << msg;
        EXPECT_NE(msg.find("camera_params_file"), std::string::npos) << msg;
        EXPECT_NE(msg.find("nowhere.ini"), std::string::npos) << msg;
    }
    mrpt::config::CConfigFileMemory incomplete("[CAM]\ncamera_params_file = calib.ini\n");
    try {
        sensorCameraParams(incomplete, "CAM", sensors);
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("calib.ini [CAMERA_PARAMS]"), std::string::npos)
            << e.what();
    }
    // dist without a model would be dropped by MRPT: refused instead.
    const std::string no_model = sensorsPathWithCalib(
        "no_model",
        "[CAMERA_PARAMS]\nresolution = [640 480]\ncx = 320\ncy = 240\nfx = 400\n"
        "fy = 400\ndist = [-0.29 0.09 0 0 0]\n");
    try {
        sensorCameraParams(incomplete, "CAM", no_model);
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("distortion_model"), std::string::npos) << e.what();
    }
}

TEST(CameraParams, AppliedToImagesOfTheCalibratedSizeOnly) {
    const std::string sensors = sensorsPathWithCalib("apply", kCalib);
    mrpt::config::CConfigFileMemory ini("[CAM]\ncamera_params_file = calib.ini\n");
    const auto cam = sensorCameraParams(ini, "CAM", sensors);
    ASSERT_TRUE(cam.has_value());

    mrpt::obs::CObservationImage obs;
    obs.sensorLabel = "CEILING_CAM";
    obs.image = mrpt::img::CImage(640, 480, mrpt::img::CH_GRAY);
    EXPECT_EQ(obs.cameraParams.fx(), 0.0);  // what MRPT's OpenCV grabber delivers
    EXPECT_TRUE(applyCameraParams(*cam, obs));
    EXPECT_DOUBLE_EQ(obs.cameraParams.fx(), 402.5);
    EXPECT_DOUBLE_EQ(obs.cameraParams.k2(), 0.09);

    mrpt::obs::CObservationImage small;
    small.sensorLabel = "CEILING_CAM";
    small.image = mrpt::img::CImage(320, 240, mrpt::img::CH_GRAY);
    EXPECT_THROW(applyCameraParams(*cam, small), ConfigError);

    mrpt::obs::CObservationOdometry odo;
    EXPECT_FALSE(applyCameraParams(*cam, odo));
}

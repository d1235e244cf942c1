// share/lookup/sensors/sensors.ini, the example camera set-up for `lookup-localize --live`:
// every sensor is a class MRPT can create and configure, the labels are the ones the
// localiser reads by default, and the mount poses point the cameras where the localiser
// expects (ceiling camera up, forward camera along the vehicle's +x).
#include <gtest/gtest.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/core/bits_math.h>
#include <mrpt/hwdrivers/CGenericSensor.h>
#include <mrpt/poses/CPose3D.h>

#include <map>
#include <string>
#include <vector>

#include "lookup/localize/localizer_options.h"

namespace {

const std::string kSensorsIni = std::string(LOOKUP_SOURCE_SHARE_DIR) + "/sensors/sensors.ini";

mrpt::poses::CPose3D mountPose(const mrpt::config::CConfigFileBase& ini, const std::string& s) {
    auto deg = [&](const char* key) { return mrpt::DEG2RAD(ini.read_double(s, key, 0)); };
    return mrpt::poses::CPose3D(ini.read_double(s, "pose_x", 0), ini.read_double(s, "pose_y", 0),
                                ini.read_double(s, "pose_z", 0), deg("pose_yaw"), deg("pose_pitch"),
                                deg("pose_roll"));
}

// The camera's optical axis (+Z of the camera frame) in vehicle coordinates.
mrpt::math::TPoint3D opticalAxis(const mrpt::poses::CPose3D& camera_on_vehicle) {
    const auto R = camera_on_vehicle.getRotationMatrix();
    return {R(0, 2), R(1, 2), R(2, 2)};
}

}  // namespace

TEST(SensorsIni, EverySensorIsAnMrptClassWithTheLocaliserLabels) {
    mrpt::config::CConfigFile ini(kSensorsIni);
    std::vector<std::string> sections;
    ini.getAllSections(sections);
    std::map<std::string, std::string> label_to_section;
    for (const auto& section : sections) {
        const std::string driver = ini.read_string(section, "driver", "");
        if (driver.empty()) continue;
        auto sensor = mrpt::hwdrivers::CGenericSensor::createSensorPtr(driver);
        ASSERT_TRUE(sensor) << "[" << section << "] driver " << driver << " is not an MRPT sensor";
        // loadConfig reads every key without opening the device (initialize() would).
        ASSERT_NO_THROW(sensor->loadConfig(ini, section)) << "[" << section << "]";
        EXPECT_EQ(sensor->getSensorLabel(), ini.read_string(section, "sensorLabel", ""));
        label_to_section[sensor->getSensorLabel()] = section;
    }
    const lookup::localize::LocalizerOptions defaults;
    ASSERT_EQ(label_to_section.count(defaults.ceiling_camera_label), 1u)
        << kSensorsIni << ": no sensor labelled " << defaults.ceiling_camera_label;
    ASSERT_EQ(label_to_section.count(defaults.forward_camera_label), 1u)
        << kSensorsIni << ": no sensor labelled " << defaults.forward_camera_label;

    const auto up = opticalAxis(mountPose(ini, label_to_section[defaults.ceiling_camera_label]));
    EXPECT_NEAR(up.z, 1.0, 1e-6) << "the ceiling camera does not look up";
    const auto ahead = opticalAxis(mountPose(ini, label_to_section[defaults.forward_camera_label]));
    EXPECT_NEAR(ahead.x, 1.0, 1e-6) << "the forward camera does not look along +x";
}

#include <gtest/gtest.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/rtti/CObject.h>
#include <mrpt/serialization/CArchive.h>
#include <mrpt/system/os.h>

#include <sstream>

// This test does not link liblookup_obs: the classes exist only once the plug-in is loaded,
// exactly as in `RawLogViewer -l liblookup_obs.so`.
TEST(Plugin, LoadsAndRecordRoundTripsByClassName) {
    const char* name = "lookup::obs::CObservationLookupReference";
    ASSERT_EQ(mrpt::rtti::classFactory(name), nullptr);
    std::string errors;
    ASSERT_TRUE(mrpt::system::loadPluginModule(LOOKUP_PLUGIN_PATH, errors)) << errors;
    auto object = mrpt::rtti::classFactory(name);
    ASSERT_NE(object, nullptr);
    auto obs = std::dynamic_pointer_cast<mrpt::obs::CObservation>(object);
    ASSERT_NE(obs, nullptr);
    obs->sensorLabel = "LOOKUP_REF";
    obs->timestamp = mrpt::Clock::fromDouble(1234.5);
    obs->setSensorPose(mrpt::poses::CPose3D(0.5, 0.1, 2.0, 0.3, 0, 0));

    mrpt::io::CMemoryStream buffer;
    auto out = mrpt::serialization::archiveFrom(buffer);
    out << *obs;
    buffer.Seek(0);
    auto in = mrpt::serialization::archiveFrom(buffer);
    auto back = std::dynamic_pointer_cast<mrpt::obs::CObservation>(in.ReadObject());
    ASSERT_NE(back, nullptr);
    EXPECT_STREQ(back->GetRuntimeClass()->className, name);
    EXPECT_EQ(back->sensorLabel, "LOOKUP_REF");
    EXPECT_DOUBLE_EQ(mrpt::Clock::toDouble(back->timestamp), 1234.5);
    mrpt::poses::CPose3D sensor;
    back->getSensorPose(sensor);
    EXPECT_NEAR(sensor.z(), 2.0, 1e-12);
    EXPECT_NEAR(sensor.yaw(), 0.3, 1e-12);
    std::ostringstream text;
    back->getDescriptionAsText(text);
    EXPECT_NE(text.str().find("LookUP reference #0"), std::string::npos);
    EXPECT_NE(mrpt::rtti::classFactory("lookup::obs::CObservationLookupResult"), nullptr);
}

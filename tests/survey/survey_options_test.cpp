#include <gtest/gtest.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/core/bits_math.h>

#include "../common/round_trip.h"
#include "lookup/common/config.h"
#include "lookup/common/options_table.h"
#include "lookup/survey/pose_graph.h"
#include "lookup/survey/survey_options.h"

using lookup::survey::SurveyOptions;

TEST(SurveyOptions, DefaultsAreValid) { EXPECT_NO_THROW(SurveyOptions().check()); }

TEST(SurveyOptions, ShareIniLoadsAndRoundTrips) {
    mrpt::config::CConfigFile file(std::string(LOOKUP_SOURCE_SHARE_DIR) + "/survey.ini");
    SurveyOptions a;
    a.keyframe_spacing_m = 99;  // must be overwritten by the file
    a.loadFromConfigFile(file, "survey");
    EXPECT_DOUBLE_EQ(a.keyframe_spacing_m, 0.25);
    EXPECT_DOUBLE_EQ(a.icp_max_range_m, 0.0);  // share/lookup/survey.ini: all returns
    a.icp_max_range_m = 12.5;
    EXPECT_DOUBLE_EQ(a.map_std_xy_m, 0.08);
    a.map_std_xy_m = 0.3;
    mrpt::config::CConfigFileMemory mem;
    a.saveToConfigFile(mem, "survey");
    SurveyOptions b;
    b.keyframe_spacing_m = 1;
    b.mcl_particles = 11;
    b.loadFromConfigFile(mem, "survey");
    EXPECT_DOUBLE_EQ(b.keyframe_spacing_m, a.keyframe_spacing_m);
    EXPECT_EQ(b.mcl_particles, a.mcl_particles);
    EXPECT_EQ(b.lidar_label, a.lidar_label);
    EXPECT_EQ(b.start_at_ground_truth, a.start_at_ground_truth);
    EXPECT_DOUBLE_EQ(b.icp_max_range_m, 12.5);
    EXPECT_DOUBLE_EQ(b.map_std_xy_m, 0.3);
}

namespace {
// Loading `key = value` must fail with a ConfigError that names the key.
void expectRefusedByName(const char* key, double value) {
    mrpt::config::CConfigFileMemory mem;
    mem.write("survey", key, value);
    SurveyOptions o;
    try {
        lookup::common::loadAndCheck(o, mem, "survey");
        FAIL() << key << " = " << value << " accepted";
    } catch (const lookup::common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
}
}  // namespace

TEST(SurveyOptions, NegativeIcpMaxRangeIsRefusedByName) {
    expectRefusedByName("icp_max_range_m", -3.0);
}

TEST(SurveyOptions, AMalformedOrZeroUncertainEndMarkIsRefusedByName) {
    expectRefusedByName("end_pose_std_xy_m", 0.0);
    mrpt::config::CConfigFileMemory mem;
    mem.write("survey", "end_pose", "60 1");
    SurveyOptions o;
    try {
        lookup::common::loadAndCheck(o, mem, "survey");
        FAIL() << "end_pose = 60 1 accepted";
    } catch (const lookup::common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("end_pose"), std::string::npos) << e.what();
    }
}

// Marks along the drive: "t x y yaw_deg" groups separated by ';' (blank groups skipped); any
// group that is not four finite numbers refuses the whole key, by name.
TEST(SurveyOptions, MarksAlongTheDriveParseOrAreRefusedByName) {
    const auto two = lookup::survey::parseMarks("100.5 1 2 90; 110 3 -4 -45.5;");
    ASSERT_TRUE(two.has_value());
    ASSERT_EQ(two->size(), 2u);
    EXPECT_DOUBLE_EQ((*two)[0].time_s, 100.5);
    EXPECT_DOUBLE_EQ((*two)[1].pose.y(), -4);
    EXPECT_NEAR(mrpt::RAD2DEG((*two)[1].pose.phi()), -45.5, 1e-12);
    EXPECT_TRUE(lookup::survey::parseMarks("")->empty());
    for (const char* bad : {"100 1 2", "100 1 2 3 4", "100 1 2 x", "1 2 3 4; nan 1 2 3"}) {
        EXPECT_FALSE(lookup::survey::parseMarks(bad).has_value()) << bad;
    }
    mrpt::config::CConfigFileMemory mem;
    mem.write("survey", "marks", "100 1 2 3; 110 1 2");
    SurveyOptions o;
    try {
        lookup::common::loadAndCheck(o, mem, "survey");
        FAIL() << "a mark of three numbers accepted";
    } catch (const lookup::common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("marks"), std::string::npos) << e.what();
    }
    expectRefusedByName("marks_std_xy_m", 0.0);
}

TEST(SurveyOptions, RejectsBadFieldAndUnknownKey) {
    expectRefusedByName("keyframe_spacing_m", -1.0);
    SurveyOptions o;
    mrpt::config::CConfigFileMemory typo;
    typo.write("survey", "keyframe_spacin_m", 0.3);
    EXPECT_THROW(o.loadFromConfigFile(typo, "survey"), lookup::common::ConfigError);
}

TEST(SurveyOptions, SurveyAndPoseGraphRoundTrip) {
    SurveyOptions s;
    s.lidar_label = "SCAN";
    s.start_pose = "1 2 90";
    s.end_pose = "61.5 -2 89.5";
    s.end_pose_std_xy_m = 0.02;
    s.marks = "1700000004 10 1 90; 1700000008.5 20 1 90";
    s.marks_std_yaw_deg = 0.3;
    s.ceiling_estimate = false;
    s.min_sharpness = 1.0 / 7.0;
    lookup::options_testing::expectRoundTrip(s, "survey");
    lookup::survey::PoseGraphOptions g;
    g.all_traverses = false;
    g.huber_sigmas = 2.25;
    g.covariance_stride = 3;
    lookup::options_testing::expectRoundTrip(g, "pose_graph");
}

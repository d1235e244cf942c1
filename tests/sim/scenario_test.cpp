// Scenario files: presets load and validate, the resolved form round-trips, and malformed files
// are refused with the file, section and key in the message.

#include <gtest/gtest.h>
#include <lookup/common/config.h>
#include <lookup/sim/scenario.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <filesystem>
#include <fstream>
#include <string>
#include "lookup/test/support.h"

namespace {

using lookup::common::ConfigError;
using lookup::sim::ScenarioOptions;

const char* kPresets[] = {
    "mine-a",      "mine-b",      "mine-a-mini",      "mine-b-mini",      "lhd-cycle-mini",
    "mine-a-real", "mine-b-real", "mine-a-real-mini", "mine-b-real-mini", "mine-b-decline-mini"};

std::string presetPath(const std::string& name) {
    return lookup::sim::findPreset(name, {std::string(LOOKUP_SOURCE_SHARE_DIR) + "/scenarios"});
}

std::string writeTemp(const std::string& name, const std::string& text) {
    const auto dir = std::filesystem::temp_directory_path() / "lookup_sim_scenario_test";
    std::filesystem::create_directories(dir);
    const std::string path = (dir / name).string();
    std::ofstream(path) << text;
    return path;
}

/// The error message `fromFile` gives for `text`, or "" if it was accepted.
std::string refusal(const std::string& name, const std::string& text) {
    const std::string path = writeTemp(name, text);
    try {
        ScenarioOptions::fromFile(path);
    } catch (const ConfigError& e) {
        return e.what();
    }
    return "";
}

TEST(Scenario, DefaultOptionsAreValidOnceTraversesExist) {
    ScenarioOptions s;
    EXPECT_THROW(s.check(), ConfigError);  // no traverse
    s.traverses.push_back({});
    s.traverses.back().name = "t";
    s.traverses.back().roles = "reference";
    EXPECT_NO_THROW(s.check());
}

TEST(Scenario, EveryPresetLoadsAndRoundTrips) {
    for (const char* name : kPresets) {
        SCOPED_TRACE(name);
        const ScenarioOptions s = ScenarioOptions::fromFile(presetPath(name));
        EXPECT_EQ(s.name, name);
        const std::string text = s.toIniText();
        const std::string path = writeTemp(std::string(name) + "-resolved.ini", text);
        const ScenarioOptions back = ScenarioOptions::fromFile(path);
        EXPECT_EQ(back.toIniText(), text);
        EXPECT_EQ(back.traverses.size(), s.traverses.size());
    }
}

TEST(Scenario, PresetsHaveThePapersTraverses) {
    const ScenarioOptions b = ScenarioOptions::fromFile(presetPath("mine-b"));
    ASSERT_EQ(b.traverses.size(), 4u);
    EXPECT_EQ(b.traverses[0].name, "left");
    EXPECT_EQ(b.traverses[3].roles, "query");
    const ScenarioOptions a = ScenarioOptions::fromFile(presetPath("mine-a"));
    ASSERT_EQ(a.traverses.size(), 9u);
    int refs = 0, queries = 0;
    for (const auto& t : a.traverses) {
        refs += t.roles.find("reference") != std::string::npos;
        queries += t.roles.find("query") != std::string::npos;
    }
    EXPECT_EQ(refs, 4);
    EXPECT_EQ(queries, 5);
}

TEST(Scenario, UnknownKeyIsRefusedWithFileSectionAndKey) {
    std::string text = lookup::test::readText(presetPath("mine-b-mini"));
    text.replace(text.find("speed_kmh"), 9, "sped_kmh");
    const std::string msg = refusal("typo.ini", text);
    EXPECT_NE(msg.find("typo.ini"), std::string::npos) << msg;
    EXPECT_NE(msg.find("[traverse_0]"), std::string::npos) << msg;
    EXPECT_NE(msg.find("sped_kmh"), std::string::npos) << msg;
}

TEST(Scenario, MalformedNumberIsRefusedWithFileSectionAndKey) {
    std::string text = lookup::test::readText(presetPath("mine-b-mini"));
    text.replace(text.find("width_m = 5.5"), 13, "width_m = 5,5");
    const std::string msg = refusal("comma.ini", text);
    EXPECT_NE(msg.find("comma.ini"), std::string::npos) << msg;
    EXPECT_NE(msg.find("[world] width_m"), std::string::npos) << msg;
    EXPECT_NE(msg.find("5,5"), std::string::npos) << msg;
}

TEST(Scenario, OutOfRangeValueNamesTheField) {
    std::string text = lookup::test::readText(presetPath("mine-b-mini"));
    text.replace(text.find("width_m = 5.5"), 13, "width_m = 1.0");
    const std::string msg = refusal("narrow.ini", text);
    EXPECT_NE(msg.find("narrow.ini"), std::string::npos) << msg;
    EXPECT_NE(msg.find("world.width_m"), std::string::npos) << msg;
}

TEST(Scenario, UnknownSectionAndMissingTraverseAreRefused) {
    std::string text = lookup::test::readText(presetPath("mine-b-mini"));
    EXPECT_NE(refusal("extra.ini", text + "\n[travers_9]\nname = x\n").find("[travers_9]"),
              std::string::npos);
    std::string fewer = text;
    fewer.replace(fewer.find("traverse_count = 4"), 18, "traverse_count = 5");
    EXPECT_NE(refusal("fewer.ini", fewer).find("[traverse_4]"), std::string::npos);
    EXPECT_NE(refusal("missing.ini", "").find("[scenario]"), std::string::npos);
    EXPECT_THROW(ScenarioOptions::fromFile("/nonexistent/x.ini"), ConfigError);
    EXPECT_THROW(lookup::sim::findPreset("no-such-mine", {LOOKUP_SOURCE_SHARE_DIR}), ConfigError);
}

/// mine-b-mini with `extra` appended to section `[section]` (inserted after its header).
std::string withKeys(const std::string& section, const std::string& extra) {
    std::string text = lookup::test::readText(presetPath("mine-b-mini"));
    const std::string header = "[" + section + "]\n";
    const auto at = text.find(header);
    if (at == std::string::npos) return text + "\n" + header + extra + "\n";
    text.insert(at + header.size(), extra + "\n");
    return text;
}

TEST(Scenario, PhysicallyImpossibleSensorValuesAreRefusedNamingTheKey) {
    const struct {
        const char* section;
        const char* keys;
        const char* field;
    } cases[] = {
        {"ceiling_camera", "readout_ms = 80", "ceiling_camera.readout_ms"},  // 14 Hz: 71 ms
        {"lidar", "latency_ms = 1500", "lidar.latency_ms"},
        {"forward_camera", "latency_ms = -1200", "forward_camera.latency_ms"},
        {"odometry", "drop_rate = 1", "odometry.drop_rate"},
        {"lidar", "drop_rate = -0.1", "lidar.drop_rate"},
        {"lidar", "dust_rate = -0.1", "lidar.dust_rate"},
        {"odometry", "slip_fraction = -0.2", "odometry.slip_fraction"},
        {"ceiling_camera", "distortion = barrel", "ceiling_camera.distortion"},
        {"ceiling_camera", "stamp_row = last", "[ceiling_camera] stamp_row"},
        {"ceiling_camera", "jitter_ms = 50", "ceiling_camera.jitter_ms"},
        {"lidar", "sweep_ms = 150", "lidar.sweep_ms"},
        {"traverse_3", "direction = sideways", "traverse_3.direction"},
        {"traverse_3", "plan = drive 30, drive 10", "traverse_3.plan leg 2"},
        {"traverse_3", "plan = drive 30, stop -5", "traverse_3.plan"},
        {"world", "grade = 10 40 -1:3", "world.grade"},
        {"world", "grade = 10 40 0.3", "world.grade"},
        {"world", "grade = 30 50 0.1, 10 40 0.1", "world.grade ramp 2"},
    };
    for (const auto& c : cases) {
        SCOPED_TRACE(c.keys);
        const std::string msg = refusal("impossible.ini", withKeys(c.section, c.keys));
        EXPECT_NE(msg.find("impossible.ini"), std::string::npos) << msg;
        EXPECT_NE(msg.find(c.field), std::string::npos) << msg;
    }
    std::string text = lookup::test::readText(presetPath("mine-b-mini"));
    text.replace(text.find("rate_hz = 50"), 12, "rate_hz = -50");
    EXPECT_NE(refusal("negative.ini", text).find("odometry.rate_hz"), std::string::npos);
}

/// How many of the failures in `msg` (one line each, "scenario.FIELD must be ...") name `field`.
int failuresNaming(const std::string& msg, const std::string& field) {
    const std::string line = "scenario." + field + " must be";
    int n = 0;
    for (auto at = msg.find(line); at != std::string::npos; at = msg.find(line, at + 1)) ++n;
    return n;
}

TEST(Scenario, EachBadKeyIsReportedOnce) {
    // [world] and the traverse overrides share their checks: one failure per bad key, under
    // its own section's name.
    const std::string world = refusal("contrast.ini", withKeys("world", "rock_contrast = 5"));
    EXPECT_EQ(failuresNaming(world, "world.rock_contrast"), 1) << world;
    const std::string vehicle =
        refusal("wheelbase.ini", withKeys("traverse_3.vehicle", "wheelbase_m = 0.1"));
    EXPECT_EQ(failuresNaming(vehicle, "traverse_3.vehicle.wheelbase_m"), 1) << vehicle;
    EXPECT_EQ(failuresNaming(vehicle, "vehicle.wheelbase_m"), 0) << vehicle;
}

TEST(Scenario, PerTraverseOverridesLoadRoundTripAndStayInTheirLane) {
    const std::string text =
        withKeys("traverse_3.ceiling_camera", "hfov_deg = 80\npose_z_m = 2.9\nexposure_ms = 8") +
        "\n[traverse_3.world]\nmesh_fraction = 0.9\nlight_spacing_m = 0\n";
    const ScenarioOptions s = ScenarioOptions::fromFile(writeTemp("later.ini", text));
    ASSERT_TRUE(s.traverses[3].ceiling_camera.has_value());
    EXPECT_EQ(s.ceilingCameraFor(3).hfov_deg, 80);
    EXPECT_EQ(s.ceilingCameraFor(3).mount.z_m, 2.9);
    EXPECT_EQ(s.ceilingCameraFor(3).rate_hz, 14) << "keys not overridden come from the scenario";
    EXPECT_EQ(s.ceilingCameraFor(0).hfov_deg, 95);
    EXPECT_EQ(s.worldFor(3).mesh_fraction, 0.9);
    EXPECT_EQ(s.worldFor(3).length_m, s.world.length_m);
    EXPECT_FALSE(s.traverses[2].world.has_value());
    const ScenarioOptions back =
        ScenarioOptions::fromFile(writeTemp("later-resolved.ini", s.toIniText()));
    EXPECT_EQ(back.toIniText(), s.toIniText());
    // The mine's shape is one for all traverses; the labels are the dataset's.
    std::string msg = refusal("shape.ini", text + "\n[traverse_2.world]\nlength_m = 30\n");
    EXPECT_NE(msg.find("[traverse_2.world]"), std::string::npos) << msg;
    EXPECT_NE(msg.find("length_m"), std::string::npos) << msg;
    msg = refusal("label.ini", withKeys("traverse_1.forward_camera", "label = OTHER"));
    EXPECT_NE(msg.find("traverse_1.forward_camera.label"), std::string::npos) << msg;
    msg = refusal("late.ini", withKeys("traverse_1.ceiling_camera", "readout_ms = 90"));
    EXPECT_NE(msg.find("traverse_1.ceiling_camera.readout_ms"), std::string::npos) << msg;
    EXPECT_NE(refusal("nine.ini", text + "\n[traverse_9.world]\nmesh_fraction = 1\n")
                  .find("[traverse_9.world]"),
              std::string::npos);
}

}  // namespace

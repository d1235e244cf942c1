#include "lookup/coarse/options.h"

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>

#include "lookup/common/config.h"
#include "lookup/common/options_table.h"

namespace lookup::coarse {
namespace {

TEST(CoarseOptions, DefaultsAreValid) { EXPECT_NO_THROW(CoarseOptions().check()); }

TEST(CoarseOptions, ShareIniEqualsDefaultsAndRoundTrips) {
    const std::string path = std::string(LOOKUP_SOURCE_SHARE_DIR) + "/coarse.ini";
    mrpt::config::CConfigFile file(path);
    CoarseOptions loaded;
    loaded.min_confidence = 99;  // must be overwritten by the file
    loaded.loadFromConfigFile(file, "coarse");
    mrpt::config::CConfigFileMemory a, b;
    CoarseOptions().saveToConfigFile(a, "coarse");
    loaded.saveToConfigFile(b, "coarse");
    EXPECT_EQ(a.getContent(), b.getContent());

    CoarseOptions changed;
    changed.sequence_length = 31;
    changed.velocity_max = 3.25;
    changed.use_odometry = false;
    changed.camera_label = "FRONT";
    mrpt::config::CConfigFileMemory mem;
    changed.saveToConfigFile(mem, "x");
    CoarseOptions back;
    back.loadFromConfigFile(mem, "x");
    EXPECT_EQ(back.sequence_length, 31);
    EXPECT_DOUBLE_EQ(back.velocity_max, 3.25);
    EXPECT_FALSE(back.use_odometry);
    EXPECT_EQ(back.camera_label, "FRONT");
}

TEST(CoarseOptions, BadValuesNameTheField) {
    mrpt::config::CConfigFileMemory typo(std::string("[coarse]\nsequence_lenght = 10\n"));
    try {
        CoarseOptions().loadFromConfigFile(typo, "coarse");
        ADD_FAILURE() << "typo accepted";
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("sequence_lenght"), std::string::npos);
    }
    mrpt::config::CConfigFileMemory bad(std::string("[coarse]\npatch_size_px = 7\n"));
    try {
        CoarseOptions o;
        common::loadAndCheck(o, bad, "coarse");  // check(): the apps' way, naming the file
        ADD_FAILURE() << "patch 7 accepted for 64x48";
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("coarse.patch_size_px"), std::string::npos);
    }
    CoarseOptions o;
    o.velocity_min = 2;
    o.velocity_max = 1;
    o.tracking_half_window_refs = 5;
    try {
        o.check();
        ADD_FAILURE();
    } catch (const common::ConfigError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("velocity_max"), std::string::npos);
        EXPECT_NE(m.find("tracking_half_window_refs"), std::string::npos);
    }
}

}  // namespace
}  // namespace lookup::coarse

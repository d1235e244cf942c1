// Options: defaults valid, share/lookup/train.ini holds exactly the defaults and round-trips,
// bad values and unknown keys are refused naming the field.

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>

#include "lookup/common/config.h"
#include "lookup/fcn/options.h"

using namespace lookup;
using namespace lookup::fcn;

namespace {
std::string saved(const TrainOptions& o) {
    mrpt::config::CConfigFileMemory m;
    o.saveToConfigFile(m, "fcn");
    return m.getContent();
}
}  // namespace

TEST(Options, DefaultsAreValid) { EXPECT_NO_THROW(TrainOptions().check()); }

TEST(Options, ShareIniHoldsTheDefaultsAndRoundTrips) {
    mrpt::config::CConfigFile cfg(std::string(LOOKUP_SOURCE_SHARE_DIR) + "/train.ini");
    TrainOptions from_file;
    from_file.network.depth = 99;  // must be overwritten by the file
    from_file.loadFromConfigFile(cfg, "fcn");
    EXPECT_EQ(saved(from_file), saved(TrainOptions()));

    TrainOptions changed;
    changed.network.base_channels = 24;
    changed.labels.matcher.patch_px = 60;
    changed.training.augment = false;
    changed.labels.use_pose_prior = false;
    mrpt::config::CConfigFileMemory m;
    changed.saveToConfigFile(m, "fcn");
    TrainOptions back;
    back.loadFromConfigFile(m, "fcn");
    EXPECT_EQ(saved(back), saved(changed));
    EXPECT_EQ(back.network.base_channels, 24);
    EXPECT_EQ(back.labels.matcher.patch_px, 60);
    EXPECT_FALSE(back.training.augment);
}

TEST(Options, InvalidValuesAreNamed) {
    TrainOptions o;
    o.network.depth = 0;
    o.training.learning_rate = -1;
    try {
        o.check();
        FAIL();
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("depth"), std::string::npos) << e.what();
    }
    o = TrainOptions();
    o.labels.held_out_share = 1.0;
    EXPECT_THROW(o.check(), common::ConfigError);
    o = TrainOptions();
    o.training.learning_rate = 0;
    try {
        o.check();
        FAIL();
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("learning_rate"), std::string::npos) << e.what();
    }
}

TEST(Options, UnknownKeysAndMalformedValuesAreRefusedNamingTheKey) {
    mrpt::config::CConfigFileMemory m;
    m.write("fcn.training", "epoks", 3);
    TrainOptions o;
    try {
        o.loadFromConfigFile(m, "fcn");
        FAIL();
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("epoks"), std::string::npos) << e.what();
    }
    mrpt::config::CConfigFileMemory bad;
    bad.write("fcn.network", "input_scale", std::string("half"));
    try {
        o.loadFromConfigFile(bad, "fcn");
        FAIL();
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("input_scale"), std::string::npos) << e.what();
    }
}

#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include "lookup/common/config.h"

using lookup::common::ConfigError;
using lookup::common::IniSection;
using lookup::common::OptionsCheck;

TEST(IniSection, ReadsTypedValuesAndFallbacks) {
    mrpt::config::CConfigFileMemory cfg("[s]\na = 2.5\nn = 7\nflag = yes\nname = mine\n");
    IniSection s(cfg, "s", "test.ini");
    EXPECT_DOUBLE_EQ(s.getDouble("a", 0), 2.5);
    EXPECT_EQ(s.getInt("n", 0), 7);
    EXPECT_TRUE(s.getBool("flag", false));
    EXPECT_EQ(s.getString("name", ""), "mine");
    EXPECT_DOUBLE_EQ(s.getDouble("absent", -1), -1);
}

TEST(IniSection, MalformedValueNamesFileSectionAndKey) {
    mrpt::config::CConfigFileMemory cfg("[tunnel]\nwidth_m = wide\n");
    IniSection s(cfg, "tunnel", "mine.ini");
    try {
        s.getDouble("width_m", 5.0);
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("mine.ini"), std::string::npos) << msg;
        EXPECT_NE(msg.find("[tunnel]"), std::string::npos) << msg;
        EXPECT_NE(msg.find("width_m"), std::string::npos) << msg;
    }
}

TEST(IniSection, MissingRequiredAndUnknownKeysAreRefused) {
    mrpt::config::CConfigFileMemory cfg("[s]\nsped = 3\n");
    IniSection s(cfg, "s", "f.ini");
    EXPECT_THROW(s.requireDouble("speed"), ConfigError);
    EXPECT_THROW(s.rejectUnknownKeys({"speed"}), ConfigError);
    EXPECT_NO_THROW(s.rejectUnknownKeys({"sped"}));
}

TEST(OptionsCheck, ReportsEveryFailingField) {
    OptionsCheck c("matcher");
    c.require(true, "ok_field", "> 0");
    c.require(false, "search_range_px", "> 0");
    c.require(false, "patch_px", "odd");
    EXPECT_FALSE(c.ok());
    EXPECT_NE(c.message().find("matcher.search_range_px"), std::string::npos);
    EXPECT_NE(c.message().find("matcher.patch_px"), std::string::npos);
    EXPECT_THROW(c.throwIfFailed(), ConfigError);
}

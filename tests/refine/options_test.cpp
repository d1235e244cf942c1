#include <gtest/gtest.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>

#include "lookup/common/config.h"
#include "lookup/refine/options.h"

using namespace lookup::refine;
using lookup::common::ConfigError;

namespace {
const std::string kIni = std::string(LOOKUP_SOURCE_SHARE_DIR) + "/refiner.ini";

void expectSame(const RefinerOptions& a, const RefinerOptions& b) {
    mrpt::config::CConfigFileMemory ma, mb;
    a.saveToConfigFile(ma, "x");
    b.saveToConfigFile(mb, "x");
    EXPECT_EQ(ma.getContent(), mb.getContent());
}
}  // namespace

TEST(RefinerOptions, DefaultsAreValidAndTableI) {
    const RefinerOptions o;
    EXPECT_NO_THROW(o.check());
    EXPECT_EQ(o.matcher.search_range_px, 40);
    EXPECT_EQ(o.matcher.patch_px, 40);
    EXPECT_DOUBLE_EQ(o.sampler.damping_ratio, 0.5);
    EXPECT_EQ(o.sampler.damping_side_px, 10);
    EXPECT_EQ(o.sampler.grid_points, 24);
    EXPECT_EQ(o.sampler.heat_map_points, 12);
    EXPECT_DOUBLE_EQ(o.acceptance.min_inlier_share, 0.6);
    EXPECT_DOUBLE_EQ(o.acceptance.max_offset_m, 2.0);
    EXPECT_NO_THROW(RefinerOptions::mineB().check());
    EXPECT_EQ(RefinerOptions::mineB().matcher.search_range_px, 70);
    EXPECT_EQ(RefinerOptions::mineB().matcher.patch_px, 60);
}

TEST(RefinerOptions, ShareIniHoldsTheDefaultsAndRoundTrips) {
    mrpt::config::CConfigFile file(kIni);
    RefinerOptions loaded;
    loaded.loadFromConfigFile(file, "refine");
    expectSame(loaded, RefinerOptions());
    const RefinerOptions mine_b = RefinerOptions::mineB();
    mrpt::config::CConfigFileMemory mem;
    mine_b.saveToConfigFile(mem, "again");
    RefinerOptions reloaded;
    reloaded.loadFromConfigFile(mem, "again");
    expectSame(reloaded, mine_b);
}

TEST(RefinerOptions, CheckNamesTheFailingField) {
    RefinerOptions o;
    o.matcher.patch_px = 0;
    o.acceptance.min_inlier_share = 1.5;
    try {
        o.check();
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("refine.matcher.patch_px"), std::string::npos)
            << e.what();
    }
    RefinerOptions margin;
    margin.sampler.border_margin_px = 5;  // < patch / 2
    EXPECT_THROW(margin.check(), ConfigError);
}

TEST(RefinerOptions, LoadingIsStrict) {
    mrpt::config::CConfigFileMemory typo("[r.matcher]\nsearch_rang_px = 40\n");
    RefinerOptions o;
    EXPECT_THROW(o.loadFromConfigFile(typo, "r"), ConfigError);
    mrpt::config::CConfigFileMemory bad("[r.sampler]\nmode = best\n");
    EXPECT_THROW(o.loadFromConfigFile(bad, "r"), ConfigError);
    mrpt::config::CConfigFileMemory nan("[r.matcher]\npatch_px = forty\n");
    EXPECT_THROW(o.loadFromConfigFile(nan, "r"), ConfigError);
}

TEST(RefinerOptions, IntegersAreRangeCheckedOnLoadNamingTheRange) {
    const auto message = [](const std::string& text) {
        mrpt::config::CConfigFileMemory cfg(text);
        RefinerOptions o;
        try {
            o.loadFromConfigFile(cfg, "r");
        } catch (const ConfigError& e) {
            return std::string(e.what());
        }
        return std::string();
    };
    // 4294967320 used to wrap to 24 (the default) and pass unnoticed.
    std::string m = message("[r.sampler]\ngrid_points = 4294967320\n");
    EXPECT_NE(m.find("[r.sampler] grid_points: 4294967320 is out of range [4, 1024]"),
              std::string::npos)
        << m;
    m = message("[r.sampler]\ngrid_points = 100000\n");
    EXPECT_NE(m.find("grid_points: 100000 is out of range [4, 1024]"), std::string::npos) << m;
    m = message("[r.matcher]\nsearch_range_px = -5\n");
    EXPECT_NE(m.find("search_range_px: -5 is out of range [2, 512]"), std::string::npos) << m;
    m = message("[r.sampler]\ndamping_ratio = nan\n");
    EXPECT_NE(m.find("damping_ratio: 'nan' is not finite"), std::string::npos) << m;
}

TEST(RefinerOptions, RollingShutterReadoutIsCheckedAndLoaded) {
    RefinerOptions o;
    EXPECT_EQ(o.rolling_shutter.readout_ms, 0.0);  // global shutter: today's results
    o.rolling_shutter.readout_ms = -1;
    EXPECT_THROW(o.check(), ConfigError);
    o.rolling_shutter.readout_ms = 1000;  // no camera reads a frame that slowly
    try {
        o.check();
        FAIL() << "expected ConfigError";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("refine.rolling_shutter.readout_ms"),
                  std::string::npos)
            << e.what();
    }
    mrpt::config::CConfigFileMemory mem;
    mem.write("refine.rolling_shutter", "readout_ms", 30.0);
    mem.write("refine.rolling_shutter", "stamp_row", "middle");
    RefinerOptions loaded;
    loaded.loadFromConfigFile(mem, "refine");
    EXPECT_NO_THROW(loaded.check());
    EXPECT_DOUBLE_EQ(loaded.rolling_shutter.readout_ms, 30.0);
    EXPECT_DOUBLE_EQ(loaded.rolling_shutter.stampRow(240), 119.5);
    mem.write("refine.rolling_shutter", "stamp_row", "last");
    EXPECT_THROW(loaded.loadFromConfigFile(mem, "refine"), ConfigError);
}

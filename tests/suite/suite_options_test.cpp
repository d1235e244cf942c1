#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "lookup/common/config.h"
#include "lookup/suite/suite.h"
#include "lookup/suite/suite_app.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using namespace lookup::suite;

namespace {

const std::vector<std::string> kShare{LOOKUP_SOURCE_SHARE_DIR};

std::string writeSuite(const std::string& name, const std::string& text) {
    // One folder per test: ctest runs this binary's tests side by side, and a shared folder
    // emptied by one test's freshDir loses another's file.
    static const fs::path dir =
        lookup::test::freshDir(std::string("lookup_suite_options_") +
                               ::testing::UnitTest::GetInstance()->current_test_info()->name());
    const fs::path path = dir / (name + ".ini");
    std::ofstream(path) << text;
    return path.string();
}

std::string loadError(const std::string& name, const std::string& text) {
    try {
        SuiteOptions::fromFile(writeSuite(name, text), kShare);
    } catch (const lookup::common::ConfigError& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(SuiteSeeds, RangesAndListsAscendingWithoutRepeats) {
    EXPECT_EQ(parseSeeds("1-5"), (std::vector<std::uint64_t>{1, 2, 3, 4, 5}));
    EXPECT_EQ(parseSeeds("10,6,8-9,6"), (std::vector<std::uint64_t>{6, 8, 9, 10}));
    EXPECT_EQ(parseSeeds("7"), (std::vector<std::uint64_t>{7}));
    for (const char* bad : {"", "5-1", "a", "1-", "1,,2", "-3", "1.5", "2-x"}) {
        EXPECT_THROW(parseSeeds(bad), std::invalid_argument) << bad;
    }
}

TEST(SuiteOptions, ReadsConditionsOverridesAndFilesFromTheShareFolder) {
    const auto o = SuiteOptions::fromFile(writeSuite("good", R"([suite]
name = quick
seeds = 6-7
localize_ini = localize-mine-b.ini
max_frames = 40

[condition.ideal]
preset = mine-b-mini

[condition.fast]
preset = mine-b-mini
traverse_3.speed_kmh = 40
world.length_m = 30
)"),
                                          kShare);
    EXPECT_EQ(o.name, "quick");
    EXPECT_EQ(o.seeds, (std::vector<std::uint64_t>{6, 7}));
    EXPECT_EQ(o.max_frames, 40u);
    ASSERT_EQ(o.conditions.size(), 2u);
    EXPECT_EQ(o.conditions[0].name, "ideal");
    EXPECT_TRUE(o.conditions[0].overrides.empty());
    EXPECT_NE(o.conditions[0].localize_ini.find("localize-mine-b.ini"), std::string::npos);
    ASSERT_EQ(o.conditions[1].overrides.size(), 2u);
    EXPECT_EQ(o.conditions[1].overrides[0][0], "traverse_3");
    EXPECT_EQ(o.conditions[1].overrides[0][1], "speed_kmh");
    EXPECT_EQ(o.conditions[1].overrides[0][2], "40");
}

TEST(SuiteOptions, RefusesTyposNamingFileSectionAndKey) {
    // A scenario key that does not exist: refused at load, not hours later in a job.
    auto e =
        loadError("typo", "[suite]\n[condition.a]\npreset = mine-b-mini\nworld.lenght_m = 3\n");
    EXPECT_NE(e.find("typo.ini"), std::string::npos) << e;
    EXPECT_NE(e.find("lenght_m"), std::string::npos) << e;
    e = loadError("nodot", "[suite]\n[condition.a]\npreset = mine-b-mini\nspeed = 3\n");
    EXPECT_NE(e.find("[condition.a] speed"), std::string::npos) << e;
    e = loadError("section", "[suite]\n[conditions.a]\npreset = mine-b-mini\n");
    EXPECT_NE(e.find("[conditions.a]"), std::string::npos) << e;
    e = loadError("suitekey", "[suite]\nseed = 1\n[condition.a]\npreset = mine-b-mini\n");
    EXPECT_NE(e.find("seed"), std::string::npos) << e;
    e = loadError("preset", "[suite]\n[condition.a]\npreset = mine-z\n");
    EXPECT_NE(e.find("mine-z"), std::string::npos) << e;
    e = loadError("seeds", "[suite]\nseeds = 3-1\n[condition.a]\npreset = mine-b-mini\n");
    EXPECT_NE(e.find("[suite] seeds"), std::string::npos) << e;
    e = loadError("ini",
                  "[suite]\nlocalize_ini = nowhere.ini\n[condition.a]\npreset = mine-b-mini\n");
    EXPECT_NE(e.find("nowhere.ini"), std::string::npos) << e;
    e = loadError("empty", "[suite]\nname = x\n");
    EXPECT_NE(e.find("no [condition.NAME]"), std::string::npos) << e;
    // An impossible value is refused by the scenario's own checks.
    e = loadError("range",
                  "[suite]\n[condition.a]\npreset = mine-b-mini\ntraverse_3.speed_kmh = -4\n");
    EXPECT_NE(e.find("speed_kmh"), std::string::npos) << e;
}

TEST(SuiteOptions, ShippedSuitesLoad) {
    std::size_t count = 0;
    for (const auto& e : fs::directory_iterator(fs::path(LOOKUP_SOURCE_SHARE_DIR) / "suites")) {
        if (e.path().extension() != ".ini") continue;
        const auto o = SuiteOptions::fromFile(e.path().string(), kShare);
        EXPECT_FALSE(o.conditions.empty()) << e.path();
        EXPECT_FALSE(o.seeds.empty()) << e.path();
        ++count;
    }
    EXPECT_GE(count, 1u);
}

TEST(SuiteSummary, AggregatesRunsAndListsFailures) {
    SuiteOptions o;
    o.conditions.resize(1);
    o.conditions[0].name = "c";
    JobResult good;
    good.condition = "c";
    good.seed = 1;
    good.ok = true;
    lookup::eval::MethodResult a, b, coarse;
    a.method = b.method = "lookup-grid24";
    coarse.method = "coarse";
    coarse.error.mean_m = 1.5;
    a.acceptance_share = 0.8, b.acceptance_share = 0.6;
    a.error.mean_m = 0.02, b.error.mean_m = 0.04;
    a.error.max_m = 0.1, b.error.max_m = 0.3;
    a.first_fix_frame = 3, b.first_fix_frame = 9, b.first_fix_distance_m = 4.5;
    a.confident_wrong = 1, b.confident_wrong = 2;
    a.frames_per_s = 120, b.frames_per_s = 90;
    a.frame_ms_p99 = 20, b.frame_ms_p99 = 45;
    good.rows = {a, coarse, b};
    JobResult bad;
    bad.condition = "c";
    bad.seed = 2;
    bad.reason = "survey: no scans";
    const auto s = summarizeConditions(o, {good, bad});
    ASSERT_EQ(s.size(), 1u);
    EXPECT_EQ(s[0].jobs, 2u);
    EXPECT_EQ(s[0].failed, 1u);
    EXPECT_EQ(s[0].runs, 2u);
    EXPECT_DOUBLE_EQ(s[0].refined_share, 0.7);
    EXPECT_DOUBLE_EQ(s[0].mean_m, 0.03);
    EXPECT_DOUBLE_EQ(s[0].max_m, 0.3);
    EXPECT_DOUBLE_EQ(s[0].first_fix_frame_median, 6);
    EXPECT_DOUBLE_EQ(s[0].first_fix_frame_max, 9);
    EXPECT_DOUBLE_EQ(s[0].first_fix_distance_m_max, 4.5);
    EXPECT_EQ(s[0].confident_wrong, 3u);
    EXPECT_DOUBLE_EQ(s[0].frames_per_s_min, 90);
    EXPECT_DOUBLE_EQ(s[0].frame_ms_p99_max, 45);
    EXPECT_DOUBLE_EQ(s[0].coarse_mean_m, 1.5);
    ASSERT_EQ(s[0].failures.size(), 1u);
    EXPECT_NE(s[0].failures[0].find("seed 2: survey: no scans"), std::string::npos);
    // A run that never fixed makes the worst first fix "never", not a smaller number.
    good.rows[2].first_fix_frame = -1;
    EXPECT_LT(summarizeConditions(o, {good})[0].first_fix_frame_max, 0);
}

TEST(SuiteApp, BadFlagsAndSuiteFileTyposAreRefusedNamingThem) {
    const std::string good = writeSuite("app", "[suite]\n[condition.a]\npreset = mine-b-mini\n");
    const std::string typo =
        writeSuite("app_typo", "[suite]\n[condition.a]\npreset = mine-b-mini\nspeed = 3\n");
    for (const auto& [args, names] : std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"--suite", good, "--out", "o", "-j", "0"}, "--jobs must be >= 1"},
             {{"--suite", good, "--out", "o", "--seeds", "3-1"}, "3-1"},
             {{"--suite", typo, "--out", "o"}, typo + " [condition.a] speed"},
             {{"--suite", good}, "--out"}}) {
        SuiteApp app(kShare);
        const auto r = lookup::test::runApp("lookup-suite", app, args);
        EXPECT_EQ(r.code, 1) << names;
        EXPECT_NE(r.err.find(names), std::string::npos) << r.err;
        EXPECT_TRUE(app.results().empty());
    }
    SuiteApp app(kShare);
    std::vector<const char*> argv{"lookup-suite", "--suite", good.c_str(), "--out", "o",
                                  "--seeds",      "2,4"};
    ASSERT_TRUE(app.initialize(int(argv.size()), argv.data()));
    EXPECT_EQ(app.options().seeds, (std::vector<std::uint64_t>{2, 4}));
}

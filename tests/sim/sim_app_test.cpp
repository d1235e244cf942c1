// SimApp, the lookup-sim program as a class: its flags, a typo'd scenario refused naming the
// file, section and key, and a small dataset written.

#include <gtest/gtest.h>

#include <fstream>

#include "lookup/sim/sim_app.h"
#include "lookup/test/support.h"
#include "test_worlds.h"

namespace fs = std::filesystem;
using lookup::sim::ScenarioOptions;
using lookup::sim::SimApp;

namespace {

// The tiny scenario's mapping traverse alone: a dataset in about a second.
std::string writeTinyScenario(const fs::path& dir) {
    ScenarioOptions s = lookup::sim::testing::tinyScenario();
    s.traverses.resize(1);
    s.traverses[0].roles = "mapping,reference,query";
    const std::string path = (dir / "tiny.ini").string();
    std::ofstream(path) << s.toIniText();
    return path;
}

}  // namespace

TEST(SimApp, WritesTheDatasetOfAScenarioFile) {
    const auto dir = lookup::test::freshDir("lookup_sim_app_run");
    const std::string ini = writeTinyScenario(dir);
    SimApp app;
    const auto r = lookup::test::runApp(
        "lookup-sim", app,
        {"--scenario", ini, "--out", (dir / "data").string(), "--seed", "5", "-q"});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(app.options().seed, 5u);
    EXPECT_EQ(r.out.rfind("lookup-sim: tiny from " + ini + ", seed 5, route ", 0), 0u) << r.out;
    EXPECT_TRUE(fs::is_regular_file(dir / "data" / "dataset.ini"));
    EXPECT_TRUE(fs::is_regular_file(dir / "data" / "middle.rawlog"));
    EXPECT_EQ(app.result().traverses.size(), 1u);
}

TEST(SimApp, ScenarioTyposAreRefusedNamingFileSectionAndKey) {
    const auto dir = lookup::test::freshDir("lookup_sim_app_typo");
    const std::string ini = writeTinyScenario(dir);
    const std::string text = lookup::test::readText(ini);
    for (const auto& [extra, names] : std::vector<std::pair<std::string, std::string>>{
             {"\n[wrld]\nlength_m = 3\n", "[wrld]"},
             {"\n[world]\nlenght_m = 3\n", "[world] lenght_m"}}) {
        std::ofstream(ini) << text << extra;
        SimApp app;
        std::vector<const char*> argv{"lookup-sim", "--scenario", ini.c_str(), "--out", "x"};
        testing::internal::CaptureStderr();
        EXPECT_FALSE(app.initialize(int(argv.size()), argv.data()));
        const std::string err = testing::internal::GetCapturedStderr();
        EXPECT_EQ(app.exitCode(), 1);
        EXPECT_EQ(err.rfind("lookup-sim: " + ini, 0), 0u) << err;
        EXPECT_NE(err.find(names), std::string::npos) << err;
    }
}

TEST(SimApp, BadFlagsAreRefusedNamingThem) {
    for (const auto& [args, names] : std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"--out", "x"}, "give exactly one of --preset NAME or --scenario FILE.ini"},
             {{"--out", "x", "-p", "mine-a", "-s", "a.ini"}, "give exactly one of --preset"},
             {{"--out", "x", "--preset", "no-such-mine"}, "no-such-mine"},
             {{"--out", "x", "--seed", "-"}, "--seed"},
             {{"--preset", "mine-a"}, "--out"}}) {
        SimApp app({std::string(LOOKUP_SOURCE_SHARE_DIR) + "/scenarios"});
        const auto r = lookup::test::runApp("lookup-sim", app, args);
        EXPECT_EQ(r.code, 1) << names;
        EXPECT_NE(r.err.find(names), std::string::npos) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
}

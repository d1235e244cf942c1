#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lookup/suite/suite.h"
#include "lookup/suite/suite_app.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using namespace lookup::suite;

// Two conditions on a 30 m mine, one seed: one runs through every stage, the other fails in
// the localiser (bad options). The failure is a row with its step and reason; the good row's
// figures come from real survey, localisation and evaluation.
TEST(SuiteRun, OneConditionThroughEveryStageAndAFailedOneThatDoesNotStopTheSuite) {
    const fs::path dir = lookup::test::freshDir("lookup_suite_run");
    std::ofstream(dir / "broken-localize.ini") << "[localizer]\nno_such_key = 1\n";
    std::ofstream(dir / "quick.ini") << R"([suite]
name = quick
seeds = 1
localize_ini = localize-mine-b.ini
max_frames = 60

[condition.short-mine]
preset = mine-b-mini
world.length_m = 30

[condition.broken-options]
preset = mine-b-mini
world.length_m = 30
localize_ini = broken-localize.ini
)";
    // Through lookup-suite's App: exit code 2, some job failed.
    SuiteApp app({LOOKUP_SOURCE_SHARE_DIR});
    const auto run = lookup::test::runApp(
        "lookup-suite", app,
        {"--suite", (dir / "quick.ini").string(), "--out", (dir / "out").string(), "-j", "2"});
    EXPECT_EQ(run.code, 2) << run.err;
    const SuiteOptions& suite = app.options();
    const auto& results = app.results();
    ASSERT_EQ(results.size(), 2u) << run.out << run.err;
    EXPECT_NE(run.out.find("| short-mine | 1 |"), std::string::npos) << run.out;
    EXPECT_TRUE(results[0].ok) << results[0].reason;
    EXPECT_FALSE(results[1].ok);
    EXPECT_NE(results[1].reason.find("localise zigzag"), std::string::npos) << results[1].reason;
    EXPECT_NE(results[1].reason.find("no_such_key"), std::string::npos) << results[1].reason;

    const auto summaries = summarizeConditions(suite, results);
    ASSERT_EQ(summaries.size(), 2u);
    EXPECT_EQ(summaries[0].runs, 1u);
    EXPECT_GT(summaries[0].refined_share, 0.3);
    EXPECT_GE(summaries[0].first_fix_frame_max, 0);
    EXPECT_LT(summaries[0].mean_m, 0.3);
    EXPECT_EQ(summaries[0].confident_wrong, 0u);
    EXPECT_EQ(summaries[1].failed, 1u);

    std::ifstream md(dir / "out" / "suite.md");
    const std::string text((std::istreambuf_iterator<char>(md)), {});
    EXPECT_NE(text.find("| short-mine | 1 |"), std::string::npos) << text;
    EXPECT_NE(text.find("Failed: broken-options seed 1: localise zigzag"), std::string::npos)
        << text;
    std::ifstream js(dir / "out" / "suite.json");
    const auto j = nlohmann::json::parse(js);
    EXPECT_EQ(j.at("jobs").size(), 2u);
    EXPECT_EQ(j.at("conditions").at(0).at("condition"), "short-mine");
    EXPECT_TRUE(fs::exists(dir / "out/jobs/short-mine/seed-1/log.txt"));
}

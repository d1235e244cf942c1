// LocalizeApp, the lookup-localize program as a class: its flags into the request, the flags
// it refuses, a typo'd --ini refused naming the file, section and key, and a small run.

#include <gtest/gtest.h>

#include <fstream>

#include "localize_fixture.h"
#include "lookup/localize/localize_app.h"
#include "lookup/test/support.h"

using namespace lookup;
using namespace lookup::localize_testing;

namespace {

bool initialize(localize::LocalizeApp& app, std::vector<std::string> args, std::string* err) {
    args.insert(args.begin(), "lookup-localize");
    std::vector<const char*> argv;
    for (const auto& a : args) argv.push_back(a.c_str());
    testing::internal::CaptureStderr();
    const bool ok = app.initialize(int(argv.size()), argv.data());
    *err = testing::internal::GetCapturedStderr();
    return ok;
}

}  // namespace

TEST(LocalizeApp, FlagsFillTheRequest) {
    localize::LocalizeApp app;
    std::string err;
    ASSERT_TRUE(initialize(app, {"--db",       "D",
                                 "--rawlog",   "Q.rawlog",
                                 "--out",      "R",
                                 "--ini",      "I.ini",
                                 "--sampling", "heatmap",
                                 "--matcher",  "orb",
                                 "--realtime", "--max-frames",
                                 "7",          "--repeat",
                                 "2",          "--kidnap-every",
                                 "-3",         "--coarse-poses",
                                 "C.tum",      "--persist-fix",
                                 "F.json",     "--camera-clock",
                                 "K.json"},
                           &err))
        << err;
    const auto& r = app.request();
    EXPECT_EQ(r.db_dir, "D");
    EXPECT_EQ(r.rawlog, "Q.rawlog");
    EXPECT_EQ(r.out_dir, "R");
    EXPECT_EQ(r.ini_file, "I.ini");
    EXPECT_EQ(r.sampling, "heatmap");
    EXPECT_EQ(r.matcher, "orb");
    EXPECT_EQ(r.realtime, 1);
    EXPECT_EQ(r.max_frames, 7u);
    EXPECT_EQ(r.repeat, 2);
    EXPECT_EQ(r.kidnap_every, 0);  // negative: never
    EXPECT_EQ(r.coarse_poses, "C.tum");
    EXPECT_EQ(r.persist_fix, "F.json");
    EXPECT_EQ(r.camera_clock, "K.json");
    EXPECT_FALSE(app.live());
    EXPECT_EQ(app.exitCode(), 0);
}

TEST(LocalizeApp, BadFlagsAreRefusedNamingThem) {
    const std::vector<std::string> base{"--db", "D", "--out", "R"};
    struct Case {
        std::vector<std::string> extra;
        std::string names;
    };
    for (const Case& c : std::vector<Case>{
             {{"--rawlog", "Q", "--max-frames", "-1"}, "--max-frames -1: must be >= 0"},
             {{}, "give exactly one of --rawlog FILE or --live FILE.ini"},
             {{"--rawlog", "Q", "--live", "S.ini"}, "give exactly one of --rawlog"},
             {{"--rawlog", "Q", "--max-frame", "3"}, "--max-frame"},
             {{"--rawlog", "Q", "--repeat", "two"}, "--repeat"}}) {
        localize::LocalizeApp app;
        std::vector<std::string> args = base;
        args.insert(args.end(), c.extra.begin(), c.extra.end());
        std::string err;
        EXPECT_FALSE(initialize(app, args, &err)) << c.names;
        EXPECT_EQ(app.exitCode(), 1) << c.names;
        EXPECT_NE(err.find(c.names), std::string::npos) << err;
        EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;
    }
}

TEST(LocalizeApp, IniTyposAreRefusedNamingFileSectionAndKey) {
    const auto dir = test::freshDir("lookup_localize_app_ini");
    const std::string ini = (dir / "bad.ini").string();
    for (const auto& [text, names] : std::vector<std::pair<std::string, std::string>>{
             {"[refine.matchr]\nsearch_radius_px = 3\n", " [refine.matchr]: unknown section"},
             {"[localizer]\nrealtme = true\n", " [localizer] realtme: unknown key"}}) {
        std::ofstream(ini) << text;
        localize::LocalizeApp app;
        const auto r = test::runApp("lookup-localize", app,
                                    {"--db", (dir / "no-db").string(), "--rawlog", "Q.rawlog",
                                     "--out", (dir / "run").string(), "--ini", ini});
        EXPECT_EQ(r.code, 1) << r.err;
        EXPECT_NE(r.err.find("lookup-localize: " + ini + names), std::string::npos) << r.err;
    }
}

TEST(LocalizeApp, RunWritesTheRunFolderAndPrintsItsTiming) {
    const auto dir = test::freshDir("lookup_localize_app_run");
    const auto req = planarRun(
        dir, [](int, auto&, auto&) {}, 10);
    localize::LocalizeApp app;
    const auto r = test::runApp("lookup-localize", app, localizeArgs(req));
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_EQ(app.timing().frames, 10u);
    EXPECT_EQ(r.out.rfind("lookup-localize: 10 frames (0 dropped) in ", 0), 0u) << r.out;
    EXPECT_NE(r.out.find("-> " + req.out_dir + "\n"), std::string::npos) << r.out;
    for (const char* f : {"frames.csv", "poses.tum", "timing.json", "run.ini"}) {
        EXPECT_TRUE(fs::is_regular_file(fs::path(req.out_dir) / f)) << f;
    }
}

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "../common/round_trip.h"
#include "../localize/localize_fixture.h"
#include "lookup/place/place_app.h"
#include "lookup/place/place_index.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;

namespace {

// lookup-place's --ini: a typo'd section is refused before anything is built.
std::string initializeError(const std::string& ini_text, int& exit_code) {
    const fs::path dir = fs::temp_directory_path() / ("place_app_" + std::to_string(getpid()));
    fs::create_directories(dir);
    const std::string ini = (dir / "p.ini").string();
    std::ofstream(ini) << ini_text;
    lookup::place::PlaceApp app;
    const char* argv[] = {"lookup-place", "--db", "/nonexistent/db", "--ini", ini.c_str()};
    testing::internal::CaptureStderr();
    const bool ok = app.initialize(5, argv);
    std::string err = testing::internal::GetCapturedStderr();
    exit_code = ok ? 0 : app.exitCode();
    fs::remove_all(dir);
    const auto at = err.find(ini);
    return at == std::string::npos ? err : "FILE" + err.substr(at + ini.size());
}

}  // namespace

TEST(PlaceApp, IniSectionTypoIsRefusedNamingFileAndSection) {
    int code = 0;
    const std::string err =
        initializeError("[place_index]\nneighbours = 2\n[place_idx]\nneighbours = 3\n", code);
    EXPECT_NE(code, 0);
    EXPECT_EQ(err, "FILE [place_idx]: unknown section (known: place_index)\n");
}

TEST(PlaceApp, IniKeyTypoAndBadValueAreRefusedNamingFileSectionAndKey) {
    int code = 0;
    EXPECT_EQ(initializeError("[place_index]\nneighbors = 2\n", code),
              "FILE [place_index] neighbors: unknown key\n");
    EXPECT_NE(code, 0);
    EXPECT_EQ(initializeError("[place_index]\nfeatures = surf\n", code),
              "FILE [place_index] features: 'surf' is not one of orb, akaze, sift\n");
}

TEST(PlaceIndexOptions, SaveThenLoadGivesTheSameOptions) {
    lookup::place::PlaceIndexOptions o;
    o.features = lookup::place::FeatureType::Akaze;
    o.reference_spacing_m = 1.0 / 3.0;
    o.lsh_probe_level = 3;
    lookup::options_testing::expectRoundTrip(o, "place_index");
}

TEST(PlaceApp, BadFlagsAreRefusedOnOneLineNamingThem) {
    for (const auto& [args, names] : std::vector<std::pair<std::vector<std::string>, std::string>>{
             {{"--db", "D", "--evaluate", "Q.rawlog"}, "--evaluate needs --gt"},
             {{"--evaluate", "Q.rawlog"}, "--db"},
             {{"--db", "D", "--every", "often"}, "--every"}}) {
        lookup::place::PlaceApp app;
        const auto r = lookup::test::runApp("lookup-place", app, args);
        EXPECT_EQ(r.code, 1) << names;
        EXPECT_NE(r.err.find(names), std::string::npos) << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    }
}

TEST(PlaceApp, RunBuildsTheIndexIntoTheDatabase) {
    const auto dir = lookup::test::freshDir("lookup_place_app_run");
    const std::string db = (dir / "db").string();
    lookup::localize_testing::writeDatabase(lookup::localize_testing::Scene(), db,
                                            {{"survey", 20, 100.0}});
    lookup::place::PlaceApp app;
    const auto r = lookup::test::runApp("lookup-place", app, {"--db", db, "--quiet"});
    ASSERT_EQ(r.code, 0) << r.err;
    const std::string index = db + "/" + lookup::place::kPlaceIndexFile;
    EXPECT_EQ(r.out.rfind(index + ": ", 0), 0u) << r.out;
    EXPECT_NE(r.out.find(" of 20 references"), std::string::npos) << r.out;
    EXPECT_GT(fs::file_size(index), 1000u);
}

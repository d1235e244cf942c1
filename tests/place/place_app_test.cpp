#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include "../common/round_trip.h"
#include "lookup/place/place_app.h"
#include "lookup/place/place_index.h"

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

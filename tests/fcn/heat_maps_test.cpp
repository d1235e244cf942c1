// Heat maps are written in the localiser's format (database::loadHeatMap reads them back), db.ini
// lists them, a second run replaces them, and db.ini keeps every other line.

#include <gtest/gtest.h>

#include <fstream>
#include <opencv2/imgcodecs.hpp>

#include "fixture.h"
#include "lookup/database/heat_maps.h"
#include "lookup/database/manifest.h"
#include "lookup/database/reference_database.h"
#include "lookup/fcn/heat_maps.h"
#include "lookup/test/support.h"

using namespace lookup;
using namespace lookup::fcn;
namespace fs = std::filesystem;

namespace {}  // namespace

TEST(HeatMaps, WrittenInTheLocalisersFormatAndListedInDbIni) {
    const auto dir = lookup::test::freshDir("lookup_fcn_heat");
    const std::string db_dir = (dir / "db").string();
    fixture::writeDatabase(db_dir, {0.0, 0.5, 1.0});
    const std::string before = lookup::test::readText(fs::path(db_dir) / "db.ini");
    const HeatMapModel model(fixture::smallOptions().network, 5);
    {
        const auto db = database::ReferenceDatabase::load(db_dir);
        EXPECT_TRUE(db.info().heatmaps_dir.empty());
        std::size_t calls = 0;
        const auto w = writeHeatMaps(db, model, [&](std::size_t, std::size_t) { ++calls; });
        EXPECT_EQ(w.count, 3u);
        EXPECT_EQ(calls, 3u);
        EXPECT_FALSE(fs::exists(fs::path(db_dir) / (w.directory + ".tmp")));
    }
    const auto db = database::ReferenceDatabase::load(db_dir);
    ASSERT_FALSE(db.info().heatmaps_dir.empty());
    const std::string first_dir = db.info().heatmaps_dir;
    for (std::size_t i = 0; i < db.size(); ++i) {
        const fs::path file = fs::path(db_dir) / first_dir / database::heatMapFileName(i);
        // Stored at the network's resolution (input_scale 0.5), read back at the image's.
        const cv::Mat raw = cv::imread(file.string(), cv::IMREAD_UNCHANGED);
        const cv::Mat image = db.ceilingImage(i);
        ASSERT_EQ(raw.type(), CV_16UC1) << file;
        EXPECT_EQ(raw.size(), model.predictAtNetworkScale(image).size());
        EXPECT_EQ(raw.size(), cv::Size(image.cols / 2, image.rows / 2));
        const cv::Mat stored = database::loadHeatMap(db, i);
        const cv::Mat predicted = model.predict(image);
        ASSERT_EQ(stored.size(), predicted.size());
        EXPECT_LT(cv::norm(stored, predicted, cv::NORM_INF), 1.0 / 65535 + 1e-6);
    }
    // A heat map larger than the image is refused by name, not cropped or shrunk.
    {
        const auto db = database::ReferenceDatabase::load(db_dir);
        const fs::path file = fs::path(db_dir) / first_dir / database::heatMapFileName(1);
        const cv::Mat image = db.ceilingImage(1);
        ASSERT_TRUE(cv::imwrite(file.string(),
                                cv::Mat(image.rows + 2, image.cols, CV_16UC1, cv::Scalar(100))));
        try {
            database::loadHeatMap(db, 1);
            ADD_FAILURE() << "an oversized heat map was accepted";
        } catch (const std::runtime_error& e) {
            EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
            EXPECT_NE(std::string(e.what()).find("larger than"), std::string::npos) << e.what();
        }
    }
    // Every line of the survey's db.ini but the [heatmaps] directory is kept.
    const std::string after = lookup::test::readText(fs::path(db_dir) / "db.ini");
    EXPECT_EQ(after.size(), before.size() + first_dir.size());
    EXPECT_NE(after.find("directory = " + first_dir), std::string::npos);

    // A second run replaces the maps and removes the unreferenced folder.
    const auto w2 = writeHeatMaps(db, HeatMapModel(fixture::smallOptions().network, 6));
    EXPECT_NE(w2.directory, first_dir);
    EXPECT_FALSE(fs::exists(fs::path(db_dir) / first_dir));
    EXPECT_EQ(database::ReferenceDatabase::load(db_dir).info().heatmaps_dir, w2.directory);
}

TEST(HeatMaps, ChecksummedInTheirFolderAndADamagedOneRefusedByName) {
    const auto dir = lookup::test::freshDir("lookup_fcn_heat_crc");
    const std::string db_dir = (dir / "db").string();
    fixture::writeDatabase(db_dir, {0.0, 0.5});
    const std::string survey_manifest =
        lookup::test::readText(fs::path(db_dir) / database::kManifest);
    const auto w = writeHeatMaps(database::ReferenceDatabase::load(db_dir),
                                 HeatMapModel(fixture::smallOptions().network, 5));
    const fs::path heat = fs::path(db_dir) / w.directory;
    EXPECT_TRUE(fs::is_regular_file(heat / database::kManifest));
    EXPECT_EQ(lookup::test::readText(fs::path(db_dir) / database::kManifest), survey_manifest);
    ASSERT_NO_THROW(database::ReferenceDatabase::load(db_dir));
    const fs::path file = heat / database::heatMapFileName(1);
    std::string bytes = lookup::test::readText(file);
    bytes[bytes.size() / 2] ^= 0x04;
    std::ofstream(file, std::ios::binary) << bytes;
    try {
        database::ReferenceDatabase::load(db_dir);
        ADD_FAILURE() << "a damaged heat map was accepted";
    } catch (const database::DatabaseError& e) {
        EXPECT_NE(std::string(e.what()).find(file.string() + ": damaged"), std::string::npos)
            << e.what();
    }
}

TEST(HeatMaps, SetDirectoryAddsTheSectionWhenAbsentAndRefusesAMissingFile) {
    const auto dir = lookup::test::freshDir("lookup_fcn_heat_ini");
    const auto ini = dir / "db.ini";
    fixture::writeDatabase((dir / "db").string(), {0.0});
    // Strip the [heatmaps] section to simulate an older db.ini.
    std::string text = lookup::test::readText(dir / "db" / "db.ini");
    const auto at = text.find("[heatmaps]");
    ASSERT_NE(at, std::string::npos);
    text.replace(at, std::string("[heatmaps]\ndirectory = \n").size(), "");
    std::ofstream(ini) << text;
    setHeatMapsDirectory(ini.string(), "heatmaps_007");
    EXPECT_EQ(database::readDatabaseInfo(ini.string()).heatmaps_dir, "heatmaps_007");
    EXPECT_FALSE(fs::exists(dir / "db.ini.tmp"));
    try {
        setHeatMapsDirectory((dir / "nope.ini").string(), "x");
        FAIL();
    } catch (const std::runtime_error& e) {
        EXPECT_NE(std::string(e.what()).find("nope.ini"), std::string::npos);
    }
}

TEST(HeatMaps, EncodingSaturatesToSixteenBits) {
    cv::Mat heat = (cv::Mat_<float>(1, 4) << -0.5f, 0.f, 0.5f, 2.f);
    const cv::Mat e = database::encodeHeatMap(heat);
    ASSERT_EQ(e.type(), CV_16UC1);
    EXPECT_EQ(e.at<std::uint16_t>(0), 0);
    EXPECT_EQ(e.at<std::uint16_t>(1), 0);
    EXPECT_EQ(e.at<std::uint16_t>(2), 32768);
    EXPECT_EQ(e.at<std::uint16_t>(3), 65535);
}

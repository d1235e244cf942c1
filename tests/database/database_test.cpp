#include <gtest/gtest.h>
#include <mrpt/random/RandomGenerators.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "lookup/database/database_writer.h"
#include "lookup/database/reference_database.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using namespace lookup::database;

namespace {

mrpt::poses::CPose3D poseOf(int i) {
    // A winding path with a few revisits, so spatial and time order differ.
    return {std::cos(i * 0.37) * 5 + i * 0.1, std::sin(i * 0.53) * 3, 0, i * 0.05, 0, 0};
}

// Writes `n` references whose ceiling image i is filled with grey level i; with
// `superseded_every` > 0 every such reference is marked superseded by a drive "today".
void writeDatabase(const fs::path& out, int n, int superseded_every = 0,
                   std::optional<double> clock_sigma_s = std::nullopt) {
    DatabaseWriter w(out.string());
    mrpt::img::TCamera cam;
    cam.ncols = 16;
    cam.nrows = 12;
    cam.fx(321.5);
    cam.fy(321.5);
    for (int i = 0; i < n; ++i) {
        ReferenceInput in;
        in.traverse = i < n / 2 ? "a" : "b";
        in.ceiling = mrpt::obs::CObservationImage::Create();
        in.ceiling->sensorLabel = "CEILING_CAM";
        in.ceiling->timestamp = mrpt::Clock::fromDouble(100.0 + i * 0.5);
        in.ceiling->cameraPose = mrpt::poses::CPose3D(0.5, 0, 2, 0, 0, 0);
        in.ceiling->cameraParams = cam;
        in.ceiling->image.resize(16, 12, mrpt::img::CH_GRAY);
        in.ceiling->image.filledRectangle(0, 0, 15, 11, mrpt::img::TColor(i, i, i));
        if (i % 2 == 0) {
            in.forward = mrpt::obs::CObservationImage::Create();
            in.forward->sensorLabel = "FORWARD_CAM";
            in.forward->timestamp = mrpt::Clock::fromDouble(100.0 + i * 0.5 + 0.01);
            in.forward->image.resize(8, 6, mrpt::img::CH_GRAY);
            in.forward->image.filledRectangle(0, 0, 7, 5, mrpt::img::TColor(200, 200, 200));
        }
        in.vehicle_pose = poseOf(i);
        in.vehicle_cov.setIdentity();
        in.vehicle_cov *= 0.01 * (i + 1);
        in.forward_vehicle_pose = poseOf(i);
        in.sharpness = 100 + i;
        if (superseded_every > 0 && i % superseded_every == 0) in.superseded_by = "today";
        w.add(in);
    }
    DatabaseInfo info;
    info.name = "test";
    info.ceiling_camera = cam;
    info.ceiling_height_m = 4.5;
    info.source_rawlogs = {"/x/a.rawlog", "/x/b.rawlog"};
    info.ceiling_time_offset_sigma_s = clock_sigma_s;
    w.commit(info);
}

}  // namespace

TEST(Database, RoundTripPosesIntrinsicsAndLazyBoundedImages) {
    const auto dir = lookup::test::freshDir("lookup_database_roundtrip");
    writeDatabase(dir / "db", 40);
    auto db = ReferenceDatabase::load((dir / "db").string(), 5);
    ASSERT_EQ(db.size(), 40u);
    EXPECT_EQ(db.info().name, "test");
    EXPECT_DOUBLE_EQ(db.info().ceiling_camera.fx(), 321.5);
    EXPECT_DOUBLE_EQ(db.info().ceiling_height_m, 4.5);
    EXPECT_EQ(db.info().source_rawlogs.size(), 2u);
    EXPECT_EQ(db.imageDiskReads(), 0u);  // nothing read at load
    for (int i = 0; i < 40; ++i) {
        const auto& r = db.reference(i);
        EXPECT_EQ(r.id, static_cast<uint32_t>(i));
        EXPECT_EQ(r.traverse, i < 20 ? "a" : "b");
        EXPECT_NEAR((r.vehicle_pose.asVectorVal() - poseOf(i).asVectorVal()).norm(), 0, 1e-9);
        EXPECT_NEAR(r.vehicle_cov(1, 1), 0.01 * (i + 1), 1e-12);
        EXPECT_NEAR(r.ceiling_camera_pose.z(), 2.0, 1e-9);
        EXPECT_EQ(r.has_forward, i % 2 == 0);
        EXPECT_DOUBLE_EQ(r.sharpness, 100.0 + i);
        const cv::Mat img = db.ceilingImage(i);
        ASSERT_EQ(img.cols, 16);
        EXPECT_EQ(img.at<uint8_t>(5, 5), i);
        EXPECT_LE(db.imagesInMemory(), 5u);  // the cache bound holds
    }
    EXPECT_EQ(db.imageDiskReads(), 40u);
    db.ceilingImage(39);  // most recent: a cache hit
    EXPECT_EQ(db.imageDiskReads(), 40u);
    db.ceilingImage(0);  // evicted long ago: read again
    EXPECT_EQ(db.imageDiskReads(), 41u);
    EXPECT_EQ(db.forwardSequence().size(), 20u);
    EXPECT_EQ(db.forwardImage(0).cols, 8);
    EXPECT_TRUE(db.forwardImage(1).empty());
    EXPECT_TRUE(fs::exists(dir / "db" / "refs.tum"));
    EXPECT_FALSE(db.info().ceiling_time_offset_sigma_s);  // not recorded: unknown
}

TEST(Database, TheSurveyCameraClocksSigmaIsKept) {
    const auto dir = lookup::test::freshDir("lookup_database_clock_sigma");
    writeDatabase(dir / "db", 4, 0, 0.004);
    const auto info = readDatabaseInfo((dir / "db" / "db.ini").string());
    ASSERT_TRUE(info.ceiling_time_offset_sigma_s);
    EXPECT_DOUBLE_EQ(*info.ceiling_time_offset_sigma_s, 0.004);
}

TEST(Database, ImagesStoredAsTheGreyPixelsTheLocaliserReads) {
    // The survey's rawlogs may hold PNG, JPEG or colour images; the database keeps what the
    // localiser reads (8-bit grey) uncompressed, pixel for pixel, so nothing is lost and nothing
    // is decoded twice.
    const auto dir = lookup::test::freshDir("lookup_database_pgm");
    cv::Mat texture(24, 32, CV_8UC3);
    cv::randu(texture, 0, 255);
    cv::Mat expected_grey;
    cv::cvtColor(texture, expected_grey, cv::COLOR_BGR2GRAY);
    const fs::path png = dir / "colour.png";
    ASSERT_TRUE(cv::imwrite(png.string(), texture));
    const cv::Mat png_grey = cv::imread(png.string(), cv::IMREAD_GRAYSCALE);

    mrpt::img::TCamera cam;
    cam.ncols = 32;
    cam.nrows = 24;
    cam.fx(300);
    cam.fy(300);
    DatabaseWriter w((dir / "db").string());
    for (int i = 0; i < 2; ++i) {
        ReferenceInput in;
        in.traverse = "a";
        in.ceiling = mrpt::obs::CObservationImage::Create();
        in.ceiling->timestamp = mrpt::Clock::fromDouble(10.0 + i);
        in.ceiling->cameraParams = cam;
        if (i == 0) {
            in.ceiling->image.setExternalStorage(png.string());  // an external colour PNG
        } else {
            in.ceiling->image = mrpt::img::CImage(texture, mrpt::img::DEEP_COPY);  // in memory
        }
        in.vehicle_pose = poseOf(i);
        in.vehicle_cov.setIdentity();
        w.add(in);
    }
    DatabaseInfo info;
    info.ceiling_camera = cam;
    w.commit(info);

    auto db = ReferenceDatabase::load((dir / "db").string());
    for (int i = 0; i < 2; ++i) {
        EXPECT_EQ(fs::path(db.reference(i).ceiling_image_path).extension(), ".pgm");
        const cv::Mat stored = db.ceilingImage(i);
        ASSERT_EQ(stored.type(), CV_8UC1);
        const cv::Mat& want = i == 0 ? png_grey : expected_grey;
        EXPECT_EQ(cv::norm(stored, want, cv::NORM_INF), 0.0) << "reference " << i;
    }
    // A source image that cannot be read is a write error naming the target, not a hole.
    DatabaseWriter bad((dir / "db2").string());
    ReferenceInput in;
    in.ceiling = mrpt::obs::CObservationImage::Create();
    in.ceiling->cameraParams = cam;
    in.ceiling->image.setExternalStorage((dir / "missing.png").string());
    in.vehicle_cov.setIdentity();
    try {
        bad.add(in);
        FAIL() << "an unreadable source image was stored";
    } catch (const std::exception& e) {
        EXPECT_NE(std::string(e.what()).find("ceiling_000000.pgm"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("missing.png"), std::string::npos) << e.what();
    }
}

TEST(Database, SpatialAndTimeQueriesMatchBruteForce) {
    const auto dir = lookup::test::freshDir("lookup_database_queries");
    writeDatabase(dir / "db", 60);
    const auto db = ReferenceDatabase::load((dir / "db").string());
    auto& rng = mrpt::random::getRandomGenerator();
    rng.randomize(7);
    for (int q = 0; q < 50; ++q) {
        const mrpt::math::TPoint2D p(rng.drawUniform(-6, 12), rng.drawUniform(-4, 4));
        std::vector<std::pair<double, std::size_t>> brute;
        for (std::size_t i = 0; i < db.size(); ++i) {
            const auto& v = db.reference(i).vehicle_pose;
            brute.push_back({std::hypot(v.x() - p.x, v.y() - p.y), i});
        }
        std::sort(brute.begin(), brute.end());
        const auto k = db.nearest(p, 5);
        ASSERT_EQ(k.size(), 5u);
        for (int j = 0; j < 5; ++j) EXPECT_NEAR(k[j].distance, brute[j].first, 1e-9);
        // The cameras stand 0.5 m ahead of the vehicles, turned with them.
        std::vector<std::pair<double, std::size_t>> cameras;
        for (std::size_t i = 0; i < db.size(); ++i) {
            const auto c = db.reference(i).vehicle_pose + mrpt::poses::CPose3D(0.5, 0, 2, 0, 0, 0);
            cameras.push_back({std::hypot(c.x() - p.x, c.y() - p.y), i});
        }
        std::sort(cameras.begin(), cameras.end());
        const auto kc = db.nearestCameras(p, 5);
        ASSERT_EQ(kc.size(), 5u);
        for (int j = 0; j < 5; ++j) {
            EXPECT_EQ(kc[j].index, cameras[j].second);
            EXPECT_NEAR(kc[j].distance, cameras[j].first, 1e-9);
        }
        const double r = rng.drawUniform(0.5, 3);
        const auto within = db.withinRadius(p, r);
        const auto expected =
            std::count_if(brute.begin(), brute.end(), [&](const auto& b) { return b.first <= r; });
        EXPECT_EQ(static_cast<long>(within.size()), expected);
        for (const auto& n : within) EXPECT_LE(n.distance, r + 1e-9);

        const double t = rng.drawUniform(95, 135);
        std::vector<std::pair<double, std::size_t>> tb;
        for (std::size_t i = 0; i < db.size(); ++i) {
            tb.push_back({std::abs(db.reference(i).time_s - t), i});
        }
        std::sort(tb.begin(), tb.end());
        const auto kt = db.nearestInTime(t, 4);
        ASSERT_EQ(kt.size(), 4u);
        for (int j = 0; j < 4; ++j) EXPECT_NEAR(kt[j].distance, tb[j].first, 1e-9);
    }
    EXPECT_EQ(db.nearest(mrpt::math::TPoint2D(0, 0), 1000).size(), 60u);
}

// The localiser's online refresh: references added in memory are found by the spatial queries
// at once with their own image, the ones they supersede no longer; the folder is not written.
TEST(Database, ReferencesAddedInMemoryReplaceTheSupersededOnes) {
    const auto dir = lookup::test::freshDir("lookup_database_in_memory");
    writeDatabase(dir / "db", 20);
    auto db = ReferenceDatabase::load((dir / "db").string());
    const auto near = db.nearestCameras(mrpt::math::TPoint2D(3.0, 0.0), 1);
    ASSERT_EQ(near.size(), 1u);
    const std::size_t old = near[0].index;
    Reference added = db.reference(old);
    added.source = added.traverse = "online";
    const cv::Mat image(12, 16, CV_8UC1, cv::Scalar(77));
    db.addInMemory({{added, image}}, {old}, "online");

    EXPECT_EQ(db.size(), 21u);
    EXPECT_EQ(db.inMemoryCount(), 1u);
    EXPECT_EQ(db.reference(20).id, 20u);
    EXPECT_EQ(db.reference(old).superseded_by, "online");
    const auto now = db.nearestCameras(mrpt::math::TPoint2D(3.0, 0.0), 1);
    ASSERT_EQ(now.size(), 1u);
    EXPECT_EQ(now[0].index, 20u);
    EXPECT_EQ(db.nearest(db.reference(20).vehicle_pose, 1).at(0).index, 20u);
    EXPECT_EQ(db.ceilingImage(20).at<uchar>(5, 5), 77);
    for (const auto& n : db.withinRadius(mrpt::math::TPoint2D(3.0, 0.0), 100)) {
        EXPECT_NE(n.index, old);
    }
    EXPECT_EQ(ReferenceDatabase::load((dir / "db").string()).size(), 20u);
}

TEST(Database, UncommittedWriterLeavesNothingAndKeepsExistingDatabase) {
    const auto dir = lookup::test::freshDir("lookup_database_atomic");
    { DatabaseWriter w((dir / "fresh").string()); }  // e.g. a survey that threw
    EXPECT_FALSE(fs::exists(dir / "fresh"));
    writeDatabase(dir / "db", 4);
    {
        DatabaseWriter w((dir / "db").string());
        ReferenceInput in;
        in.ceiling = mrpt::obs::CObservationImage::Create();
        in.ceiling->image.resize(4, 4, mrpt::img::CH_GRAY);
        w.add(in);
    }  // destroyed before commit
    EXPECT_EQ(ReferenceDatabase::load((dir / "db").string()).size(), 4u);
    for (const auto& e : fs::directory_iterator(dir)) {
        EXPECT_EQ(e.path().filename().string().find(".tmp-"), std::string::npos);
    }
    writeDatabase(dir / "db", 6);  // a committed rerun replaces it
    EXPECT_EQ(ReferenceDatabase::load((dir / "db").string()).size(), 6u);
}

TEST(Database, MissingImageAndMissingFolderNamed) {
    const auto dir = lookup::test::freshDir("lookup_database_broken");
    writeDatabase(dir / "db", 3);
    fs::remove(dir / "db" / "refs_Images" / "ceiling_000001.pgm");
    try {
        ReferenceDatabase::load((dir / "db").string());
        FAIL() << "missing image accepted";
    } catch (const DatabaseError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("ceiling_000001.pgm"), std::string::npos) << m;
        EXPECT_NE(m.find("manifest.crc32"), std::string::npos) << m;
    }
    // Without the manifest (older databases) the record that refers to it is named.
    fs::remove(dir / "db" / "manifest.crc32");
    try {
        ReferenceDatabase::load((dir / "db").string());
        FAIL() << "missing image accepted";
    } catch (const DatabaseError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("ceiling_000001.pgm"), std::string::npos) << m;
        EXPECT_NE(m.find("refs.rawlog: record"), std::string::npos) << m;
    }
    EXPECT_THROW(ReferenceDatabase::load((dir / "nothing").string()), DatabaseError);
}

TEST(Database, SupersededReferencesAreKeptButNoSpatialQueryReturnsThem) {
    const auto dir = lookup::test::freshDir("lookup_database_superseded");
    writeDatabase(dir / "db", 60, 3);
    const auto db = ReferenceDatabase::load((dir / "db").string());
    ASSERT_EQ(db.size(), 60u);
    for (int i = 0; i < 60; ++i) {
        EXPECT_EQ(db.reference(i).current(), i % 3 != 0) << i;
        EXPECT_EQ(db.reference(i).superseded_by, i % 3 == 0 ? "today" : "");
    }
    auto& rng = mrpt::random::getRandomGenerator();
    rng.randomize(11);
    for (int q = 0; q < 30; ++q) {
        const mrpt::math::TPoint2D p(rng.drawUniform(-6, 12), rng.drawUniform(-4, 4));
        // Brute force over the current references only.
        std::vector<std::pair<double, std::size_t>> brute;
        for (std::size_t i = 0; i < db.size(); ++i) {
            if (i % 3 == 0) continue;
            const auto c = db.reference(i).ceiling_camera_pose;
            brute.push_back({std::hypot(c.x() - p.x, c.y() - p.y), i});
        }
        std::sort(brute.begin(), brute.end());
        const auto kc = db.nearestCameras(p, 4);
        ASSERT_EQ(kc.size(), 4u);
        for (int j = 0; j < 4; ++j) EXPECT_EQ(kc[j].index, brute[j].second);
        for (const auto& n : db.nearest(p, 10)) EXPECT_NE(n.index % 3, 0u);
        for (const auto& n : db.withinRadius(p, 3.0)) EXPECT_NE(n.index % 3, 0u);
    }
    EXPECT_EQ(db.nearest(mrpt::math::TPoint2D(0, 0), 1000).size(), 40u);
    // The time line is the survey's: a superseded reference is still found by its time.
    EXPECT_EQ(db.nearestInTime(100.0, 1).front().index, 0u);
}

// Fault injection into survey rawlogs: non-finite lidar and odometry values, unusable
// intrinsics, garbage and wrong-size images. Each must end as a counted, named skip or a clear
// refusal, never as a silently wrong database.
#include <gtest/gtest.h>

#include <algorithm>

#include <mrpt/config/CConfigFile.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>

#include <opencv2/imgcodecs.hpp>

#include "lookup/database/reference_database.h"
#include "lookup/survey/survey.h"
#include "lookup/test/support.h"
#include "survey_fixture.h"

namespace fs = std::filesystem;
using namespace lookup::survey;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

const mrpt::config::CConfigFile& shareIni() { return lookup::test::shareSurveyIni(); }

SurveyOptions shareOptions() {
    SurveyOptions o = lookup::test::shareSurveyOptions(true);
    // 80x60 fixture images are too small for the ceiling triples (tested in
    // no_ground_truth_test): the configured height, without its warning among these.
    o.ceiling_estimate = false;
    return o;
}

SurveyInputs inputsFor(const std::string& rawlog, const std::string& gt, const fs::path& out) {
    SurveyInputs in;
    TraverseSpec t;
    t.name = "corridor";
    t.rawlog = rawlog;
    t.ground_truth = gt;
    in.traverses.push_back(t);
    in.out_dir = out.string();
    return in;
}

// Copies `src` to `dst` (images stay where they are), `mutate` changing each record.
void rewriteRawlog(const std::string& src, const std::string& dst,
                   const std::function<void(std::size_t, mrpt::obs::CObservation&)>& mutate) {
    lookup::common::RawlogReader reader(src);
    lookup::common::RawlogWriter writer(dst);
    mrpt::obs::CObservation::Ptr o;
    for (std::size_t i = 0; reader.next(o); ++i) {
        mutate(i, *o);
        writer.write(*o);
    }
    writer.close();
}

}  // namespace

TEST(SurveyFault, NonFiniteLidarRangesLeaveReferencePosesAsAccurate) {
    const auto dir = lookup::test::freshDir("lookup_survey_fault_lidar");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 12.0);
    const auto clean =
        Survey(shareOptions(), shareIni()).run(inputsFor(f.rawlog, f.ground_truth, dir / "clean"));
    ASSERT_TRUE(clean.ok()) << clean.reason;

    const std::string bad = (dir / "nan.rawlog").string();
    std::size_t scans = 0;
    rewriteRawlog(f.rawlog, bad, [&](std::size_t, mrpt::obs::CObservation& o) {
        auto* scan = dynamic_cast<mrpt::obs::CObservation2DRangeScan*>(&o);
        if (!scan) return;
        ++scans;
        for (std::size_t i = 0; i < scan->getScanSize(); ++i) {
            if (scans == 40 || i % 7 == 0) scan->setScanRange(i, float(kNaN));
            if (i % 31 == 0) scan->setScanRange(i, std::numeric_limits<float>::infinity());
            if (i % 53 == 0) scan->setScanRange(i, -1.0f);
        }
        if (scans == 50) scan->aperture = float(kNaN);
        if (scans == 60) scan->maxRange = std::numeric_limits<float>::infinity();
        if (scans == 70) scan->sensorPose.x(kNaN);
    });
    const auto r =
        Survey(shareOptions(), shareIni()).run(inputsFor(bad, f.ground_truth, dir / "db"));
    ASSERT_TRUE(r.ok()) << r.reason;
    const auto& t = r.traverses.at(0);
    EXPECT_EQ(t.skipped.scans, 4u);  // all-NaN ranges, NaN aperture, inf maxRange, NaN pose
    EXPECT_GT(t.skipped.lidar_ranges, 30 * scans);
    // Among the warnings (the fixture's tiny images also leave the camera time offset
    // unestimated): the refused lidar data, naming the rawlog.
    const auto named = std::find_if(r.warnings.begin(), r.warnings.end(), [](const auto& w) {
        return w.find("nan.rawlog") != std::string::npos;
    });
    EXPECT_NE(named, r.warnings.end());
    EXPECT_NE(r.toJson().find("\"lidar_ranges\": " + std::to_string(t.skipped.lidar_ranges)),
              std::string::npos);
    // As accurate as without them (the survey took 0.9 m off before they were refused).
    const auto& c = clean.traverses.at(0);
    EXPECT_LT(t.error.max_m, c.error.max_m + 0.05) << "clean max " << c.error.max_m;
    EXPECT_LT(t.error.mean_m, c.error.mean_m + 0.02) << "clean mean " << c.error.mean_m;
    EXPECT_LT(t.error.max_m, 0.5);
}

TEST(SurveyFault, NonFiniteOdometryRecordsSkippedAndCounted) {
    const auto dir = lookup::test::freshDir("lookup_survey_fault_odometry");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 10.0);
    const std::string bad = (dir / "nan.rawlog").string();
    std::size_t odometry = 0;
    rewriteRawlog(f.rawlog, bad, [&](std::size_t, mrpt::obs::CObservation& o) {
        auto* odo = dynamic_cast<mrpt::obs::CObservationOdometry*>(&o);
        if (!odo) return;
        ++odometry;
        if (odometry == 30) odo->odometry.x(kNaN);
        if (odometry == 50) odo->odometry.phi(std::numeric_limits<double>::infinity());
        if (odometry == 70) {
            odo->hasVelocities = true;
            odo->velocityLocal.vx = kNaN;
        }
    });
    const auto r =
        Survey(shareOptions(), shareIni()).run(inputsFor(bad, f.ground_truth, dir / "db"));
    ASSERT_TRUE(r.ok()) << r.reason;
    EXPECT_EQ(r.traverses.at(0).skipped.odometry, 3u);
    EXPECT_LT(r.traverses.at(0).error.max_m, 0.3);
    // The database must outlive the loop: a range-for over a temporary's member dangles.
    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    for (const auto& ref : db.references()) {
        ASSERT_TRUE(std::isfinite(ref.vehicle_pose.x()) && std::isfinite(ref.vehicle_pose.yaw()));
    }
}

// An inclinometer reading beside every odometry record, level (the fixture's corridor is flat),
// some without a finite pitch or without a roll: those are counted and skipped, the rest level
// the drive, which must come out as accurate as without them.
TEST(SurveyFault, InclinometerReadingsWithoutAFinitePitchAndRollSkippedAndCounted) {
    const auto dir = lookup::test::freshDir("lookup_survey_fault_imu");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 10.0);
    const std::string with_imu = (dir / "imu.rawlog").string();
    std::size_t readings = 0;
    {
        lookup::common::RawlogReader reader(f.rawlog);
        lookup::common::RawlogWriter writer(with_imu);
        mrpt::obs::CObservation::Ptr o;
        while (reader.next(o)) {
            writer.write(*o);
            if (!std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) continue;
            mrpt::obs::CObservationIMU imu;
            imu.sensorLabel = "IMU";
            imu.timestamp = o->timestamp;
            ++readings;
            imu.set(mrpt::obs::IMU_PITCH, readings == 20 ? kNaN : 0.002);
            if (readings != 40) imu.set(mrpt::obs::IMU_ROLL, -0.001);
            writer.write(imu);
        }
        writer.close();
    }
    const auto r =
        Survey(shareOptions(), shareIni()).run(inputsFor(with_imu, f.ground_truth, dir / "db"));
    ASSERT_TRUE(r.ok()) << r.reason;
    const TraverseReport& t = r.traverses.at(0);
    EXPECT_EQ(t.skipped.imu, 2u);
    EXPECT_NE(t.skipped.first.find("IMU: no finite pitch and roll"), std::string::npos)
        << t.skipped.first;
    EXPECT_EQ(t.levelling.imu_records, readings - 2);
    EXPECT_GT(t.levelling.odometry_levelled, readings / 2);
    EXPECT_GT(t.levelling.scans_levelled, 10u);
    EXPECT_NEAR(t.levelling.levelled_m, t.levelling.odometry_m, 1e-3 * t.levelling.odometry_m);
    EXPECT_LT(t.error.max_m, 0.3);
}

TEST(SurveyFault, UnusableIntrinsicsRefused) {
    const auto dir = lookup::test::freshDir("lookup_survey_fault_intrinsics");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 4.0);
    const std::string some = (dir / "some.rawlog").string();
    std::size_t images = 0, broken = 0;
    rewriteRawlog(f.rawlog, some, [&](std::size_t, mrpt::obs::CObservation& o) {
        auto* img = dynamic_cast<mrpt::obs::CObservationImage*>(&o);
        if (!img) return;
        ++images;
        if (images % 5 == 0) img->cameraParams.fx(kNaN);
        if (images % 5 == 1) img->cameraParams.fy(0);
        if (images % 5 == 2) img->cameraParams.fx(-40);
        broken += images % 5 <= 2 ? 1 : 0;
    });
    auto in = inputsFor(some, f.ground_truth, dir / "db");
    in.poses_file = kPosesFromGroundTruth;
    const auto r = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_TRUE(r.ok()) << r.reason;
    const auto& s = r.traverses.at(0).skipped;
    EXPECT_GT(s.ceiling_intrinsics, 0u);
    EXPECT_GT(s.forward_intrinsics, 0u);
    EXPECT_EQ(s.ceiling_intrinsics + s.forward_intrinsics, broken);
    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    EXPECT_DOUBLE_EQ(db.info().ceiling_camera.fx(), 40.0);
    EXPECT_GT(db.info().forward_camera.fx(), 0.0);

    // Every ceiling image unusable: a clear refusal naming the rawlog, no database.
    const std::string all = (dir / "all.rawlog").string();
    rewriteRawlog(f.rawlog, all, [&](std::size_t, mrpt::obs::CObservation& o) {
        if (auto* img = dynamic_cast<mrpt::obs::CObservationImage*>(&o)) img->cameraParams.fx(0);
    });
    in = inputsFor(all, f.ground_truth, dir / "db2");
    in.poses_file = kPosesFromGroundTruth;
    const auto refused = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(refused.ok());
    EXPECT_NE(refused.reason.find("all.rawlog"), std::string::npos) << refused.reason;
    EXPECT_NE(refused.reason.find("focal length"), std::string::npos) << refused.reason;
    EXPECT_FALSE(fs::exists(dir / "db2"));
}

TEST(SurveyFault, GarbageEmptyAndWrongSizeImagesRefused) {
    const auto dir = lookup::test::freshDir("lookup_survey_fault_images");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 4.0);
    const fs::path images = dir / "corridor_Images";
    for (int k = 0; k < f.frames; k += 3) {
        std::ofstream(images / ("CEILING_CAM_" + std::to_string(k) + ".png"), std::ios::binary)
            << "\x89PNG garbage, not an image";
        std::ofstream(images / ("FORWARD_CAM_" + std::to_string(k + 1) + ".png"));  // empty
    }
    cv::imwrite((images / "CEILING_CAM_1.png").string(), cv::Mat(30, 40, CV_8UC1, 128));
    cv::imwrite((images / "FORWARD_CAM_2.png").string(), cv::Mat(24, 32, CV_16UC1, 128));
    auto in = inputsFor(f.rawlog, f.ground_truth, dir / "db");
    in.poses_file = kPosesFromGroundTruth;
    const auto r = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_TRUE(r.ok()) << r.reason;
    const auto& t = r.traverses.at(0);
    EXPECT_GT(t.rejected_image, 0u);
    EXPECT_GT(t.rejected_forward, 0u);
    EXPECT_FALSE(t.first_image_problem.empty());
    ASSERT_FALSE(r.warnings.empty());
    EXPECT_NE(r.warnings.back().find("CEILING_CAM_"), std::string::npos) << r.warnings.back();
    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    ASSERT_GT(db.size(), 5u);
    for (std::size_t i = 0; i < db.size(); ++i) {
        const cv::Mat c = cv::imread(db.reference(i).ceiling_image_path, cv::IMREAD_UNCHANGED);
        ASSERT_EQ(c.cols, 80) << db.reference(i).ceiling_image_path;
        ASSERT_EQ(c.rows, 60);
        if (!db.reference(i).has_forward) continue;
        const cv::Mat fw = cv::imread(db.reference(i).forward_image_path, cv::IMREAD_UNCHANGED);
        ASSERT_EQ(fw.cols, 32) << db.reference(i).forward_image_path;
        ASSERT_EQ(fw.depth(), CV_8U);
    }
}

TEST(SurveyFault, TwoTraversesOfOneNameAreRefusedNamingBothRawlogs) {
    const auto dir = lookup::test::freshDir("lookup_survey_fault_names");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 4.0);
    const std::string copy = (dir / "copy.rawlog").string();
    rewriteRawlog(f.rawlog, copy, [](std::size_t, mrpt::obs::CObservation&) {});
    auto in = inputsFor(f.rawlog, f.ground_truth, dir / "db");
    TraverseSpec again = in.traverses.front();
    again.rawlog = copy;
    in.traverses.push_back(again);
    in.poses_file = kPosesFromGroundTruth;
    const auto r = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(r.ok());
    EXPECT_NE(r.reason.find("'corridor'"), std::string::npos) << r.reason;
    EXPECT_NE(r.reason.find("copy.rawlog"), std::string::npos) << r.reason;
    EXPECT_NE(r.reason.find(f.rawlog), std::string::npos) << r.reason;
    EXPECT_FALSE(fs::exists(dir / "db"));
}

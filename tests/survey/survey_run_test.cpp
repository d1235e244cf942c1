#include <gtest/gtest.h>

#include <mrpt/config/CConfigFile.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/obs/CObservationImage.h>
#include <algorithm>
#include <cmath>

#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "lookup/database/reference_database.h"
#include "lookup/survey/survey.h"
#include "lookup/test/support.h"
#include "survey_fixture.h"

namespace fs = std::filesystem;
using namespace lookup::survey;

namespace {

const mrpt::config::CConfigFile& shareIni() { return lookup::test::shareSurveyIni(); }

SurveyOptions shareOptions() { return lookup::test::shareSurveyOptions(true); }

SurveyInputs inputsFor(const lookup::test::Fixture& f, const fs::path& out) {
    SurveyInputs in;
    TraverseSpec t;
    t.name = "corridor";
    t.rawlog = f.rawlog;
    t.ground_truth = f.ground_truth;
    in.traverses.push_back(t);
    in.out_dir = out.string();
    return in;
}

bool noStagingLeft(const fs::path& dir) {
    for (const auto& e : fs::directory_iterator(dir)) {
        const auto n = e.path().filename().string();
        if (n.find(".tmp-") != std::string::npos || n.find(".old-") != std::string::npos) {
            return false;
        }
    }
    return true;
}

}  // namespace

TEST(SurveyRun, PoseFileGivesCameraPosesEqualToTruthComposedWithMount) {
    const auto dir = lookup::test::freshDir("lookup_survey_posefile");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 10.0);
    auto in = inputsFor(f, dir / "db");
    in.poses_file = f.ground_truth;
    const auto result = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_TRUE(result.ok()) << result.reason;

    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    ASSERT_EQ(db.size(), result.references);
    // 10 m at 0.25 m spacing, some due frames blurred: between 20 and 41 references.
    EXPECT_GE(db.size(), 20u);
    EXPECT_LE(db.size(), 41u);
    EXPECT_GT(result.traverses.at(0).rejected_blur, 0u);
    // Said, not only counted: a survey that skips frames tells which setting skipped them.
    const std::string skipped = "skipped " + std::to_string(result.traverses.at(0).rejected_blur) +
                                " ceiling keyframes (" +
                                std::to_string(result.traverses.at(0).rejected_blur) + " blurred";
    EXPECT_TRUE(std::any_of(result.warnings.begin(), result.warnings.end(),
                            [&](const std::string& w) { return w.find(skipped) != w.npos; }))
        << skipped;
    EXPECT_DOUBLE_EQ(db.info().ceiling_camera.fx(), 40.0);
    EXPECT_TRUE(fs::exists(dir / "db" / "refs.tum"));
    EXPECT_TRUE(fs::exists(dir / "db" / "survey_report.json"));
    const auto gt =
        lookup::common::makeInterpolator(lookup::common::readPoseFile(f.ground_truth), 1.0);
    for (const auto& r : db.references()) {
        mrpt::poses::CPose3D truth;
        bool valid = false;
        gt.interpolate(mrpt::Clock::fromDouble(r.time_s), truth, valid);
        ASSERT_TRUE(valid);
        const auto expected = truth + f.ceiling_mount;
        EXPECT_NEAR((r.ceiling_camera_pose.asVectorVal() - expected.asVectorVal()).norm(), 0, 1e-6)
            << "reference " << r.id;
        EXPECT_GE(r.sharpness, shareOptions().min_sharpness);  // no blurred reference
        EXPECT_TRUE(r.has_forward);
        EXPECT_NEAR(r.forward_time_s - r.time_s, 0.02, 1e-3);
    }
    // Reported error against the same truth is zero.
    EXPECT_LT(result.traverses.at(0).error.max_m, 1e-6);
}

// The survey camera's lens carries a blotch of dust (letting 35 % of the light through at its
// middle): found in the mean of the traverse's references and divided out of them before they
// are stored, said in the report and a warning. A clean lens is left alone.
TEST(SurveyRun, DirtOnTheSurveyCamerasLensIsDividedOutOfTheReferences) {
    const auto dir = lookup::test::freshDir("lookup_survey_dirty_lens");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 20.0);
    const cv::Rect blotch(18, 20, 12, 12);
    cv::Mat transmission(60, 80, CV_32F);
    for (int v = 0; v < 60; ++v) {
        for (int u = 0; u < 80; ++u) {
            const double d2 = (std::pow(u - 24, 2) + std::pow(v - 26, 2)) / (12.0 * 12.0);
            transmission.at<float>(v, u) = static_cast<float>(1 - 0.65 * std::exp(-d2));
        }
    }
    // Inside the blotch against the same pixels' mean over every image, as a share.
    const auto blotchShare = [&](const std::vector<cv::Mat>& images) {
        double inside = 0, all = 0;
        for (const auto& m : images) {
            inside += cv::mean(m(blotch))[0];
            all += cv::mean(m)[0];
        }
        return inside / all;
    };
    const auto clean = Survey(shareOptions(), shareIni()).run(inputsFor(f, dir / "clean"));
    ASSERT_TRUE(clean.ok()) << clean.reason;
    EXPECT_FALSE(clean.traverses.at(0).lens.corrected);
    EXPECT_GT(clean.traverses.at(0).lens.images, 40u);
    std::vector<cv::Mat> dirty_images;
    for (const auto& e : fs::directory_iterator(dir / "corridor_Images")) {
        const std::string path = e.path().string();
        if (path.find("CEILING_CAM") == std::string::npos) continue;
        cv::Mat image;
        cv::imread(path, cv::IMREAD_GRAYSCALE).convertTo(image, CV_32F);
        cv::Mat(image.mul(transmission)).convertTo(image, CV_8U);
        cv::imwrite(path, image);
        dirty_images.push_back(image);
    }
    const auto dirty = Survey(shareOptions(), shareIni()).run(inputsFor(f, dir / "db"));
    ASSERT_TRUE(dirty.ok()) << dirty.reason;
    const auto& lens = dirty.traverses.at(0).lens;
    EXPECT_TRUE(lens.corrected);
    EXPECT_LT(lens.least_transmission, 0.6);
    EXPECT_TRUE(std::any_of(dirty.warnings.begin(), dirty.warnings.end(), [](const std::string& w) {
        return w.find("lens is dirty") != w.npos;
    }));
    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    std::vector<cv::Mat> stored;
    for (std::size_t i = 0; i < db.size(); ++i) stored.push_back(db.ceilingImage(i));
    EXPECT_LT(blotchShare(dirty_images), 0.7);
    EXPECT_NEAR(blotchShare(stored), 1.0, 0.12);
}

TEST(SurveyRun, DeskewedScansAreCountedInTheReport) {
    const auto dir = lookup::test::freshDir("lookup_survey_deskew_count");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 6.0);
    auto in = inputsFor(f, dir / "db");
    in.poses_file = f.ground_truth;
    const auto plain = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_TRUE(plain.ok()) << plain.reason;
    EXPECT_EQ(plain.traverses.at(0).scans_deskewed, 0u);
    SurveyOptions o = shareOptions();
    o.lidar_sweep_ms = 50;
    in.out_dir = (dir / "db2").string();
    const auto swept = Survey(o, shareIni()).run(in);
    ASSERT_TRUE(swept.ok()) << swept.reason;
    const auto deskewed = swept.traverses.at(0).scans_deskewed;
    EXPECT_GT(deskewed, 10u);
    EXPECT_NE(swept.toJson().find("\"scans_deskewed\": " + std::to_string(deskewed)),
              std::string::npos)
        << swept.toJson();
}

TEST(SurveyRun, PosesFromEachTraverseGroundTruth) {
    const auto dir = lookup::test::freshDir("lookup_survey_posesgt");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 4.0);
    auto in = inputsFor(f, dir / "db");
    in.poses_file = kPosesFromGroundTruth;
    const auto result = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_TRUE(result.ok()) << result.reason;
    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    const auto gt =
        lookup::common::makeInterpolator(lookup::common::readPoseFile(f.ground_truth), 1.0);
    ASSERT_GT(db.size(), 5u);
    for (const auto& r : db.references()) {
        mrpt::poses::CPose3D truth;
        bool valid = false;
        gt.interpolate(mrpt::Clock::fromDouble(r.time_s), truth, valid);
        ASSERT_TRUE(valid);
        EXPECT_NEAR((r.vehicle_pose.asVectorVal() - truth.asVectorVal()).norm(), 0, 1e-6);
    }

    // A traverse without ground truth cannot use it: refused, naming the rawlog.
    in.traverses.at(0).ground_truth.clear();
    in.out_dir = (dir / "db2").string();
    const auto refused = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(refused.ok());
    EXPECT_NE(refused.reason.find("corridor.rawlog"), std::string::npos) << refused.reason;
    EXPECT_FALSE(fs::exists(dir / "db2"));
}

TEST(SurveyRun, LaserPathPosesCloseToTruth) {
    const auto dir = lookup::test::freshDir("lookup_survey_laser");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 12.0);
    const auto result = Survey(shareOptions(), shareIni()).run(inputsFor(f, dir / "db"));
    ASSERT_TRUE(result.ok()) << result.reason;
    const auto& t = result.traverses.at(0);
    ASSERT_TRUE(t.has_ground_truth);
    EXPECT_GT(t.error.count, 30u);
    // A straight corridor leaves the along-track position weakly observed (the degeneracy the
    // issue mentions): only bound it; the cross-track position is observable and must be tight.
    EXPECT_LT(t.error.max_m, 0.50) << result.toJson();
    EXPECT_LT(t.error.mean_yaw_deg, 1.0) << result.toJson();
    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    double cross = 0;
    for (const auto& r : db.references()) {
        cross += std::abs(r.vehicle_pose.y() - lookup::test::truePoseAt(r.time_s - 1.7e9).y());
    }
    EXPECT_LT(cross / db.size(), 0.05);
    // Stored covariances carry the map's own error on top of the graph's marginal covariance.
    const double map_var = std::pow(shareOptions().map_std_xy_m, 2);
    ASSERT_GT(map_var, 0.0);
    for (const auto& r : db.references()) {
        EXPECT_GE(r.vehicle_cov(0, 0), map_var * (1 - 1e-9));
        EXPECT_GE(r.vehicle_cov(1, 1), map_var * (1 - 1e-9));
    }
    EXPECT_TRUE(fs::exists(dir / "db" / "map.gridmap.gz"));
    EXPECT_TRUE(fs::exists(dir / "db" / "map.png"));
}

// The start pose's heading error turns the whole map about the start: every reference's
// covariance carries it as the lever from the start, turned by 90 deg, times that error.
TEST(SurveyRun, TheStartPoseErrorIsARigidErrorInEveryCovariance) {
    const auto dir = lookup::test::freshDir("lookup_survey_start_std");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 12.0);
    const auto covariances = [&](double std_xy_m, double std_yaw_deg, const std::string& name) {
        auto o = shareOptions();
        o.start_pose = "0 0 5.7106";
        o.start_pose_std_xy_m = std_xy_m;
        o.start_pose_std_yaw_deg = std_yaw_deg;
        const auto result = Survey(o, shareIni()).run(inputsFor(f, dir / name));
        EXPECT_TRUE(result.ok()) << result.reason;
        return lookup::database::ReferenceDatabase::load((dir / name).string());
    };
    const auto exact = covariances(0, 0, "exact");
    const auto uncertain = covariances(0.05, 1.0, "uncertain");
    ASSERT_EQ(exact.size(), uncertain.size());
    ASSERT_GT(exact.size(), 30u);
    const double syaw2 = std::pow(mrpt::DEG2RAD(1.0), 2);
    for (std::size_t i = 0; i < exact.size(); ++i) {
        const auto& a = exact.reference(i);
        const auto& b = uncertain.reference(i);
        ASSERT_EQ(a.vehicle_pose.x(), b.vehicle_pose.x()) << i;
        const double x = b.vehicle_pose.x(), y = b.vehicle_pose.y();
        EXPECT_NEAR(b.vehicle_cov(0, 0) - a.vehicle_cov(0, 0), 0.0025 + syaw2 * y * y, 1e-6) << i;
        EXPECT_NEAR(b.vehicle_cov(1, 1) - a.vehicle_cov(1, 1), 0.0025 + syaw2 * x * x, 1e-6) << i;
        EXPECT_NEAR(b.vehicle_cov(2, 2) - a.vehicle_cov(2, 2), syaw2, 1e-9) << i;
    }
}

// A start mark's heading error turns the whole map about the start. A second mark where the
// drive ends turns it back (the map's shape is the laser's); one that disagrees with the map
// beyond both marks' uncertainty is reported and not used.
TEST(SurveyRun, AnEndMarkTurnsTheMapBackOntoBothMarks) {
    const auto dir = lookup::test::freshDir("lookup_survey_end_mark");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 12.0);
    const auto run = [&](const std::string& end_pose, const std::string& name,
                         double start_std_yaw_deg = 2.0) {
        auto o = shareOptions();
        o.start_pose = "0 0 7.7106";  // the truth's heading is 5.7106 deg
        o.start_pose_std_yaw_deg = start_std_yaw_deg;
        o.end_pose = end_pose;
        o.end_pose_std_xy_m = 0.3;  // the fixture's map is 0.3 m long at its end, see below
        o.end_pose_std_yaw_deg = 0.5;
        auto result = Survey(o, shareIni()).run(inputsFor(f, dir / name));
        EXPECT_TRUE(result.ok()) << result.reason;
        return std::make_pair(result,
                              lookup::database::ReferenceDatabase::load((dir / name).string()));
    };
    // Worst position error and mean heading error of the references against the truth.
    const auto errors = [](const lookup::database::ReferenceDatabase& db) {
        double worst = 0, heading = 0;
        for (const auto& r : db.references()) {
            const auto truth = lookup::test::truePoseAt(r.time_s - 1.7e9);
            worst = std::max(
                worst, std::hypot(r.vehicle_pose.x() - truth.x(), r.vehicle_pose.y() - truth.y()));
            heading += std::abs(mrpt::math::wrapToPi(r.vehicle_pose.yaw() - truth.phi()));
        }
        return std::make_pair(worst, mrpt::RAD2DEG(heading / db.size()));
    };
    const mrpt::poses::CPose2D end = lookup::test::truePoseAt(12.0);  // the last scan
    const std::string end_text = std::to_string(end.x()) + " " + std::to_string(end.y()) + " " +
                                 std::to_string(mrpt::RAD2DEG(end.phi()));
    const auto [start_result, start_only] = run("", "start_only");
    const auto [end_result, both] = run(end_text, "both");
    const auto [wrong_result, wrong] = run("14 2 0", "wrong");

    EXPECT_FALSE(start_result.end_mark.given);
    EXPECT_GT(errors(start_only).second, 1.5);
    EXPECT_TRUE(end_result.end_mark.used);
    EXPECT_NEAR(mrpt::RAD2DEG(end_result.end_mark.correction.phi()), -2.0, 0.4);
    EXPECT_LT(errors(both).second, 0.3);
    // The fixture's map is also stretched along its straight corridor (odometry scale, which
    // the scans hardly see): that part of the end's error is the map's, not the frame's.
    EXPECT_LT(errors(both).first, 0.7 * errors(start_only).first);
    // What is left of the frame's error is smaller, and every covariance says so at the far
    // end.
    EXPECT_LT(end_result.end_mark.std_yaw_deg, 0.5);
    ASSERT_EQ(both.size(), start_only.size());
    const std::size_t last = both.size() - 1;
    EXPECT_LT(both.reference(last).vehicle_cov(1, 1),
              0.2 * start_only.reference(last).vehicle_cov(1, 1));

    EXPECT_TRUE(wrong_result.end_mark.given);
    EXPECT_FALSE(wrong_result.end_mark.used);
    EXPECT_GT(wrong_result.end_mark.disagreement_m, 1.5);
    const auto& warnings = wrong_result.warnings;
    EXPECT_TRUE(std::any_of(warnings.begin(), warnings.end(), [](const std::string& w) {
        return w.find("end_pose '14 2 0'") != std::string::npos &&
               w.find("not used") != std::string::npos;
    }));
    ASSERT_EQ(wrong.size(), start_only.size());
    for (std::size_t i = 0; i < wrong.size(); ++i) {
        EXPECT_EQ(wrong.reference(i).vehicle_pose.y(), start_only.reference(i).vehicle_pose.y())
            << i;
    }

    // A start given as exact holds the frame where it is, whatever the end mark says.
    const auto exact_start = run(end_text, "exact_start", 0.0).second;
    ASSERT_EQ(exact_start.size(), start_only.size());
    EXPECT_NEAR(exact_start.reference(last).vehicle_pose.y(),
                start_only.reference(last).vehicle_pose.y(), 1e-4);
}

// Marks along the drive tie the map like an end mark: a start mark's heading error is turned
// back without one. A mark that disagrees with the others and the map is left out, said and
// reported; one outside the drive's time is said and not used.
TEST(SurveyRun, MarksAlongTheDriveTurnTheMapBackAndAWrongOneIsLeftOut) {
    const auto dir = lookup::test::freshDir("lookup_survey_drive_marks");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 12.0);
    const auto run = [&](const std::string& marks, const std::string& name) {
        auto o = shareOptions();
        o.start_pose = "0 0 7.7106";  // the truth's heading is 5.7106 deg
        o.start_pose_std_yaw_deg = 2.0;
        o.marks = marks;
        o.marks_std_xy_m = 0.3;  // the fixture's map is stretched along the corridor
        o.marks_std_yaw_deg = 0.5;
        auto result = Survey(o, shareIni()).run(inputsFor(f, dir / name));
        EXPECT_TRUE(result.ok()) << result.reason;
        return std::make_pair(result,
                              lookup::database::ReferenceDatabase::load((dir / name).string()));
    };
    const auto headingError = [](const lookup::database::ReferenceDatabase& db) {
        double sum = 0;
        for (const auto& r : db.references()) {
            const auto truth = lookup::test::truePoseAt(r.time_s - 1.7e9);
            sum += std::abs(mrpt::math::wrapToPi(r.vehicle_pose.yaw() - truth.phi()));
        }
        return mrpt::RAD2DEG(sum / db.size());
    };
    const auto markAt = [](double t, double dy = 0) {
        const auto p = lookup::test::truePoseAt(t);
        return std::to_string(1.7e9 + t) + " " + std::to_string(p.x()) + " " +
               std::to_string(p.y() + dy) + " " + std::to_string(mrpt::RAD2DEG(p.phi()));
    };
    const auto [none_result, none] = run("", "none");
    const auto [good_result, good] = run(markAt(4) + "; " + markAt(8), "good");
    const auto [wrong_result, wrong] =
        run(markAt(4) + "; " + markAt(6, 2.5) + "; " + markAt(8) + "; " + markAt(40), "wrong");

    EXPECT_TRUE(none_result.drive_marks.empty());
    EXPECT_GT(headingError(none), 1.5);
    ASSERT_EQ(good_result.drive_marks.size(), 2u);
    EXPECT_TRUE(good_result.drive_marks[0].used && good_result.drive_marks[1].used);
    EXPECT_FALSE(good_result.end_mark.given);
    EXPECT_NEAR(mrpt::RAD2DEG(good_result.end_mark.correction.phi()), -2.0, 0.4);
    EXPECT_LT(headingError(good), 0.3);
    EXPECT_NE(good_result.toJson().find("\"marks\""), std::string::npos);

    // The mark 2.5 m beside the drive is left out, the two good ones still turn the map back;
    // the one at 40 s (the drive lasts 12) is said and not reported as a mark.
    ASSERT_EQ(wrong_result.drive_marks.size(), 3u);
    EXPECT_TRUE(wrong_result.drive_marks[0].used);
    EXPECT_FALSE(wrong_result.drive_marks[1].used);
    EXPECT_GT(wrong_result.drive_marks[1].disagreement_m, 2.0);
    EXPECT_TRUE(wrong_result.drive_marks[2].used);
    EXPECT_LT(headingError(wrong), 0.3);
    const auto said = [&](const std::string& a, const std::string& b) {
        return std::any_of(
            wrong_result.warnings.begin(), wrong_result.warnings.end(), [&](const std::string& w) {
                return w.find(a) != std::string::npos && w.find(b) != std::string::npos;
            });
    };
    EXPECT_TRUE(said("mark at time 1700000006.000", "not used"));
    EXPECT_TRUE(said("mark at time 1700000040.000", "outside"));
}

TEST(SurveyRun, MissingLidarNamesLabelsPresent) {
    const auto dir = lookup::test::freshDir("lookup_survey_nolidar");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 2.0, false);
    const auto result = Survey(shareOptions(), shareIni()).run(inputsFor(f, dir / "db"));
    ASSERT_FALSE(result.ok());
    EXPECT_NE(result.reason.find(f.rawlog), std::string::npos) << result.reason;
    EXPECT_NE(result.reason.find("LIDAR"), std::string::npos) << result.reason;
    EXPECT_NE(result.reason.find("labels present: CEILING_CAM, FORWARD_CAM, ODOMETRY"),
              std::string::npos)
        << result.reason;
    EXPECT_FALSE(fs::exists(dir / "db"));
    EXPECT_TRUE(noStagingLeft(dir));
}

TEST(SurveyRun, MissingImageNamesFileAndRecord) {
    const auto dir = lookup::test::freshDir("lookup_survey_noimage");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 2.0);
    fs::remove(dir / "corridor_Images" / "CEILING_CAM_5.png");
    auto in = inputsFor(f, dir / "db");
    in.poses_file = f.ground_truth;
    const auto result = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(result.ok());
    EXPECT_NE(result.reason.find("CEILING_CAM_5.png"), std::string::npos) << result.reason;
    // Records per frame: odometry, scan, ceiling, forward -> frame 5's ceiling is record 22.
    EXPECT_NE(result.reason.find("record 22"), std::string::npos) << result.reason;
    EXPECT_FALSE(fs::exists(dir / "db"));
}

TEST(SurveyRun, NonMonotonicTimeStampsNamed) {
    const auto dir = lookup::test::freshDir("lookup_survey_nonmono");
    const std::string path = (dir / "bad.rawlog").string();
    {
        lookup::common::RawlogWriter w(path);
        for (int k = 0; k < 3; ++k) {
            mrpt::obs::CObservationImage img;
            img.sensorLabel = "CEILING_CAM";
            img.timestamp = mrpt::Clock::fromDouble(k == 2 ? 5.0 : 10.0 + k);
            img.image =
                mrpt::img::CImage(cv::Mat(6, 8, CV_8UC1, cv::Scalar(100)), mrpt::img::DEEP_COPY);
            w.writeWithExternalImage(img, std::to_string(k) + ".png");
        }
    }
    SurveyInputs in;
    in.traverses.push_back({"bad", path, "", true, true});
    in.out_dir = (dir / "db").string();
    in.poses_file = path;  // never reached
    const auto result = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(result.ok());
    EXPECT_NE(result.reason.find(path + ": record 2: non-monotonic time stamp"), std::string::npos)
        << result.reason;
}

TEST(SurveyRun, MismatchedPoseFileTimesNamed) {
    const auto dir = lookup::test::freshDir("lookup_survey_mismatch");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 2.0);
    auto track = lookup::common::readPoseFile(f.ground_truth);
    for (auto& p : track) p.time_s += 500;
    const std::string shifted = (dir / "shifted.txt").string();
    lookup::common::writeMrptPoseFile(shifted, track);
    auto in = inputsFor(f, dir / "db");
    in.poses_file = shifted;
    const auto result = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(result.ok());
    EXPECT_NE(result.reason.find("mismatched time stamps"), std::string::npos) << result.reason;
    EXPECT_NE(result.reason.find("record 2:"), std::string::npos) << result.reason;
    EXPECT_NE(result.reason.find(shifted), std::string::npos) << result.reason;
}

TEST(SurveyRun, UnreadableMapNamed) {
    const auto dir = lookup::test::freshDir("lookup_survey_badmap");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 2.0);
    const std::string map = (dir / "broken.gridmap.gz").string();
    std::ofstream(map) << "not a map";
    auto in = inputsFor(f, dir / "db");
    in.map_file = map;
    const auto result = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(result.ok());
    EXPECT_NE(result.reason.find(map + ": unreadable map"), std::string::npos) << result.reason;
}

TEST(SurveyRun, FailedSurveyKeepsExistingDatabase) {
    const auto dir = lookup::test::freshDir("lookup_survey_keep");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 3.0);
    auto in = inputsFor(f, dir / "db");
    in.poses_file = f.ground_truth;
    const auto first = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_TRUE(first.ok()) << first.reason;
    in.poses_file = (dir / "missing.txt").string();
    const auto second = Survey(shareOptions(), shareIni()).run(in);
    ASSERT_FALSE(second.ok());
    EXPECT_NE(second.reason.find("missing.txt"), std::string::npos) << second.reason;
    const auto db = lookup::database::ReferenceDatabase::load((dir / "db").string());
    EXPECT_EQ(db.size(), first.references);
    EXPECT_TRUE(noStagingLeft(dir));
    // A successful rerun replaces it.
    in.poses_file = f.ground_truth;
    ASSERT_TRUE(Survey(shareOptions(), shareIni()).run(in).ok());
    EXPECT_TRUE(noStagingLeft(dir));
}

// lookup-localize end to end on a synthetic planar ceiling: a database of references along a
// straight drive, a query drive offset sideways, coarse poses from a file with metre-level
// errors; the refined poses must land within centimetres of the truth.

#include <gtest/gtest.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <Eigen/Dense>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <map>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <vector>

#include "localize_fixture.h"
#include "lookup/coarse/options.h"
#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"
#include "lookup/database/reference_database.h"
#include "lookup/eval/evaluator.h"
#include "lookup/localize/localize_app.h"
#include "lookup/localize/localizer.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

namespace fs = std::filesystem;
using namespace lookup;
using namespace lookup::localize_testing;

namespace {

// Two survey traverses with unrelated forward views (seeds 1 and 2): "long", 60 references,
// then "short", 45; reference 60 + k is frame k of "short".
database::ReferenceDatabase twoForwardTraverses(const std::string& name) {
    const auto dir = lookup::test::freshDir("lookup_localize_" + name);
    writeDatabase(Scene(), (dir / "db").string(),
                  {{"long", 60, 100.0, /*forward_seed=*/1}, {"short", 45, 500.0, 2}});
    return database::ReferenceDatabase::load((dir / "db").string());
}

/// planarRun in a fresh folder `name`, localised with `ini_text` as its .ini: the run read back.
eval::Run localisedPlanarRun(const std::string& name, const Spoiler& spoil, int frames,
                             const std::string& ini_text) {
    const auto dir = lookup::test::freshDir(name);
    auto req = planarRun(dir, spoil, frames);
    req.ini_file = (dir / "localize.ini").string();
    std::ofstream(req.ini_file) << ini_text;
    localize::runLocalization(req);
    return eval::loadRun(req.out_dir);
}

/// How far a frame's pose lies from the default PlanarDrive's vehicle at frame `i` [m].
double offDefaultDrive(const eval::FrameRow& f, int i) {
    const auto truth = PlanarDrive().vehicle(i);
    return std::hypot(f.x - truth.x(), f.y - truth.y());
}

}  // namespace

TEST(Localize, RefinesCoarsePosesToCentimetresOnASyntheticCeiling) {
    Scene scene;
    const auto dir = lookup::test::freshDir("lookup_localize_planar");
    writeDatabase(scene, (dir / "db").string(), {{"survey", 65, 100.0}});  // x = -8 .. 8

    // Query drive: 0.4 m to the left of the survey line, slightly rotated, 20 frames.
    common::PoseTrack truth, coarse;
    {
        common::RawlogWriter rawlog((dir / "query.rawlog").string());
        for (int i = 0; i < 20; ++i) {
            const double t = kT0 + 0.1 * i;
            const mrpt::poses::CPose3D vehicle(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0);
            truth.push_back({t, vehicle});
            // Coarse error of 0.6-1.0 m along the tunnel, as a sequence matcher would give.
            coarse.push_back(
                {t, vehicle + mrpt::poses::CPose3D(0.6 + 0.02 * i, -0.4, 0, -0.05, 0, 0)});
            auto img = scene.image(vehicle, t);
            char name[32];
            std::snprintf(name, sizeof name, "ceiling_%03d.png", i);
            rawlog.writeWithExternalImage(*img, name);
            mrpt::obs::CObservationOdometry odo;
            odo.sensorLabel = "ODOMETRY";
            odo.timestamp = img->timestamp;
            odo.odometry = mrpt::poses::CPose2D(vehicle.x(), vehicle.y(), vehicle.yaw());
            rawlog.write(odo);
        }
        rawlog.close();
    }
    common::writeTumPoseFile((dir / "coarse.tum").string(), coarse);
    common::writeMrptPoseFile((dir / "query.rawlog.GT.txt").string(), truth);

    localize::LocalizeRequest req;
    req.db_dir = (dir / "db").string();
    req.rawlog = (dir / "query.rawlog").string();
    req.out_dir = (dir / "run").string();
    req.coarse_poses = (dir / "coarse.tum").string();
    req.sampling = "grid";  // no --method: the run is named after its sampler
    req.progress = false;
    const auto timing = localize::runLocalization(req);
    EXPECT_EQ(timing.frames, 20u);
    EXPECT_EQ(timing.frames_dropped, 0u);
    EXPECT_GT(timing.startup_s, 0.0);  // the database load, apart from the frames' time
    EXPECT_GT(timing.wall_s, 0.0);
    {
        std::ifstream in(fs::path(req.out_dir) / "timing.json");
        const auto j = nlohmann::json::parse(in);
        EXPECT_DOUBLE_EQ(j.at("startup_s").get<double>(), timing.startup_s);
        EXPECT_DOUBLE_EQ(j.at("frames_per_s").get<double>(), 20.0 / timing.wall_s);
    }

    const auto report =
        eval::evaluate({eval::loadGroundTruth((dir / "query.rawlog.GT.txt").string())},
                       {eval::loadRun(req.out_dir)}, {});
    ASSERT_EQ(report.rows.size(), 2u);
    const auto& coarse_row = report.rows[0];
    const auto& lookup_row = report.rows[1];
    EXPECT_EQ(coarse_row.method, "coarse");
    EXPECT_EQ(lookup_row.method, "lookup-grid24");
    EXPECT_GT(coarse_row.error.mean_m, 0.5);
    EXPECT_GE(lookup_row.acceptance_share, 0.95);
    EXPECT_LT(lookup_row.error.mean_m, 0.03);
    EXPECT_LT(lookup_row.error.max_m, 0.10);

    for (const char* f :
         {"frames.csv", "poses.tum", "coarse.tum", "results.rawlog", "timing.json", "run.ini"}) {
        EXPECT_TRUE(fs::exists(fs::path(req.out_dir) / f)) << f;
    }

    // The options a run resolved, given back as --ini, give the same poses.
    {
        localize::LocalizeRequest again = req;
        again.out_dir = (dir / "again").string();
        again.ini_file = (fs::path(req.out_dir) / "run.ini").string();
        localize::runLocalization(again);
        EXPECT_EQ(readText(fs::path(again.out_dir) / "poses.tum"),
                  readText(fs::path(req.out_dir) / "poses.tum"));
    }

    // --repeat: three passes, each timed one second after the previous one ended.
    {
        localize::LocalizeRequest again = req;
        again.out_dir = (dir / "repeat").string();
        again.repeat = 3;
        EXPECT_EQ(localize::runLocalization(again).frames, 60u);
        std::ifstream in(fs::path(again.out_dir) / "frames.csv");
        std::string line;
        std::getline(in, line);  // header
        std::vector<double> stamps;
        while (std::getline(in, line)) stamps.push_back(std::stod(line.substr(0, line.find(','))));
        ASSERT_EQ(stamps.size(), 60u);
        for (std::size_t k = 1; k < stamps.size(); ++k) {
            EXPECT_GT(stamps[k], stamps[k - 1]) << "frame " << k;
        }
        EXPECT_NEAR(stamps[20] - stamps[19], 1.0, 1e-3);  // one second between passes
        EXPECT_NEAR(stamps[40] - stamps[20], stamps[20] - stamps[0], 1e-3);
        again.repeat = 0;
        EXPECT_THROW(localize::runLocalization(again), common::ConfigError);
    }

    // The same frames from a "live" camera: MRPT's CCameraSensor replaying the rawlog, as
    // rawlog-grabber would drive it on the vehicle.
    std::ofstream(dir / "sensors.ini")
        << "[CAM]\ndriver = CCameraSensor\nprocess_rate = 50\n"
        << "grabber_type = rawlog\nrawlog_file = " << (dir / "query.rawlog").string()
        << "\nrawlog_camera_sensor_label = CEILING_CAM\n"
        << "sensorLabel = CEILING_CAM\npose_z = 1.5\n";
    localize::LiveRequest live;
    live.base = req;
    live.base.out_dir = (dir / "live").string();
    live.sensors_ini = (dir / "sensors.ini").string();
    live.quiet_timeout_s = 1.0;
    live.duration_s = 20;
    const auto live_timing = localize::runLiveLocalization(live);
    EXPECT_EQ(live_timing.frames, 20u);
    const auto live_report =
        eval::evaluate({eval::loadGroundTruth((dir / "query.rawlog.GT.txt").string())},
                       {eval::loadRun(live.base.out_dir)}, {});
    ASSERT_EQ(live_report.rows.size(), 2u);
    EXPECT_LT(live_report.rows[1].error.mean_m, 0.03);

    // camera_params_file gives a live camera its calibration (MRPT's grabbers deliver none):
    // the recorded intrinsics reproduce the run, wrong ones change it, a missing file is
    // refused naming the sensors file, section and key.
    mrpt::img::TCamera recorded;
    {
        common::RawlogReader reader((dir / "query.rawlog").string());
        mrpt::obs::CObservation::Ptr obs;
        while (reader.next(obs)) {
            const auto* img = dynamic_cast<const mrpt::obs::CObservationImage*>(obs.get());
            if (img == nullptr || obs->sensorLabel != "CEILING_CAM") continue;
            recorded = img->cameraParams;
            break;
        }
    }
    const auto calibrated = [&](const std::string& name, double fx_scale) {
        std::ofstream(dir / (name + "-calib.ini"))
            << "[CAMERA_PARAMS]\nresolution = [" << recorded.ncols << " " << recorded.nrows
            << "]\ncx = " << recorded.cx() << "\ncy = " << recorded.cy()
            << "\nfx = " << recorded.fx() * fx_scale << "\nfy = " << recorded.fy() * fx_scale
            << "\ndist = [" << recorded.k1() << " " << recorded.k2() << " " << recorded.p1() << " "
            << recorded.p2() << " " << recorded.k3() << "]\ndistortion_model = plumb_bob\n";
        std::ifstream base(dir / "sensors.ini");
        std::ofstream(dir / (name + "-sensors.ini"))
            << base.rdbuf() << "camera_params_file = " << name << "-calib.ini\n";
        localize::LiveRequest l = live;
        l.base.out_dir = (dir / name).string();
        l.sensors_ini = (dir / (name + "-sensors.ini")).string();
        return l;
    };
    const auto meanErrorOf = [&](const localize::LiveRequest& l) {
        const auto r =
            eval::evaluate({eval::loadGroundTruth((dir / "query.rawlog.GT.txt").string())},
                           {eval::loadRun(l.base.out_dir)}, {});
        return r.rows.size() == 2 ? r.rows[1].error.mean_m : 1e9;
    };
    const auto same = calibrated("calib-same", 1.0);
    EXPECT_EQ(localize::runLiveLocalization(same).frames, 20u);
    EXPECT_LT(meanErrorOf(same), 0.03);
    // A focal length 1.5 times too long scales every offset by 1/1.5: the ceiling confirms no
    // frame, and no pose is reported rather than a wrong one.
    const auto wrong = calibrated("calib-wrong", 1.5);
    localize::runLiveLocalization(wrong);
    const auto wrong_run = eval::loadRun(wrong.base.out_dir);
    ASSERT_EQ(wrong_run.frames.size(), 20u);
    for (const auto& f : wrong_run.frames) {
        EXPECT_NE(f.status, "refined") << f.reason;
        EXPECT_FALSE(f.has_pose) << f.status << ": " << f.reason;
    }
    auto missing = calibrated("calib-missing", 1.0);
    fs::remove(dir / "calib-missing-calib.ini");
    try {
        localize::runLiveLocalization(missing);
        ADD_FAILURE() << "a missing calibration file was accepted";
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("camera_params_file"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("calib-missing-sensors.ini"), std::string::npos)
            << e.what();
    }
}

TEST(Localize, OnADeclineSurveyedIn3DThePoseCarriesTheFloorsHeight) {
    // The scene 5 m down on an 8 deg grade, its references surveyed with 3-D poses: every frame
    // refines to the same plan pose as on the level, and its height is the floor's under it.
    // Over the level scene's planar references no frame has a height.
    PlanarDrive drive;
    drive.grade = mrpt::poses::CPose3D(2.0, -1.0, -5.0, 0.3, mrpt::DEG2RAD(8.0), 0.0);
    const auto none = [](int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&) {};
    const int frames = 12;
    const auto dir = lookup::test::freshDir("lookup_localize_decline_3d");
    auto req = planarRun(dir, none, frames, drive);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), std::size_t(frames));
    for (int i = 0; i < frames; ++i) {
        const auto& f = run.frames[i];
        const mrpt::poses::CPose3D truth = drive.grade + drive.vehicle(i);
        ASSERT_EQ(f.status, "refined") << i << ": " << f.reason;
        EXPECT_LT(std::hypot(f.x - truth.x(), f.y - truth.y()), 0.02) << i;
        ASSERT_TRUE(f.has_z) << i;
        EXPECT_NEAR(f.z, truth.z(), 0.01) << i;
    }
    const auto level_dir = lookup::test::freshDir("lookup_localize_decline_level");
    auto level = planarRun(level_dir, none, 3);
    localize::runLocalization(level);
    for (const auto& f : eval::loadRun(level.out_dir).frames) EXPECT_FALSE(f.has_z);
}

TEST(Localize, AnOdometryDropoutIsBridgedAtTheLastVelocityWithAGrowingEllipse) {
    const auto dir = lookup::test::freshDir("lookup_localize_odometry_dropout");
    // Frames 8-15 (0.8 s at 3 m/s): no odometry (its readings are not finite, so skipped) and
    // a ceiling too flat to match, so only dead reckoning places the vehicle.
    const int frames = 24;
    auto req = planarRun(
        dir,
        [](int i, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry& odo) {
            if (i < 8 || i > 15) return;
            odo.odometry.x(std::numeric_limits<double>::quiet_NaN());
            img.image = mrpt::img::CImage(cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)),
                                          mrpt::img::DEEP_COPY);
        },
        frames);
    common::PoseTrack truth;
    for (int i = 0; i < frames; ++i) {
        truth.push_back({kT0 + 0.1 * i, mrpt::poses::CPose3D(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0)});
    }
    common::writeMrptPoseFile((dir / "query.rawlog.GT.txt").string(), truth);
    localize::runLocalization(req);

    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), std::size_t(frames));
    for (int i = 8; i <= 15; ++i) {
        const auto& f = run.frames[i];
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        ASSERT_TRUE(f.has_pose) << i;
        EXPECT_LT(std::hypot(f.x - truth[i].pose.x(), f.y - truth[i].pose.y()), 0.1) << i;
    }
    EXPECT_GT(run.frames[15].cov_xx, run.frames[8].cov_xx);
    const auto report =
        eval::evaluate({eval::loadGroundTruth((dir / "query.rawlog.GT.txt").string())}, {run}, {});
    ASSERT_EQ(report.rows.size(), 2u);
    EXPECT_EQ(report.rows[1].confident_wrong, 0u);
    EXPECT_EQ(run.frames[16].status, "refined") << run.frames[16].reason;
}

// The vehicle stops for a second (frames 8-18 at one place) and drives on: a stopped vehicle
// keeps its fix, without drifting, and picks the motion up again.
TEST(Localize, AStoppedVehicleKeepsItsFixAndDrivesOn) {
    PlanarDrive drive;
    drive.vehicle = [](int i) {
        const int moving = i <= 8 ? i : std::max(8, i - 10);
        return mrpt::poses::CPose3D(-5 + 0.3 * moving, 0.4, 0, 0.05, 0, 0);
    };
    const int frames = 26;
    const auto dir = lookup::test::freshDir("lookup_localize_standstill");
    auto req = planarRun(
        dir, [](int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&) {}, frames,
        drive);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), std::size_t(frames));
    double x_lo = 1e9, x_hi = -1e9;
    for (int i = 0; i < frames; ++i) {
        const auto& f = run.frames[i];
        const auto truth = drive.vehicle(i);
        ASSERT_EQ(f.status, "refined") << i << ": " << f.reason;
        EXPECT_LT(std::hypot(f.x - truth.x(), f.y - truth.y()), 0.03) << i;
        if (i >= 8 && i <= 18) x_lo = std::min(x_lo, f.x), x_hi = std::max(x_hi, f.x);
    }
    EXPECT_LT(x_hi - x_lo, 0.01) << "the stopped vehicle's fixes drift";
}

// A corner taken briskly while the odometry drops out (frames 7-13: readings not finite): the
// vehicle turns 0.25 rad a frame from frame 10 on, and from frame 10 the ceiling is too flat to
// match. The last fix (frame 9) lies inside the dropout, where the odometry is only the straight
// line between the readings around it, 27 degrees off the vehicle's heading there: every pose
// dead-reckoned from that fix after the dropout is turned by it, and its ellipse has to say so.
TEST(Localize, AFixInsideAnOdometryDropoutThroughACornerWidensTheDeadReckoning) {
    PlanarDrive drive;
    drive.vehicle = [](int i) {
        double x = -5, y = 0.4, yaw = 0.05;
        for (int k = 0; k < i; ++k) {
            x += 0.3 * std::cos(yaw);
            y += 0.3 * std::sin(yaw);
            if (k >= 9 && k < 14) yaw += 0.25;
        }
        return mrpt::poses::CPose3D(x, y, 0, yaw, 0, 0);
    };
    const auto spoil = [](int i, mrpt::obs::CObservationImage& img,
                          mrpt::obs::CObservationOdometry& odo) {
        if (i >= 7 && i <= 13) odo.odometry.x(std::numeric_limits<double>::quiet_NaN());
        if (i >= 10) {
            img.image = mrpt::img::CImage(cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)),
                                          mrpt::img::DEEP_COPY);
        }
    };
    const int frames = 22;
    const auto dir = lookup::test::freshDir("lookup_localize_dropout_corner");
    auto req = planarRun(dir, spoil, frames, drive);
    common::PoseTrack truth;
    for (int i = 0; i < frames; ++i) truth.push_back({kT0 + 0.1 * i, drive.vehicle(i)});
    common::writeMrptPoseFile((dir / "query.rawlog.GT.txt").string(), truth);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), std::size_t(frames));
    ASSERT_EQ(run.frames[9].status, "refined") << run.frames[9].reason;
    double largest_error = 0;
    for (int i = 14; i < frames; ++i) {
        const auto& f = run.frames[i];
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        const Eigen::Vector2d e(f.x - truth[i].pose.x(), f.y - truth[i].pose.y());
        Eigen::Matrix2d cov;
        cov << f.cov_xx, f.cov_xy, f.cov_xy, f.cov_yy;
        largest_error = std::max(largest_error, e.norm());
        // Inside the 99.7 % ellipse (chi-square, 2 degrees of freedom).
        EXPECT_LT(e.dot(cov.inverse() * e), 11.8) << i << ": " << e.norm() << " m off";
    }
    EXPECT_GT(largest_error, 0.5) << "the dead reckoning was not turned: nothing tested";
    const auto report =
        eval::evaluate({eval::loadGroundTruth((dir / "query.rawlog.GT.txt").string())}, {run}, {});
    ASSERT_EQ(report.rows.size(), 2u);
    EXPECT_EQ(report.rows[1].confident_wrong, 0u);
}

// Odometry that under-reads by 20 % (a slipping wheel) against a ceiling that is right:
// within [localizer] track_disagreement_m the track is kept; with a tighter setting three
// fixes in a row off the prediction drop it.
TEST(Localize, FixesThatKeepDisagreeingWithOdometryDropTheTrack) {
    const auto under_read = [](int i, mrpt::obs::CObservationImage&,
                               mrpt::obs::CObservationOdometry& odo) {
        odo.odometry.x(-5 + 0.8 * 0.3 * i);
    };
    const auto drops = [&](const std::string& name, const std::string& ini_text) {
        std::size_t dropped = 0;
        const auto run =
            localisedPlanarRun("lookup_localize_track_" + name, under_read, 16, ini_text);
        for (const auto& f : run.frames) {
            dropped += f.reason.find("from the odometry prediction") != std::string::npos;
        }
        return dropped;
    };
    EXPECT_EQ(drops("default", "[localizer]\n"), 0u);
    EXPECT_GE(drops("tight",
                    "[localizer]\ntrack_disagreement_m = 0.02\n"
                    "track_disagreement_per_m = 0\n"),
              1u);
}

// From frame 5 the ceiling is another one (new shotcrete: textured, but nothing of it in the
// references) and the wheel slips, reading 25 % more distance than the vehicle drives: 1 m
// too far by frame 19. Measured on the ceiling between consecutive frames, the dead
// reckoning follows the vehicle; from the odometry alone it runs ahead. Either way the frames
// are fallbacks with the same uncertainty.
TEST(Localize, OnAChangedCeilingTheDeadReckoningFollowsTheCeilingsOwnMotion) {
    Scene changed;
    changed.ceiling = refine::synthetic::SyntheticCeiling::make(kCeilingHeight, 40.0, 0.01, 8);
    const auto spoil = [&](int i, mrpt::obs::CObservationImage& img,
                           mrpt::obs::CObservationOdometry& odo) {
        if (i < 5) return;
        odo.odometry.x(-5 + 0.3 * 5 + 1.25 * 0.3 * (i - 5));
        img.image = changed.image(PlanarDrive().vehicle(i), kT0 + 0.1 * i)->image;
    };
    const auto run = [&](const std::string& name, const std::string& ini_text) {
        return localisedPlanarRun("lookup_localize_ceiling_odometry_" + name, spoil, 20, ini_text);
    };
    const auto followed = run("on", "[localizer]\n");
    const auto odometry = run("off", "[localizer]\nceiling_odometry = false\n");
    ASSERT_EQ(followed.frames.size(), 20u);
    ASSERT_EQ(odometry.frames.size(), 20u);
    ASSERT_EQ(followed.frames[4].status, "refined") << followed.frames[4].reason;
    for (int i = 5; i < 20; ++i) {
        const auto &f = followed.frames[i], &o = odometry.frames[i];
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        ASSERT_EQ(o.status, "fallback") << i << ": " << o.reason;
        EXPECT_LT(offDefaultDrive(f, i), 0.1) << i;
        EXPECT_NEAR(f.cov_xx, o.cov_xx, 1e-9) << i;
        if (i > 5) {  // frame 5 has no frame of its own ceiling before it
            EXPECT_NE(f.reason.find("ceiling's own motion"), std::string::npos)
                << i << ": " << f.reason;
        }
        EXPECT_EQ(o.reason.find("ceiling's own motion"), std::string::npos)
            << i << ": " << o.reason;
    }
    EXPECT_GT(offDefaultDrive(odometry.frames[19], 19), 0.9);
}

// From frame 5 the ceiling is another one (as above) and the camera shows the same image
// every frame (mud over the lens, or a driver that resends its last frame) while the wheels,
// gripping, drive on 0.3 m a frame. Frame to frame the ceiling then says the vehicle stands
// still: a disagreement no wheel's slip makes (ceiling_odometry_max_slip), so the dead
// reckoning keeps the odometry's steps. Without that bound it stops where the image froze.
TEST(Localize, AnImageThatStandsStillWhileTheWheelsGripDoesNotStopTheDeadReckoning) {
    Scene changed;
    changed.ceiling = refine::synthetic::SyntheticCeiling::make(kCeilingHeight, 40.0, 0.01, 8);
    const auto frozen = changed.image(PlanarDrive().vehicle(5), kT0 + 0.5)->image;
    const auto spoil = [&](int i, mrpt::obs::CObservationImage& img,
                           mrpt::obs::CObservationOdometry&) {
        if (i >= 5) img.image = frozen;
    };
    const auto run = [&](const std::string& name, const std::string& ini_text) {
        return localisedPlanarRun("lookup_localize_frozen_view_" + name, spoil, 20, ini_text);
    };
    const auto bounded = run("bounded", "[localizer]\n");
    const auto unbounded = run("unbounded", "[localizer]\nceiling_odometry_max_slip = 10\n");
    ASSERT_EQ(bounded.frames.size(), 20u);
    ASSERT_EQ(unbounded.frames.size(), 20u);
    ASSERT_EQ(bounded.frames[4].status, "refined") << bounded.frames[4].reason;
    for (int i = 5; i < 20; ++i) {
        const auto& f = bounded.frames[i];
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        EXPECT_EQ(f.reason.find("ceiling's own motion"), std::string::npos)
            << i << ": " << f.reason;
        if (i > 5) {  // frame 5 has no frame of its own ceiling before it
            EXPECT_NE(f.reason.find("more than a wheel slips"), std::string::npos)
                << i << ": " << f.reason;
        }
        EXPECT_LT(offDefaultDrive(f, i), 0.1) << i;
    }
    EXPECT_GT(offDefaultDrive(unbounded.frames[19], 19), 2.0)
        << "the ceiling's step was never taken";
}

// Every query image behind a lens caked with dust (soft blotches letting 25-50 % of the light
// through) in a dim, hazy place (a quarter of the ceiling's contrast over a flat airlight). Once
// the lens's mean has its images (lens_frames, one per frame here), the dirt is found and
// divided out: the later frames refine where, uncorrected, the blotches stand in the way.
TEST(Localize, DirtOnTheLensIsFoundInTheDrivesMeanAndDividedOut) {
    cv::Mat transmission(240, 320, CV_32F, cv::Scalar(1));
    const double blotches[][4] = {{70, 60, 40, 0.75},
                                  {230, 90, 45, 0.7},
                                  {150, 180, 40, 0.6},
                                  {290, 210, 30, 0.5},
                                  {20, 200, 35, 0.7}};
    for (const auto& b : blotches) {
        for (int v = 0; v < 240; ++v) {
            for (int u = 0; u < 320; ++u) {
                const double d2 = (std::pow(u - b[0], 2) + std::pow(v - b[1], 2)) / (b[2] * b[2]);
                transmission.at<float>(v, u) *= static_cast<float>(1 - b[3] * std::exp(-d2));
            }
        }
    }
    const auto spoil = [&](int, mrpt::obs::CObservationImage& img,
                           mrpt::obs::CObservationOdometry&) {
        cv::Mat radiance;
        img.image.asCvMatRef().convertTo(radiance, CV_32F, 0.25, 90);
        cv::Mat seen;
        cv::Mat(radiance.mul(transmission)).convertTo(seen, CV_8U);
        img.image = mrpt::img::CImage(seen, mrpt::img::DEEP_COPY);
    };
    const auto run = [&](const std::string& name, const std::string& ini_text) {
        return localisedPlanarRun("lookup_localize_dirty_lens_" + name, spoil, 40, ini_text);
    };
    const std::string lens = "[localizer]\nlens_frames = 15\n";
    const auto corrected = run("corrected", lens);
    const auto uncorrected = run("uncorrected", lens + "lens_correction = false\n");
    ASSERT_EQ(corrected.frames.size(), 40u);
    ASSERT_EQ(uncorrected.frames.size(), 40u);
    std::size_t refined = 0, refined_uncorrected = 0;
    for (int i = 20; i < 40; ++i) {
        refined += corrected.frames[i].status == "refined";
        refined_uncorrected += uncorrected.frames[i].status == "refined";
        if (corrected.frames[i].status == "refined")
            EXPECT_LT(offDefaultDrive(corrected.frames[i], i), 0.05) << i;
    }
    EXPECT_GE(refined, 18u);
    EXPECT_LE(refined_uncorrected + 5, refined);
    std::ifstream timing(fs::temp_directory_path() / "lookup_localize_dirty_lens_corrected" /
                         "run" / "timing.json");
    const auto lens_json = nlohmann::json::parse(timing).at("lens");
    EXPECT_EQ(lens_json.at("corrected").get<double>(), 1.0);
    EXPECT_LT(lens_json.at("least_transmission").get<double>(), 0.6);
}

// The vehicle turns at 0.3 rad/s until frame 7, then drives straight; over frames 8-21 the
// odometry drops out (readings not finite) and the ceiling is another one (textured, nothing
// of it in the references). Extrapolated, the odometry would keep turning, and past the
// tracking gap (1 s) it has no pose at all; measured frame to frame on the ceiling, heading
// included, and carried on at the velocity measured there, the dead reckoning keeps the line.
TEST(Localize, ThroughAnOdometryDropoutTheCeilingsOwnMotionKeepsTheHeading) {
    Scene changed;
    changed.ceiling = refine::synthetic::SyntheticCeiling::make(kCeilingHeight, 40.0, 0.01, 8);
    PlanarDrive drive;
    drive.vehicle = [](int i) {
        double x = -5, y = 0.4, yaw = -0.1;
        for (int k = 0; k < i; ++k) {
            x += 0.3 * std::cos(yaw);
            y += 0.3 * std::sin(yaw);
            if (k < 7) yaw += 0.03;
        }
        return mrpt::poses::CPose3D(x, y, 0, yaw, 0, 0);
    };
    const auto spoil = [&](int i, mrpt::obs::CObservationImage& img,
                           mrpt::obs::CObservationOdometry& odo) {
        if (i < 8 || i > 21) return;
        odo.odometry.x(std::numeric_limits<double>::quiet_NaN());
        img.image = changed.image(drive.vehicle(i), kT0 + 0.1 * i)->image;
    };
    const auto dir = lookup::test::freshDir("lookup_localize_dropout_heading");
    auto req = planarRun(dir, spoil, 24, drive);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), 24u);
    ASSERT_EQ(run.frames[7].status, "refined") << run.frames[7].reason;
    for (int i = 9; i <= 21; ++i) {
        const auto& f = run.frames[i];
        const auto truth = drive.vehicle(i);
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        EXPECT_NE(f.reason.find("ceiling's own motion"), std::string::npos)
            << i << ": " << f.reason;
        EXPECT_LT(std::abs(mrpt::math::wrapToPi(f.yaw - truth.yaw())), mrpt::DEG2RAD(2.0)) << i;
        EXPECT_LT(std::hypot(f.x - truth.x(), f.y - truth.y()), 0.15) << i;
    }
    EXPECT_GT(run.frames[21].cov_xx, run.frames[9].cov_xx);
}

// Forward to x = 1.9 m, then reversing back along the same line. Where the vehicle stands at
// x in [-2.5, -0.5] the ceiling is another one (new shotcrete over the surveyed rock), and the
// wheel reads 2 % long. On the way in those frames refine against nothing; the fix after them
// closes the stretch, whose frames, bridged on the odometry, the online refresh adds as
// references. On the way back the same ceiling is then refined, within centimetres.
TEST(Localize, OnlineRefreshRefinesAChangedStretchOnTheWayBack) {
    Scene changed;
    changed.ceiling = refine::synthetic::SyntheticCeiling::make(kCeilingHeight, 40.0, 0.01, 8);
    PlanarDrive drive;
    drive.vehicle = [](int i) {
        const double x = i <= 23 ? -5 + 0.3 * i : 1.9 - 0.3 * (i - 23);
        return mrpt::poses::CPose3D(x, 0.4, 0, 0.05, 0, 0);
    };
    const auto on_new_shotcrete = [&](int i) {
        const double x = drive.vehicle(i).x();
        return x >= -2.5 && x <= -0.5;
    };
    const auto spoil = [&](int i, mrpt::obs::CObservationImage& img,
                           mrpt::obs::CObservationOdometry& odo) {
        odo.odometry.x(-5 + 1.02 * (drive.vehicle(i).x() + 5));
        if (on_new_shotcrete(i)) img.image = changed.image(drive.vehicle(i), kT0 + 0.1 * i)->image;
    };
    const auto run = [&](const std::string& name, const std::string& ini_text) {
        const auto dir = lookup::test::freshDir("lookup_localize_online_refresh_" + name);
        auto req = planarRun(dir, spoil, 48, drive);
        req.ini_file = (dir / "localize.ini").string();
        std::ofstream(req.ini_file) << ini_text;
        localize::runLocalization(req);
        return eval::loadRun(req.out_dir);
    };
    const auto refreshed = run("on", "[localizer]\n");
    const auto surveyed = run("off", "[localizer]\nonline_refresh = false\n");
    ASSERT_EQ(refreshed.frames.size(), 48u);
    ASSERT_EQ(surveyed.frames.size(), 48u);
    int way_in = 0, way_back = 0, way_back_surveyed = 0;
    for (int i = 0; i < 48; ++i) {
        if (!on_new_shotcrete(i)) continue;
        const auto &f = refreshed.frames[i], &s = surveyed.frames[i];
        (i <= 23 ? way_in : way_back) += f.status == "refined";
        way_back_surveyed += i > 23 && s.status == "refined";
        const auto truth = drive.vehicle(i);
        if (f.status == "refined") {
            EXPECT_LT(std::hypot(f.x - truth.x(), f.y - truth.y()), 0.05) << i;
        }
    }
    EXPECT_EQ(way_in, 0);
    EXPECT_EQ(way_back_surveyed, 0);
    EXPECT_GE(way_back, 6) << "of 7";
}

// A wheel that slips once: from frame 8 the odometry reads 0.6 m farther along than the
// vehicle went, so the prediction lies beyond the SAD window. A tracked frame that fails
// searches the references around its prediction (tracking_acquisition_sigmas) and fixes
// again at once; without that search it waits for the coarse stage or the tracking gap.
TEST(Localize, AFailedTrackedFrameSearchesAroundItsPrediction) {
    const auto slipped = [](int i, mrpt::obs::CObservationImage&,
                            mrpt::obs::CObservationOdometry& odo) {
        if (i >= 8) odo.odometry.x(odo.odometry.x() + 0.6);
    };
    const auto run = [&](const std::string& name, const std::string& ini_text) {
        return localisedPlanarRun("lookup_localize_tracked_search_" + name, slipped, 14, ini_text);
    };
    const auto searched = run("on", "[localizer]\n");
    const auto waited = run("off", "[localizer]\ntracking_acquisition_sigmas = 0\n");
    ASSERT_EQ(searched.frames.size(), 14u);
    ASSERT_EQ(searched.frames[7].status, "refined") << searched.frames[7].reason;
    int refined_after_slip = 0, waited_refined = 0;
    for (int i = 8; i < 14; ++i) {
        const auto& f = searched.frames[i];
        if (f.status != "refined") continue;
        ++refined_after_slip;
        EXPECT_LT(offDefaultDrive(f, i), 0.05) << i;
    }
    for (int i = 8; i < 14; ++i) waited_refined += waited.frames[i].status == "refined";
    EXPECT_EQ(searched.frames[8].status, "refined") << searched.frames[8].reason;
    EXPECT_GE(refined_after_slip, 5);
    EXPECT_LT(waited_refined, refined_after_slip) << waited.frames[8].reason;
}

// Frame 10's image shows the ceiling turned by 8 degrees (a camera knocked for an instant, a
// reference that does not fit), while the odometry turns nothing; frames 11-15 see a flat
// ceiling. The fix of frame 10 disagrees with the odometry's heading and is refused, so the
// dead reckoning that follows starts from frame 9's fix; accepted, it would carry 8 degrees.
TEST(Localize, AFixWhoseHeadingDisagreesWithTheOdometryIsRefused) {
    const Scene scene;
    const auto turned_then_flat = [&](int i, mrpt::obs::CObservationImage& img,
                                      mrpt::obs::CObservationOdometry&) {
        const mrpt::poses::CPose3D vehicle(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0);
        if (i == 10) {
            const mrpt::poses::CPose3D turned(0, 0, 0, mrpt::DEG2RAD(8.0), 0, 0);
            img.image = scene.image(vehicle + turned, 0)->image;
        } else if (i > 10 && i < 16) {
            img.image = mrpt::img::CImage(cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)),
                                          mrpt::img::DEEP_COPY);
        }
    };
    const auto run = [&](const std::string& name, const std::string& ini_text) {
        return localisedPlanarRun("lookup_localize_heading_" + name, turned_then_flat, 16,
                                  ini_text);
    };
    const auto yawError = [](const eval::FrameRow& f) {
        return std::abs(mrpt::RAD2DEG(mrpt::math::wrapToPi(f.yaw - 0.05)));
    };
    const auto checked = run("checked", "[localizer]\n");
    const auto unchecked = run("unchecked", "[localizer]\ntrack_heading_floor_deg = 180\n");
    ASSERT_EQ(checked.frames.size(), 16u);
    ASSERT_EQ(checked.frames[9].status, "refined") << checked.frames[9].reason;
    EXPECT_EQ(checked.frames[10].status, "fallback");
    EXPECT_NE(checked.frames[10].reason.find("heading"), std::string::npos)
        << checked.frames[10].reason;
    for (int i = 10; i < 16; ++i) {
        const auto& f = checked.frames[i];
        EXPECT_LT(yawError(f), 1.0) << i;
        EXPECT_LT(offDefaultDrive(f, i), 0.1) << i;
    }
    ASSERT_EQ(unchecked.frames[10].status, "refined") << unchecked.frames[10].reason;
    EXPECT_GT(yawError(unchecked.frames[10]), 5.0);
}

// Frame 10 is seen from the vehicle turned by 1.5 degrees (too little for the heading check:
// a fix over a changed ceiling, right in place and off in heading), then the ceiling is bare
// for 15 frames. Dead-reckoned from that fix's heading the track would leave the line by 4.5 m
// x sin(1.5 deg) = 0.12 m off it; the median of the recent fixes' headings against the odometry
// keeps it on the line.
TEST(Localize, TheDeadReckoningTakesItsHeadingFromTheRecentFixesNotTheLastOneAlone) {
    const Scene scene;
    const auto turned_then_bare = [&](int i, mrpt::obs::CObservationImage& img,
                                      mrpt::obs::CObservationOdometry&) {
        const mrpt::poses::CPose3D vehicle(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0);
        if (i == 10) {
            const mrpt::poses::CPose3D turned(0, 0, 0, mrpt::DEG2RAD(1.5), 0, 0);
            img.image = scene.image(vehicle + turned, 0)->image;
        } else if (i > 10) {
            img.image = mrpt::img::CImage(cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)),
                                          mrpt::img::DEEP_COPY);
        }
    };
    const auto run =
        localisedPlanarRun("lookup_localize_heading_anchor", turned_then_bare, 26, "[localizer]\n");
    ASSERT_EQ(run.frames.size(), 26u);
    ASSERT_EQ(run.frames[10].status, "refined") << run.frames[10].reason;
    EXPECT_GT(std::abs(mrpt::RAD2DEG(mrpt::math::wrapToPi(run.frames[10].yaw - 0.05))), 1.0);
    for (int i = 11; i < 26; ++i) {
        const auto& f = run.frames[i];
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        EXPECT_LT(std::abs(f.y - 0.4), 0.04) << i;  // the vehicle drives along y = 0.4
        EXPECT_LT(std::abs(f.x - (-5 + 0.3 * i)), 0.05) << i;
    }
}

// The odometry's heading jumps by 10 degrees between frames 8 and 9 (a wheel slipping in a
// turn): every fix after it disagrees with the prediction. The first ones are refused, then
// the track is dropped and the vehicle is found again around the coarse poses.
TEST(Localize, FixesThatKeepDisagreeingInHeadingDropTheTrackAndFixAgain) {
    const auto dir = lookup::test::freshDir("lookup_localize_heading_slip");
    const auto vehicle = [](int i) { return mrpt::poses::CPose2D(-5 + 0.3 * i, 0.4, 0.05); };
    auto req = planarRun(
        dir,
        [&](int i, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry& odo) {
            if (i < 9) return;
            const auto pivot = vehicle(8);
            odo.odometry =
                pivot + mrpt::poses::CPose2D(0, 0, mrpt::DEG2RAD(10.0)) + (vehicle(i) - pivot);
        },
        20);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), 20u);
    ASSERT_EQ(run.frames[8].status, "refined") << run.frames[8].reason;
    EXPECT_NE(run.frames[9].reason.find("heading"), std::string::npos) << run.frames[9].reason;
    bool dropped = false;
    for (int i = 9; i < 13; ++i) {
        dropped = dropped || run.frames[i].reason.find("track dropped") != std::string::npos;
    }
    EXPECT_TRUE(dropped);
    for (int i = 16; i < 20; ++i) {
        const auto& f = run.frames[i];
        ASSERT_EQ(f.status, "refined") << i << ": " << f.reason;
        EXPECT_LT(offDefaultDrive(f, i), 0.05) << i;
    }
}

// The survey vehicle driven back against its own survey, its camera 3 m ahead of its base:
// the references whose vehicles stood nearest saw the ceiling 6 m from the one the camera sees
// now; the references whose cameras stood nearest saw the same ceiling.
TEST(Localize, DrivingAgainstTheSurveyTheReferencesAreThoseWhoseCamerasSawTheCeiling) {
    const auto dir = lookup::test::freshDir("lookup_localize_against_survey");
    PlanarDrive against;
    against.vehicle = [](int i) {
        return mrpt::poses::CPose3D(3 - 0.3 * i, 0.3, 0, M_PI + 0.05, 0, 0);
    };
    against.coarse_error = mrpt::poses::CPose3D(0.3, -0.2, 0, -0.03, 0, 0);
    against.camera_ahead = mrpt::poses::CPose3D(3.0, 0, 0, 0, 0, 0);
    const int frames = 10;
    const auto req = planarRun(
        dir, [](int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&) {}, frames,
        against);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), std::size_t(frames));
    for (int i = 0; i < frames; ++i) {
        const auto& f = run.frames[i];
        ASSERT_EQ(f.status, "refined") << i << ": " << f.reason;
        EXPECT_LT(std::hypot(f.x - (3 - 0.3 * i), f.y - 0.3), 0.05) << i;
    }
}

// A pose at the image's time is as uncertain as that time: 3 m/s along x with the stamps
// uncertain by 0.1 s adds (0.3 m)^2 along the motion to every emitted pose, nothing across it.
TEST(Localize, AnUncertainImageTimeWidensThePoseAlongTheMotion) {
    const auto run = [&](const std::string& name, const std::string& ini_text) {
        return localisedPlanarRun(
            "lookup_localize_image_time_" + name,
            [](int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&) {}, 8,
            ini_text);
    };
    const auto exact = run("exact", "[localizer]\n");
    const auto uncertain = run("uncertain", "[localizer]\nimage_time_sigma_s = 0.1\n");
    for (int i = 3; i < 8; ++i) {
        ASSERT_EQ(uncertain.frames[i].status, "refined") << uncertain.frames[i].reason;
        EXPECT_NEAR(uncertain.frames[i].cov_xx - exact.frames[i].cov_xx, 0.09, 0.01) << i;
        EXPECT_NEAR(uncertain.frames[i].cov_yy - exact.frames[i].cov_yy, 0.0, 0.001) << i;
        EXPECT_EQ(uncertain.frames[i].x, exact.frames[i].x) << i;
    }
}

// Against a database whose survey camera clock is known, a vehicle camera without a configured
// offset is late by an unknown amount the references no longer share: 3 m/s along x with
// uncalibrated_image_time_sigma_s 0.015 s adds (0.045 m)^2 along the motion to every emitted
// pose, and nothing once [time_offsets] calibrates the camera or the survey's clock is unknown.
TEST(Localize, AnUncalibratedCameraAgainstAKnownSurveyClockWidensThePoseAlongTheMotion) {
    const auto run = [&](const std::string& name, std::optional<double> survey_sigma_s,
                         const std::string& ini_text) {
        const auto dir = lookup::test::freshDir("lookup_localize_uncalibrated_" + name);
        PlanarDrive drive;
        drive.survey_camera.time_offset_sigma_s = survey_sigma_s;
        auto req = planarRun(
            dir, [](int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&) {}, 8,
            drive);
        req.ini_file = (dir / "localize.ini").string();
        std::ofstream(req.ini_file) << ini_text;
        localize::runLocalization(req);
        return eval::loadRun(req.out_dir);
    };
    const auto unknown = run("unknown", std::nullopt, "[localizer]\n");
    const auto uncalibrated = run("uncalibrated", 0.004, "[localizer]\n");
    const auto calibrated = run("calibrated", 0.004, "[time_offsets]\nCEILING_CAM = 0\n");
    for (int i = 3; i < 8; ++i) {
        ASSERT_EQ(uncalibrated.frames[i].status, "refined") << uncalibrated.frames[i].reason;
        EXPECT_NEAR(uncalibrated.frames[i].cov_xx - unknown.frames[i].cov_xx, 0.045 * 0.045, 0.0005)
            << i;
        EXPECT_NEAR(uncalibrated.frames[i].cov_yy - unknown.frames[i].cov_yy, 0.0, 0.001) << i;
        EXPECT_NEAR(calibrated.frames[i].cov_xx, unknown.frames[i].cov_xx, 1e-6) << i;
        // The track itself is the same: its fixes and predictions share the vehicle's clock.
        EXPECT_EQ(uncalibrated.frames[i].x, unknown.frames[i].x) << i;
    }
}

// Against a database whose survey camera clock is unknown (sigma 0.05 s, past
// survey_clock_max_sigma_s) the references' lateness is taken as the vehicle's: driving as they
// were driven (2.5 m/s along x) at 3 m/s leaves (0.5 m/s x 0.05 s)^2 along the motion; driving
// against them (-3 m/s) leaves (5.5 m/s x 0.05 s)^2, which no ellipse may leave out.
TEST(Localize, AgainstAnUnknownSurveyClockTheUnsharedLatenessWidensThePose) {
    const auto run = [&](const std::string& name, std::optional<double> survey_sigma_s,
                         bool against) {
        const auto dir = lookup::test::freshDir("lookup_localize_unshared_" + name);
        PlanarDrive drive;
        drive.survey_camera.time_offset_sigma_s = survey_sigma_s;
        if (against) {
            drive.vehicle = [](int i) {
                return mrpt::poses::CPose3D(3 - 0.3 * i, 0.3, 0, M_PI + 0.05, 0, 0);
            };
            drive.coarse_error = mrpt::poses::CPose3D(0.3, -0.2, 0, -0.03, 0, 0);
            drive.camera_ahead = mrpt::poses::CPose3D(3.0, 0, 0, 0, 0, 0);
        }
        auto req = planarRun(
            dir, [](int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&) {}, 8,
            drive);
        localize::runLocalization(req);
        return eval::loadRun(req.out_dir);
    };
    for (const bool against : {false, true}) {
        const std::string way = against ? "against" : "along";
        const auto none = run(way + "_none", std::nullopt, against);
        const auto unknown = run(way + "_unknown", 0.05, against);
        const auto known = run(way + "_known", 0.004, against);
        const double w = against ? 5.5 : 0.5;
        for (int i = 3; i < 8; ++i) {
            ASSERT_EQ(unknown.frames[i].status, "refined") << way << unknown.frames[i].reason;
            const double along = unknown.frames[i].cov_xx - none.frames[i].cov_xx;
            EXPECT_NEAR(along, std::pow(w * 0.05, 2), 0.15 * std::pow(w * 0.05, 2)) << way << i;
            EXPECT_NEAR(unknown.frames[i].cov_yy - none.frames[i].cov_yy, 0.0, 0.002) << way << i;
            EXPECT_EQ(unknown.frames[i].x, none.frames[i].x) << way << i;
            // A known survey clock has the vehicle's own uncalibrated lateness instead.
            EXPECT_NEAR(known.frames[i].cov_xx - none.frames[i].cov_xx, std::pow(3 * 0.015, 2),
                        0.0005)
                << way << i;
        }
    }
}

TEST(Localize, PastTheTrackingGapOdometryFromTheLastFixStaysTheFallback) {
    const auto dir = lookup::test::freshDir("lookup_localize_dead_reckoning");
    // From frame 5 on (1.5 s, past the 1 s tracking gap) a ceiling too flat to match, as in a
    // place the survey never entered; the coarse poses are 0.72 m off with their 2 m sigma.
    const int frames = 20;
    auto req = planarRun(
        dir,
        [](int i, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry&) {
            if (i < 5) return;
            img.image = mrpt::img::CImage(cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)),
                                          mrpt::img::DEEP_COPY);
        },
        frames);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), std::size_t(frames));
    ASSERT_EQ(run.frames[4].status, "refined") << run.frames[4].reason;
    // Dead reckoning starts from the fix as uncertain as it was, then odometry adds its own
    // (0.05 m + 0.05 m per metre, 0.3 m driven).
    const double odometry_sigma = 0.05 + 0.05 * 0.3;
    EXPECT_GE(run.frames[5].cov_xx, run.frames[4].cov_xx + 0.99 * odometry_sigma * odometry_sigma);
    for (int i = 16; i < frames; ++i) {  // more than 1 s after the last fix
        const auto& f = run.frames[i];
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        EXPECT_LT(offDefaultDrive(f, i), 0.1) << i;
        EXPECT_LT(f.cov_xx, 1.0) << i;  // not the coarse pose's 2 m
    }
}

// Lost for longer than the tracking gap with no coarse stage to seed a search (a stretch of
// ceiling too flat to match, frames 5-15), while a wheel slips 0.6 m: where the ceiling can be
// matched again, the search along the dead reckoning finds the vehicle at the next frame.
TEST(Localize, PastTheTrackingGapTheSearchFollowsTheDeadReckoning) {
    const auto dir = lookup::test::freshDir("lookup_localize_dead_reckoning_search");
    const int frames = 22;
    auto req = planarRun(
        dir,
        [](int i, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry& odo) {
            if (i >= 10) odo.odometry.x(odo.odometry.x() + 0.6);
            if (i < 5 || i > 15) return;
            img.image = mrpt::img::CImage(cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)),
                                          mrpt::img::DEEP_COPY);
        },
        frames);
    // Coarse poses for the first fix only: after it nothing else would seed a search.
    auto coarse = common::readPoseFile(req.coarse_poses);
    coarse.resize(5);
    common::writeTumPoseFile(req.coarse_poses, coarse);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), std::size_t(frames));
    ASSERT_EQ(run.frames[15].status, "fallback") << run.frames[15].reason;
    for (int i = 16; i < frames; ++i) {
        const auto& f = run.frames[i];
        ASSERT_EQ(f.status, "refined") << i << ": " << f.reason;
        EXPECT_LT(offDefaultDrive(f, i), 0.05) << i;
    }
}

TEST(Localize, RunsAreNamedAfterTheirSamplerAndMatcher) {
    refine::RefinerOptions o;
    o.sampler.mode = refine::SamplingMode::Auto;
    EXPECT_EQ(localize::defaultMethodName(o, false), "lookup-grid24");
    EXPECT_EQ(localize::defaultMethodName(o, true), "lookup-fcn12");
    o.sampler.mode = refine::SamplingMode::Grid;
    o.sampler.grid_points = 30;
    EXPECT_EQ(localize::defaultMethodName(o, true), "lookup-grid30");
    o.sampler.mode = refine::SamplingMode::HeatMap;
    o.sampler.heat_map_points = 8;
    EXPECT_EQ(localize::defaultMethodName(o, false), "lookup-fcn8");
    o.correspondence.method = refine::CorrespondenceMethod::Ecc;
    EXPECT_EQ(localize::defaultMethodName(o, true), "lookup-ecc");
}

TEST(Localize, CoarseStageMatchesEachSurveyTraverseAsItsOwnSequence) {
    // "long" has more references, so a coarse stage fed one traverse by size would never see
    // the query's own ("short").
    const auto db = twoForwardTraverses("traverses");
    coarse::CoarseOptions options;  // sequence_length 30
    auto source = localize::makeSequenceCoarseSource(db, options, "");

    // The query re-drives "short": its views plus a little sensor noise.
    int usable = 0, on_short = 0, at_the_right_frame = 0;
    for (int k = 0; k < 40; ++k) {
        auto view = forwardView(2, k, 900.0 + 0.1 * k);
        cv::Mat noisy = view->image.asCvMat<cv::Mat>(mrpt::img::SHALLOW_COPY).clone();
        cv::Mat noise(noisy.size(), CV_8UC1);
        cv::randu(noise, 0, 6);
        noisy += noise;
        view->image = mrpt::img::CImage(noisy, mrpt::img::DEEP_COPY);
        coarse::CoarseQuery q;
        q.time_s = 900.0 + 0.1 * k;
        q.forward_image = &view->image;
        const auto r = source->locate(q);
        if (!r.usable()) continue;
        ++usable;
        const auto& ref = db.reference(r.reference_index);
        on_short += ref.traverse == "short";
        // References of "short" were written after the 60 of "long", one per frame.
        at_the_right_frame +=
            ref.traverse == "short" && std::abs(static_cast<int>(r.reference_index) - 60 - k) <= 1;
    }
    EXPECT_GE(usable, 8);  // from the 30th frame on
    EXPECT_EQ(on_short, usable);
    EXPECT_EQ(at_the_right_frame, usable);

    // Naming a traverse restricts the coarse stage to it.
    auto only_long = localize::makeSequenceCoarseSource(db, options, "long");
    EXPECT_EQ(only_long->name().find('+'), std::string::npos);
    EXPECT_THROW(localize::makeSequenceCoarseSource(db, options, "absent"), std::runtime_error);
}

TEST(Localize, AcquisitionCandidatesCoverEveryNearbyTraverse) {
    // Two traverses 0.4 m apart, closer than acquisition_step_m (0.5 m): thinned together, the
    // nearer one would shadow the other, and a query driving beside the farther one would get
    // candidates only 0.4 m further off, beyond the SAD window (mine-a query4 start-up).
    const Scene scene;
    const auto dir = lookup::test::freshDir("lookup_localize_candidates");
    writeDatabase(scene, (dir / "db").string(),
                  {{"near", 40, 100.0, 0, /*y_m=*/0.0}, {"far", 40, 200.0, 0, /*y_m=*/0.4}});
    auto db = database::ReferenceDatabase::load((dir / "db").string());
    localize::LocalizerOptions options;
    options.acquisition_radius_m = 2.0;
    options.acquisition_step_m = 0.5;
    const localize::Localizer localizer(db, options, refine::RefinerOptions{}, nullptr, false);

    const auto candidates = localizer.acquisitionCandidates(mrpt::poses::CPose2D(-4.0, 0.0, 0));
    std::map<std::string, std::vector<double>> along;  // x of the candidates, per traverse
    for (std::size_t i : candidates) {
        const auto& ref = db.reference(i);
        EXPECT_LE(std::hypot(ref.vehicle_pose.x() + 4.0, ref.vehicle_pose.y()), 2.0 + 1e-9);
        along[ref.traverse].push_back(ref.vehicle_pose.x());
    }
    ASSERT_EQ(along.size(), 2u);
    for (auto& [name, xs] : along) {
        std::sort(xs.begin(), xs.end());
        // References 0.25 m apart thinned to >= 0.5 m: every other one, across the whole disc.
        EXPECT_GE(xs.size(), 6u) << name;
        for (std::size_t k = 1; k < xs.size(); ++k) {
            EXPECT_GE(xs[k] - xs[k - 1], 0.5 - 1e-9) << name;
            EXPECT_LE(xs[k] - xs[k - 1], 0.75 + 1e-9) << name;  // no gap beyond the thinning
        }
    }
    // The nearest reference comes first.
    ASSERT_FALSE(candidates.empty());
    EXPECT_NEAR(db.reference(candidates.front()).vehicle_pose.x(), -4.0, 1e-9);
    EXPECT_NEAR(db.reference(candidates.front()).vehicle_pose.y(), 0.0, 1e-9);
}

TEST(Localize, TheCameraClockIsAppliedWhereItStandsOutOfTheSurveysOwnClock) {
    // The references carry the survey camera's lateness: against a database whose survey clock
    // is known (db.ini) the vehicle's estimate is applied as it is; against one known only to a
    // larger sigma, that sigma is what the estimate must stand out of; without one, not at all,
    // unless forced either way.
    const Scene scene;
    const auto dir = lookup::test::freshDir("lookup_localize_camera_clock");
    using Apply = localize::CameraClockApply;
    struct Case {
        std::optional<double> survey_sigma_s;
        Apply apply;
        bool applies;
        double contamination_s;
    };
    for (const Case& c :
         {Case{0.004, Apply::Auto, true, 0.0}, Case{0.012, Apply::Auto, true, 0.012},
          Case{std::nullopt, Apply::Auto, false, 0.0}, Case{std::nullopt, Apply::Always, true, 0.0},
          Case{0.004, Apply::Never, false, 0.0}}) {
        const std::string db_dir = (dir / "db").string();
        fs::remove_all(db_dir);
        SurveyCamera survey;
        survey.time_offset_sigma_s = c.survey_sigma_s;
        writeDatabase(scene, db_dir, {{"survey", 4, 100.0}}, survey);
        auto db = database::ReferenceDatabase::load(db_dir);
        localize::LocalizerOptions options;
        options.apply_camera_time_offset = c.apply;
        const localize::Localizer localizer(db, options, refine::RefinerOptions{}, nullptr, false);
        EXPECT_EQ(localizer.cameraClock().applies(), c.applies)
            << "survey sigma " << c.survey_sigma_s.value_or(-1) << ", mode " << int(c.apply);
        EXPECT_DOUBLE_EQ(localizer.cameraClock().contamination(), c.contamination_s);
    }
}

TEST(Localize, SkippedCoarseSearchesStillBuildTheSequence) {
    // coarse_while_tracking = false: while LookUP tracks, forward frames only join the coarse
    // sequence. The first frame searched must match at once (a full sequence), not start over.
    const auto db = twoForwardTraverses("skipped_search");
    coarse::CoarseOptions options;  // sequence_length 30
    auto source = localize::makeSequenceCoarseSource(db, options, "");
    for (int k = 0; k < 36; ++k) {
        const auto view = forwardView(2, k, 900.0 + 0.1 * k);
        coarse::CoarseQuery q;
        q.time_s = 900.0 + 0.1 * k;
        q.forward_image = &view->image;
        q.search = k >= 32;
        const auto r = source->locate(q);
        if (k < 32) {
            EXPECT_EQ(r.status, coarse::CoarseStatus::NotSearched) << "frame " << k;
            EXPECT_FALSE(r.usable());
            EXPECT_EQ(r.evaluated_references, 0u);
            continue;
        }
        ASSERT_TRUE(r.usable()) << "frame " << k << ": " << r.reason;
        // The first search after skipped frames is global (the last match went stale).
        if (k == 32) {
            EXPECT_EQ(r.status, coarse::CoarseStatus::Global);
        }
        EXPECT_EQ(db.reference(r.reference_index).traverse, "short");
        EXPECT_LE(std::abs(static_cast<int>(r.reference_index) - 60 - k), 1) << "frame " << k;
    }
}

TEST(Localize, MissingDatabaseAndRawlogWithoutCeilingImagesAreRefused) {
    const auto dir = lookup::test::freshDir("lookup_localize_bad");
    localize::LocalizeRequest req;
    req.db_dir = (dir / "nodb").string();
    req.rawlog = (dir / "q.rawlog").string();
    req.out_dir = (dir / "run").string();
    req.progress = false;
    EXPECT_THROW(localize::runLocalization(req), std::exception);

    Scene scene;
    writeDatabase(scene, (dir / "db").string(), {{"survey", 65, 100.0}});  // x = -8 .. 8
    {
        common::RawlogWriter rawlog(req.rawlog);
        mrpt::obs::CObservationOdometry odo;
        odo.sensorLabel = "ODOMETRY";
        rawlog.write(odo);
        rawlog.close();
    }
    req.db_dir = (dir / "db").string();
    common::writeTumPoseFile((dir / "coarse.tum").string(),
                             {{kT0, mrpt::poses::CPose3D()}, {kT0 + 1, mrpt::poses::CPose3D()}});
    req.coarse_poses = (dir / "coarse.tum").string();
    try {
        localize::runLocalization(req);
        FAIL() << "a rawlog without ceiling images was accepted";
    } catch (const std::exception& e) {
        EXPECT_NE(std::string(e.what()).find("q.rawlog"), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("CEILING_CAM"), std::string::npos) << e.what();
    }
}

namespace {

struct FrameRow {
    std::string status;
    double x = 0, y = 0;
};

std::vector<FrameRow> readFrames(const fs::path& run) {
    std::ifstream in(run / "frames.csv");
    std::string line;
    std::getline(in, line);  // header: time_s,status,reason,x,y,...
    std::vector<FrameRow> rows;
    while (std::getline(in, line)) {
        // The reason may hold commas only inside quotes; split the first fields by hand.
        std::vector<std::string> fields;
        std::string field;
        bool quoted = false;
        for (char ch : line) {
            if (ch == '"') quoted = !quoted;
            if (ch == ',' && !quoted) {
                fields.push_back(field);
                field.clear();
            } else {
                field += ch;
            }
        }
        fields.push_back(field);
        FrameRow r;
        r.status = fields.at(1);
        if (r.status == "refined") {
            r.x = std::stod(fields.at(3));
            r.y = std::stod(fields.at(4));
        }
        rows.push_back(r);
    }
    return rows;
}

// A query re-driving the survey line 0.1 m to its left from reference 10 on, one ceiling and
// one forward frame per reference; the ceiling from `ceiling` (the survey's, or another).
void writeStartUpQuery(const Scene& ceiling, const fs::path& path, int frames,
                       bool odometry = false) {
    common::RawlogWriter rawlog(path.string());
    for (int k = 0; k < frames; ++k) {
        const double t = kT0 + 0.1 * k;
        if (odometry) {
            mrpt::obs::CObservationOdometry odo;
            odo.sensorLabel = "ODOMETRY";
            odo.timestamp = mrpt::Clock::fromDouble(t);
            odo.odometry = mrpt::poses::CPose2D(-8 + 0.25 * (k + 10), 0.1, 0);
            rawlog.write(odo);
        }
        auto forward = forwardView(1, k + 10, t);
        rawlog.writeWithExternalImage(*forward, "forward_" + std::to_string(k) + ".png");
        const mrpt::poses::CPose3D vehicle(-8 + 0.25 * (k + 10), 0.1, 0, 0, 0, 0);
        auto img = ceiling.image(vehicle, t);
        rawlog.writeWithExternalImage(*img, "ceiling_" + std::to_string(k) + ".png");
    }
    rawlog.close();
}

}  // namespace

TEST(Localize, StartUpAcquisitionFixesBeforeTheCoarseSequenceIsFullAndOnlyOnTheRightCeiling) {
    const Scene scene;
    const auto dir = lookup::test::freshDir("lookup_localize_startup");
    writeDatabase(scene, (dir / "db").string(), {{"survey", 65, 100.0, /*forward_seed=*/1}});
    writeStartUpQuery(scene, dir / "query.rawlog", 32);

    localize::LocalizeRequest req;
    req.db_dir = (dir / "db").string();
    req.rawlog = (dir / "query.rawlog").string();
    req.sampling = "grid";
    req.progress = false;
    const auto firstRefined = [](const std::vector<FrameRow>& rows) {
        for (std::size_t k = 0; k < rows.size(); ++k) {
            if (rows[k].status == "refined") return int(k);
        }
        return -1;
    };

    // Default (startup_acquisition_frames = 5): refined from the 5th frame, on the truth.
    req.out_dir = (dir / "run").string();
    localize::runLocalization(req);
    const auto rows = readFrames(req.out_dir);
    ASSERT_EQ(rows.size(), 32u);
    EXPECT_EQ(firstRefined(rows), 4);
    for (std::size_t k = 4; k < rows.size(); ++k) {
        ASSERT_EQ(rows[k].status, "refined") << "frame " << k;
        EXPECT_NEAR(rows[k].x, -8 + 0.25 * (k + 10), 0.03) << "frame " << k;
        EXPECT_NEAR(rows[k].y, 0.1, 0.03) << "frame " << k;
    }

    // Off: nothing before the coarse sequence is full (sequence_length = 30 frames).
    std::ofstream(dir / "off.ini") << "[localizer]\nstartup_acquisition_frames = 0\n";
    req.ini_file = (dir / "off.ini").string();
    req.out_dir = (dir / "run_off").string();
    localize::runLocalization(req);
    EXPECT_EQ(firstRefined(readFrames(req.out_dir)), 29);

    // The same forward views over another ceiling: the seeds point at the right place, but the
    // ceiling there does not match, so no start-up frame may become a fix.
    Scene other;
    other.ceiling = refine::synthetic::SyntheticCeiling::make(kCeilingHeight, 40.0, 0.01, 99);
    writeStartUpQuery(other, dir / "other.rawlog", 12);
    req.ini_file.clear();
    req.rawlog = (dir / "other.rawlog").string();
    req.out_dir = (dir / "run_other").string();
    localize::runLocalization(req);
    const auto other_rows = readFrames(req.out_dir);
    ASSERT_EQ(other_rows.size(), 12u);
    EXPECT_EQ(firstRefined(other_rows), -1);
    EXPECT_EQ(other_rows.back().status, "lost");
}

TEST(Localize, NonFiniteOrGarbageObservationsAreSkippedAndCountedNeverPoses) {
    const auto dir = lookup::test::freshDir("lookup_localize_garbage");
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const auto req = planarRun(
        dir, [&](int i, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry& odo) {
            if (i == 5) odo.odometry.x(nan);
            if (i == 8) {
                odo.hasVelocities = true;
                odo.velocityLocal.vx = std::numeric_limits<double>::infinity();
            }
            if (i == 11) odo.odometry.y(1e300);
            if (i == 14) img.cameraParams.fx(nan);
            if (i == 16) img.image = mrpt::img::CImage();
        });
    const auto timing = localize::runLocalization(req);
    EXPECT_EQ(timing.frames, 18u);  // two ceiling frames refused
    EXPECT_EQ(timing.skipped.at("odometry_not_finite"), 3u);
    EXPECT_EQ(timing.skipped.at("intrinsics_invalid"), 1u);
    EXPECT_EQ(timing.skipped.at("image_unusable"), 1u);
    EXPECT_EQ(nonFiniteLines(fs::path(req.out_dir) / "frames.csv", 1), 0u);
    EXPECT_EQ(nonFiniteLines(fs::path(req.out_dir) / "poses.tum", 0), 0u);
    std::ifstream in(fs::path(req.out_dir) / "timing.json");
    const auto j = nlohmann::json::parse(in);
    EXPECT_EQ(j.at("skipped").at("odometry_not_finite").get<int>(), 3);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), 18u);
    std::size_t refined = 0;
    for (const auto& f : run.frames) refined += f.status == "refined";
    EXPECT_GE(refined, 16u);  // the good frames around the garbage still refine
}

TEST(Localize, AQueryCameraOfAnotherSizeAndFocalLengthIsRectifiedIntoTheDatabases) {
    const auto dir = lookup::test::freshDir("lookup_localize_other_camera");
    const auto req = planarRun(
        dir, [&](int, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry&) {
            cv::Mat m;
            cv::resize(img.image.asCvMat<cv::Mat>(mrpt::img::SHALLOW_COPY), m, cv::Size(256, 192),
                       0, 0, cv::INTER_AREA);
            img.image = mrpt::img::CImage(m, mrpt::img::DEEP_COPY);
            img.cameraParams.scaleToResolution(256, 192);
        });
    const auto timing = localize::runLocalization(req);
    EXPECT_EQ(timing.frames, 20u);
    EXPECT_TRUE(timing.skipped.empty());
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), 20u);
    std::size_t refined = 0;
    for (const auto& f : run.frames) refined += f.status == "refined";
    EXPECT_GE(refined, 18u);
}

TEST(Localize, QueryIntrinsicsThatCannotDescribeTheImageAreRefusedNamingTheRecord) {
    const auto dir = lookup::test::freshDir("lookup_localize_bad_intrinsics");
    const auto req = planarRun(
        dir, [&](int i, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry&) {
            if (i == 4) img.cameraParams.ncols = 640;  // the calibration of another resolution
            if (i == 7) img.cameraParams.distortion = static_cast<mrpt::img::DistortionModel>(7);
            if (i == 9) img.cameraParams.dist[4] = std::numeric_limits<double>::infinity();
        });
    testing::internal::CaptureStderr();
    const auto timing = localize::runLocalization(req);
    const std::string err = testing::internal::GetCapturedStderr();
    EXPECT_EQ(timing.frames, 17u);
    EXPECT_EQ(timing.skipped.at("image_size"), 1u);
    EXPECT_EQ(timing.skipped.at("intrinsics_invalid"), 2u);
    for (const char* expected : {"intrinsics are for 640x", "distortion model 7 is not one MRPT",
                                 "dist[4] = inf is not finite", "query.rawlog"}) {
        EXPECT_NE(err.find(expected), std::string::npos) << expected << " not in: " << err;
    }
}

namespace {

// runLocalization's error message, or "" when it ran.
std::string errorOf(const localize::LocalizeRequest& req) {
    try {
        localize::runLocalization(req);
    } catch (const std::exception& e) {
        return e.what();
    }
    return {};
}

}  // namespace

TEST(Localize, RunsThatCannotWorkAreRefusedAtTheStartWithTheReason) {
    const auto dir = lookup::test::freshDir("lookup_localize_cannot_work");
    auto req = planarRun(dir, [](int, auto&, auto&) {});

    // Query ceiling images of another size than their intrinsics say (another size than the
    // references' with intrinsics to match is rectified into the database's camera).
    const auto half = lookup::test::freshDir("lookup_localize_cannot_work_size");
    auto small = planarRun(half, [](int, mrpt::obs::CObservationImage& img, auto&) {
        cv::Mat m;
        cv::resize(img.image.asCvMat<cv::Mat>(mrpt::img::SHALLOW_COPY), m, cv::Size(160, 120));
        img.image = mrpt::img::CImage(m, mrpt::img::DEEP_COPY);
    });
    std::string e = errorOf(small);
    EXPECT_NE(e.find("ceiling images are 160x120, expected 320x240 (their intrinsics' size)"),
              std::string::npos)
        << e;

    // Coarse poses of another drive: no overlap with the query's time span.
    common::writeTumPoseFile((dir / "other.tum").string(), {{kT0 + 500, mrpt::poses::CPose3D()},
                                                            {kT0 + 510, mrpt::poses::CPose3D()}});
    auto other = req;
    other.coarse_poses = (dir / "other.tum").string();
    e = errorOf(other);
    EXPECT_NE(e.find("other.tum covers"), std::string::npos) << e;
    EXPECT_NE(e.find("no overlap"), std::string::npos) << e;

    // No <name>_Images folder beside the rawlog.
    fs::rename(dir / "query_Images", dir / "moved_Images");
    e = errorOf(req);
    EXPECT_NE(e.find("query_Images does not exist"), std::string::npos) << e;
    fs::rename(dir / "moved_Images", dir / "query_Images");
    EXPECT_EQ(errorOf(req), "");
    EXPECT_FALSE(fs::exists(req.out_dir + ".partial"));  // a refused run leaves nothing behind
}

TEST(Localize, AForwardCameraLabelWithoutImagesIsRefusedNamingThePresentLabels) {
    const Scene scene;
    const auto dir = lookup::test::freshDir("lookup_localize_forward_label");
    writeDatabase(scene, (dir / "db").string(), {{"survey", 65, 100.0, /*forward_seed=*/1}});
    writeStartUpQuery(scene, dir / "query.rawlog", 8);
    std::ofstream(dir / "label.ini") << "[localizer]\nforward_camera_label = FRONT_CAM\n";
    localize::LocalizeRequest req;
    req.db_dir = (dir / "db").string();
    req.rawlog = (dir / "query.rawlog").string();
    req.out_dir = (dir / "run").string();
    req.ini_file = (dir / "label.ini").string();
    req.progress = false;
    const std::string e = errorOf(req);
    EXPECT_NE(e.find("'FRONT_CAM'"), std::string::npos) << e;
    EXPECT_NE(e.find("FORWARD_CAM (mrpt::obs::CObservationImage)"), std::string::npos) << e;
    EXPECT_NE(e.find("forward_camera_label"), std::string::npos) << e;
}

TEST(Localize, RepeatedPassesRefineAsTheFirstOneDoes) {
    const Scene scene;
    const auto dir = lookup::test::freshDir("lookup_localize_repeat_passes");
    writeDatabase(scene, (dir / "db").string(), {{"survey", 65, 100.0, /*forward_seed=*/1}});
    writeStartUpQuery(scene, dir / "query.rawlog", 32, /*odometry=*/true);
    localize::LocalizeRequest req;
    req.db_dir = (dir / "db").string();
    req.rawlog = (dir / "query.rawlog").string();
    req.out_dir = (dir / "run").string();
    req.sampling = "grid";
    req.progress = false;
    req.repeat = 3;
    EXPECT_EQ(localize::runLocalization(req).frames, 96u);
    const auto rows = readFrames(req.out_dir);
    ASSERT_EQ(rows.size(), 96u);
    int refined[3] = {0, 0, 0};
    for (std::size_t k = 0; k < rows.size(); ++k) refined[k / 32] += rows[k].status == "refined";
    EXPECT_GE(refined[0], 27);
    EXPECT_NEAR(refined[1], refined[0], 2);  // within a few points of pass 1
    EXPECT_NEAR(refined[2], refined[0], 2);
}

namespace {

// The planar drive with each ceiling image read by a rolling shutter (`readout_s`, stamped at
// the first row) while the vehicle drives at 3 m/s; localised with `ini` (its text).
struct RollingRun {
    localize::RunTiming timing;
    double mean_error_m = 0;
    std::size_t refined = 0;
};

RollingRun rollingShutterRun(const std::string& name, double readout_s, const std::string& ini) {
    const auto dir = lookup::test::freshDir("lookup_localize_" + name);
    const Scene scene;
    refine::RowTiming timing;
    timing.readout_s = readout_s;
    // planarRun: 0.3 m per 0.1 s along the map's x, the vehicle turned by 0.05 rad.
    timing.velocity = {3.0 * std::cos(0.05), -3.0 * std::sin(0.05), 0.0};
    auto req = planarRun(
        dir, [&](int, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry& odo) {
            const mrpt::poses::CPose3D vehicle(odo.odometry);
            img.image = mrpt::img::CImage(
                scene.ceiling.renderRollingShutter(scene.camera, scene.mount, vehicle, timing),
                mrpt::img::DEEP_COPY);
        });
    if (!ini.empty()) {
        req.ini_file = (dir / "options.ini").string();
        std::ofstream(req.ini_file) << ini;
    }
    RollingRun out;
    out.timing = localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    for (const auto& f : run.frames) {
        if (f.status != "refined") continue;
        const int i = int(std::lround((f.time_s - kT0) / 0.1));
        out.mean_error_m += offDefaultDrive(f, i);
        ++out.refined;
    }
    if (out.refined > 0) out.mean_error_m /= double(out.refined);
    return out;
}

}  // namespace

TEST(Localize, ARollingShutterQueryIsRefinedRowByRowWithTheOdometrysVelocity) {
    // 60 ms readout at 3 m/s: 0.18 m between the first and the last row.
    const auto without = rollingShutterRun("rolling_without", 0.060, "");
    const auto with =
        rollingShutterRun("rolling_with", 0.060, "[refine.rolling_shutter]\nreadout_ms = 60\n");
    EXPECT_GE(with.refined, 18u);
    EXPECT_LT(with.mean_error_m, 0.01);     // the first frame has no velocity yet: 5 mm of it
    EXPECT_GT(without.mean_error_m, 0.05);  // the stamp's pose is the first row's
    // A readout longer than the 100 ms frame period is a wrong setting: every frame after the
    // first is refused, and counted.
    const auto refused =
        rollingShutterRun("rolling_refused", 0.060, "[refine.rolling_shutter]\nreadout_ms = 150\n");
    EXPECT_EQ(refused.timing.skipped.at("readout_exceeds_frame_period"), 19u);
}

namespace {

// A drive along the vehicle's heading speeding up from 0.5 to 4 m/s and braking again, its
// ceiling camera a rolling shutter of 60 ms stamped at the first row, over a database whose
// survey camera clock is known to `survey_clock_sigma_s` (none: not known) and whose camera
// read its rows in `survey_readout_s` (not recorded) at the survey's 2.5 m/s; localised with
// `ini`. Returns the mean error of the last 15 frames and the run's timing.
std::pair<double, localize::RunTiming> varyingSpeedRollingRun(
    const std::string& name, const std::string& ini,
    std::optional<double> survey_clock_sigma_s = 0.005, double survey_readout_s = 0) {
    constexpr int kFrames = 40;
    constexpr double kHeading = 0.05;
    std::vector<double> speed, travelled{0.0};
    for (int i = 0; i < kFrames; ++i) {
        speed.push_back(0.5 + 3.5 * std::sin(M_PI * i / kFrames));
        travelled.push_back(travelled.back() + 0.1 * speed.back());
    }
    const auto pose = [&](int i) {
        return mrpt::poses::CPose3D(-5 + travelled[i] * std::cos(kHeading),
                                    0.4 + travelled[i] * std::sin(kHeading), 0, kHeading, 0, 0);
    };
    const auto dir = lookup::test::freshDir("lookup_localize_" + name);
    const Scene scene;
    PlanarDrive drive;
    drive.vehicle = pose;
    drive.survey_camera.time_offset_sigma_s = survey_clock_sigma_s;
    drive.survey_camera.timing.readout_s = survey_readout_s;
    drive.survey_camera.timing.velocity = {2.5, 0.0, 0.0};
    auto req = planarRun(
        dir,
        [&](int i, mrpt::obs::CObservationImage& img, mrpt::obs::CObservationOdometry&) {
            refine::RowTiming timing;
            timing.readout_s = 0.060;
            timing.velocity = {speed[i], 0.0, 0.0};
            img.image = mrpt::img::CImage(
                scene.ceiling.renderRollingShutter(scene.camera, scene.mount, pose(i), timing),
                mrpt::img::DEEP_COPY);
        },
        kFrames, drive);
    req.ini_file = (dir / "options.ini").string();
    std::ofstream(req.ini_file) << ini;
    const auto timing = localize::runLocalization(req);
    double sum = 0;
    int n = 0;
    for (const auto& f : eval::loadRun(req.out_dir).frames) {
        const int i = int(std::lround((f.time_s - kT0) / 0.1));
        if (i < kFrames - 15 || f.status != "refined") continue;
        sum += std::hypot(f.x - pose(i).x(), f.y - pose(i).y());
        ++n;
    }
    EXPECT_GE(n, 12);
    return {n > 0 ? sum / n : 1e9, timing};
}

}  // namespace

TEST(Localize, AnUnconfiguredRollingShutterIsEstimatedFromTheRowsAndApplied) {
    // Up to 4 m/s x 60 ms: the rows' mean exposure 0.12 m past the stamp's pose.
    const std::string estimating =
        "[localizer]\nreadout_min_frames = 20\nreadout_max_sigma_s = 0.005\n";
    const auto [unmodelled_m, unmodelled] =
        varyingSpeedRollingRun("rolling_unmodelled", "[localizer]\nestimate_readout = false\n");
    const auto [estimated_m, estimated] = varyingSpeedRollingRun("rolling_estimated", estimating);
    EXPECT_TRUE(unmodelled.readout.empty());
    ASSERT_EQ(estimated.readout.count("query_applied_s"), 1u);
    EXPECT_NEAR(estimated.readout.at("query_applied_s"), 0.060, 0.008);
    EXPECT_NEAR(estimated.readout.at("survey_applied_s"), 0.0, 1e-12);  // a global shutter
    EXPECT_GT(unmodelled_m, 0.05);
    EXPECT_LT(estimated_m, 0.02);
    // Against a survey whose camera clock is not known, the vehicle's readout is applied where
    // the survey's camera shows none (a global shutter)...
    const auto [unknown_m, unknown] =
        varyingSpeedRollingRun("rolling_unknown_clock", estimating, std::nullopt);
    EXPECT_NEAR(unknown.readout.at("query_applied_s"), 0.060, 0.008);
    EXPECT_LT(unknown_m, 0.02);
    // ... and not where the survey's camera read its rows alike: its half readout is part of
    // the lateness that the references and the vehicle share, and cancels with the vehicle's.
    const auto [alike_off_m, alike_off] = varyingSpeedRollingRun(
        "rolling_alike_off", "[localizer]\nestimate_readout = false\n", std::nullopt, 0.060);
    const auto [alike_m, alike] =
        varyingSpeedRollingRun("rolling_alike", estimating, std::nullopt, 0.060);
    EXPECT_NEAR(alike.readout.at("query_s"), 0.060, 0.008);
    EXPECT_NEAR(alike.readout.at("survey_s"), 0.060, 0.008);
    EXPECT_EQ(alike.readout.at("query_applied_s"), 0.0);
    EXPECT_EQ(alike.readout.at("survey_applied_s"), 0.0);
    EXPECT_NEAR(alike_m, alike_off_m, 1e-9);
}

TEST(Localize, RollingShutterReferencesAreSeenFromTheSurveyVehiclesRowPoses) {
    // The survey camera read its rows in 60 ms while the survey vehicle drove at 2.5 m/s
    // (references 0.25 m and 0.1 s apart); the query camera is a global shutter.
    const auto dir = lookup::test::freshDir("lookup_localize_rolling_references");
    const Scene scene;
    auto req =
        planarRun(dir, [](int, mrpt::obs::CObservationImage&, mrpt::obs::CObservationOdometry&) {});
    refine::RowTiming timing;
    timing.readout_s = 0.060;
    timing.velocity = {2.5, 0.0, 0.0};
    const auto writeDb = [&](const std::string& name, double stored_readout_ms) {
        writeDatabase(scene, (dir / name).string(), {{"survey", 65, 100.0}},
                      {timing, stored_readout_ms, std::nullopt});
        EXPECT_EQ(database::readDatabaseInfo((dir / name / "db.ini").string()).ceiling_readout_ms,
                  stored_readout_ms);
    };
    const auto meanError = [&](const std::string& name) {
        req.db_dir = (dir / name).string();
        req.out_dir = (dir / ("run_" + name)).string();
        localize::runLocalization(req);
        double sum = 0;
        std::size_t n = 0;
        for (const auto& f : eval::loadRun(req.out_dir).frames) {
            if (f.status != "refined") continue;
            const int i = int(std::lround((f.time_s - kT0) / 0.1));
            sum += offDefaultDrive(f, i);
            ++n;
        }
        EXPECT_GE(n, 18u);
        return n > 0 ? sum / double(n) : 1e9;
    };
    writeDb("db_recorded", 60);
    writeDb("db_unrecorded", 0);
    EXPECT_LT(meanError("db_recorded"), 0.01);
    EXPECT_GT(meanError("db_unrecorded"), 0.03);
}

// A ceiling camera that never gives a fix (flat images: a covered lens, a dead lamp) leaves
// only the coarse stage's place, which in tunnels that alias may be tens of metres off with
// nothing to say so: no pose is reported, and the coarse match stays in its own columns. Once
// a fix was made, the odometry carries on from it, its ellipse growing, past the few metres a
// coarse place could claim.
TEST(Localize, ACoarseMatchTheCeilingNeverConfirmedIsNoPose) {
    const auto flat = [](mrpt::obs::CObservationImage& img) {
        img.image =
            mrpt::img::CImage(cv::Mat(240, 320, CV_8UC1, cv::Scalar(128)), mrpt::img::DEEP_COPY);
    };
    const auto never = lookup::test::freshDir("lookup_localize_coarse_unconfirmed");
    auto req = planarRun(
        never, [&](int, mrpt::obs::CObservationImage& img, auto&) { flat(img); }, 12);
    localize::runLocalization(req);
    const auto run = eval::loadRun(req.out_dir);
    ASSERT_EQ(run.frames.size(), 12u);
    for (const auto& f : run.frames) {
        EXPECT_EQ(f.status, "lost") << f.reason;
        EXPECT_FALSE(f.has_pose);
        EXPECT_TRUE(f.has_coarse);
        EXPECT_NE(f.reason.find("not confirmed by the ceiling"), std::string::npos) << f.reason;
    }

    // A fix at frames 0-3, then the ceiling is lost for the rest of a drive long enough for
    // the dead reckoning's sigma to pass 2 m (the odometry here is exact).
    const auto later = lookup::test::freshDir("lookup_localize_coarse_after_a_fix");
    PlanarDrive drive;
    drive.vehicle = [](int i) { return mrpt::poses::CPose3D(-5 + 1.5 * i, 0.4, 0, 0.05, 0, 0); };
    req = planarRun(
        later,
        [&](int i, mrpt::obs::CObservationImage& img, auto&) {
            if (i >= 4) flat(img);
        },
        60, drive);
    localize::runLocalization(req);
    const auto dead = eval::loadRun(req.out_dir);
    ASSERT_EQ(dead.frames.size(), 60u);
    ASSERT_EQ(dead.frames[3].status, "refined") << dead.frames[3].reason;
    for (int i = 4; i < 60; ++i) {
        const auto& f = dead.frames[i];
        ASSERT_EQ(f.status, "fallback") << i << ": " << f.reason;
        EXPECT_LT(std::hypot(f.x - (-5 + 1.5 * i), f.y - 0.4), 0.2) << i;
    }
    EXPECT_GT(dead.frames.back().cov_xx + dead.frames.back().cov_yy, 2 * 2.0 * 2.0)
        << "the drive never took the dead reckoning past the coarse fallback's sigma";
}

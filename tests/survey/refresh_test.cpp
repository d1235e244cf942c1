// lookup-survey --refresh: an operating drive's images added where the ceiling changed, posed by
// the fixes on both sides and the odometry between them.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "lookup/common/errors.h"
#include "lookup/database/database_writer.h"
#include "lookup/database/reference_database.h"
#include "lookup/eval/run_io.h"
#include "lookup/survey/refresh.h"
#include "lookup/survey/survey_app.h"
#include "survey_fixture.h"

namespace fs = std::filesystem;
using namespace lookup;

namespace {

constexpr double kT0 = 1.7e9;  // the fixture's first stamp

/// A surveyed database along the fixture's corridor: a reference every 0.25 m of the truth,
/// with the fixture's ceiling mount (the survey's images; their pixels do not matter here).
void writeSurveyedDatabase(const std::string& dir, const test::Fixture& f) {
    database::DatabaseWriter w(dir);
    const mrpt::img::TCamera cam = test::fixtureCeilingCamera();
    for (int k = 0; k <= 80; ++k) {
        const double t = 0.25 * k;
        const auto pose = mrpt::poses::CPose3D(test::truePoseAt(t));
        database::ReferenceInput in;
        in.traverse = "survey";
        in.ceiling = mrpt::obs::CObservationImage::Create();
        in.ceiling->sensorLabel = "CEILING_CAM";
        in.ceiling->timestamp = mrpt::Clock::fromDouble(kT0 - 1000 + t);
        in.ceiling->cameraPose = f.ceiling_mount;
        in.ceiling->cameraParams = cam;
        in.ceiling->image = mrpt::img::CImage(test::ceilingTexture(pose + f.ceiling_mount, 80, 60),
                                              mrpt::img::DEEP_COPY);
        if (k % 4 == 0) {  // a forward image 20 ms later, as the survey attaches them
            in.forward = mrpt::obs::CObservationImage::Create();
            in.forward->sensorLabel = "FORWARD_CAM";
            in.forward->timestamp = mrpt::Clock::fromDouble(kT0 - 1000 + t + 0.02);
            in.forward->cameraPose = f.forward_mount;
            in.forward->image =
                mrpt::img::CImage(test::ceilingTexture(pose, 32, 24), mrpt::img::DEEP_COPY);
            in.forward_vehicle_pose = mrpt::poses::CPose3D(test::truePoseAt(t + 0.02));
        }
        in.vehicle_pose = pose;
        in.vehicle_cov.setIdentity();
        in.vehicle_cov *= 1e-4;
        in.travelled_m = t;
        w.add(in);
    }
    database::DatabaseInfo info;
    info.name = "corridor";
    info.ceiling_camera = cam;
    info.ceiling_height_m = 4.0;
    w.commit(info);
}

/// A finished run of the fixture's drive: refined at the truth, except over `unrefined` (s),
/// where the localiser emitted a dead-reckoned pose half a metre off. `far_fix_error_m` moves
/// the first fix after that stretch.
void writeRun(const std::string& dir, const test::Fixture& f, std::pair<double, double> unrefined,
              double far_fix_error_m = 0, double time_shift_s = 0) {
    fs::create_directories(dir);
    std::vector<eval::FrameRow> rows;
    bool after = false;
    for (int k = 0; k < f.frames; ++k) {
        const double t = 0.1 * k;
        const auto truth = test::truePoseAt(t);
        eval::FrameRow row;
        row.time_s = kT0 + t + time_shift_s;
        row.has_pose = true;
        const bool in_stretch = t > unrefined.first && t < unrefined.second;
        row.status = in_stretch ? "fallback" : "refined";
        row.x = truth.x() + (in_stretch ? 0.5 : 0.0);
        row.y = truth.y();
        row.yaw = truth.phi();
        if (!in_stretch && t > unrefined.first && !after) {
            row.x += far_fix_error_m;
            after = true;
        }
        row.cov_xx = row.cov_yy = 1e-4;
        row.cov_tt = 1e-5;
        row.inlier_share = in_stretch ? 0.1 : 0.9;
        row.references = 3;
        rows.push_back(row);
    }
    eval::writeFramesCsv(dir + "/frames.csv", rows);
    std::ofstream(dir + "/timing.json") << "{\"frames\": " << rows.size() << "}\n";
}

struct RefreshCase {
    fs::path dir;
    test::Fixture drive;
    survey::RefreshInputs in;
};

RefreshCase makeCase(const std::string& name, double far_fix_error_m = 0, double time_shift_s = 0) {
    RefreshCase c;
    c.dir = test::freshDir(name);
    c.drive = test::makeSurveyRawlog((c.dir / "drive").string(), "today", 20.0, false);
    writeSurveyedDatabase((c.dir / "db").string(), c.drive);
    writeRun((c.dir / "run").string(), c.drive, {8.0, 13.0}, far_fix_error_m, time_shift_s);
    c.in = {(c.dir / "db").string(), c.drive.rawlog, (c.dir / "run").string(),
            (c.dir / "refreshed").string(), ""};
    return c;
}

double cameraDistance(const database::Reference& a, const database::Reference& b) {
    const auto &p = a.ceiling_camera_pose, &q = b.ceiling_camera_pose;
    return std::hypot(p.x() - q.x(), p.y() - q.y());
}

}  // namespace

TEST(Refresh, TheChangedStretchGetsTheDrivesImagesPosedBetweenItsFixes) {
    const auto c = makeCase("lookup_refresh_stretch");
    const auto o = test::shareSurveyOptions(false);
    const auto result = survey::refreshDatabase(c.in, o);
    ASSERT_EQ(result.stretches.size(), 1u);
    const auto& s = result.stretches.front();
    EXPECT_EQ(s.refused, "");
    EXPECT_NEAR(s.length_m, 5.0 * 1.02, 0.1);  // the odometry's 2 % scale error
    EXPECT_GT(s.closure_m, 0.05);              // ... which the forward run alone misses by
    EXPECT_GT(result.references_added, 10u);
    EXPECT_GT(result.references_superseded, 0u);

    const auto before = database::ReferenceDatabase::load(c.in.db_dir);
    const auto after = database::ReferenceDatabase::load(c.in.out_dir);
    ASSERT_EQ(after.size(), before.size() + result.references_added);
    for (std::size_t i = 0; i < before.size(); ++i) {
        // The surveyed references come through as they were, forward images included.
        const auto &was = before.reference(i), &is = after.reference(i);
        EXPECT_TRUE(was.current());
        EXPECT_EQ(is.source, "survey");
        EXPECT_NEAR((is.vehicle_pose.asVectorVal() - was.vehicle_pose.asVectorVal()).norm(), 0,
                    1e-9);
        ASSERT_EQ(is.has_forward, was.has_forward) << i;
        if (!was.has_forward) continue;
        EXPECT_DOUBLE_EQ(is.forward_time_s, was.forward_time_s);
        EXPECT_NEAR(
            (is.forward_camera_pose.asVectorVal() - was.forward_camera_pose.asVectorVal()).norm(),
            0, 1e-9)
            << i;
    }
    std::vector<std::size_t> bridged;
    for (std::size_t i = before.size(); i < after.size(); ++i) {
        const auto& r = after.reference(i);
        EXPECT_EQ(r.source, "refresh");
        EXPECT_EQ(r.traverse, "today");
        // Between the fixes (each run of the odometry off by up to 0.1 m) the blend is on the
        // truth, the emitted dead-reckoned poses (0.5 m off) unused; the margins are the fixes.
        const double t = r.time_s - kT0;
        const auto truth = test::truePoseAt(t);
        EXPECT_NEAR(r.vehicle_pose.x(), truth.x(), 0.01) << t;
        EXPECT_NEAR(r.vehicle_pose.y(), truth.y(), 0.01) << t;
        EXPECT_GE(t, 8.0 - 1.05);
        EXPECT_LE(t, 13.0 + 1.05);
        if (t > 8.0 && t < 13.0) bridged.push_back(i);
    }
    ASSERT_FALSE(bridged.empty());
    // Superseded: exactly the survey's references whose cameras stood within the radius of a
    // bridged one's camera.
    for (std::size_t i = 0; i < before.size(); ++i) {
        double nearest = 1e9;
        for (std::size_t b : bridged) {
            nearest = std::min(nearest, cameraDistance(after.reference(i), after.reference(b)));
        }
        EXPECT_EQ(after.reference(i).current(), nearest > o.refresh.supersede_radius_m) << i;
        if (!after.reference(i).current()) {
            EXPECT_EQ(after.reference(i).superseded_by, "today");
        }
    }
    // Over the changed stretch the localiser now gets today's images only.
    const auto middle = after.reference(bridged[bridged.size() / 2]).ceiling_camera_pose;
    for (const auto& n : after.nearestCameras({middle.x(), middle.y()}, 3)) {
        EXPECT_EQ(after.reference(n.index).source, "refresh");
    }
    EXPECT_TRUE(fs::is_regular_file(c.dir / "refreshed" / survey::kRefreshReport));
}

TEST(Refresh, OdometryThatDoesNotJoinTheFixesLeavesTheStretchAlone) {
    const auto c = makeCase("lookup_refresh_closure", /*far_fix_error_m=*/1.0);
    const auto result = survey::refreshDatabase(c.in, test::shareSurveyOptions(false));
    ASSERT_EQ(result.stretches.size(), 1u);
    EXPECT_NE(result.stretches.front().refused.find("misses the other"), std::string::npos)
        << result.stretches.front().refused;
    EXPECT_EQ(result.references_added, 0u);
    EXPECT_EQ(result.references_superseded, 0u);
}

TEST(Refresh, ARunOfAnotherDriveOrTheSameFolderIsRefusedNamingIt) {
    auto c = makeCase("lookup_refresh_refused", 0, /*time_shift_s=*/1000);
    const auto o = test::shareSurveyOptions(false);
    try {
        survey::refreshDatabase(c.in, o);
        FAIL() << "a run of another drive was accepted";
    } catch (const eval::RunError& e) {
        EXPECT_NE(std::string(e.what()).find(c.in.run_dir), std::string::npos) << e.what();
        EXPECT_NE(std::string(e.what()).find("not a run of this drive"), std::string::npos);
    }
    EXPECT_FALSE(fs::exists(c.in.out_dir));
    c.in.out_dir = c.in.db_dir;
    EXPECT_THROW(survey::refreshDatabase(c.in, o), common::ConfigError);
    EXPECT_EQ(database::ReferenceDatabase::load(c.in.db_dir).size(), 81u);
}

TEST(Refresh, TheCommandLineTakesOneDriveAndItsRun) {
    const auto refused = [](std::vector<const char*> args) {
        args.insert(args.begin(), "lookup-survey");
        survey::SurveyApp app;
        testing::internal::CaptureStderr();
        const bool ok = app.initialize(int(args.size()), args.data());
        const std::string err = testing::internal::GetCapturedStderr();
        EXPECT_FALSE(ok);
        EXPECT_EQ(app.exitCode(), common::kExitUsage) << err;
        return err;
    };
    EXPECT_NE(refused({"--refresh", "db", "--rawlogs", "drive.rawlog", "--out", "new"})
                  .find("--refresh and --run go together"),
              std::string::npos);
    EXPECT_NE(refused({"--refresh", "db", "--rawlogs", "a.rawlog,b.rawlog", "--run", "run", "--out",
                       "new"})
                  .find("one drive"),
              std::string::npos);
    EXPECT_NE(refused({"--refresh", "db", "--rawlogs", "a.rawlog", "--run", "run", "--poses",
                       "p.tum", "--out", "new"})
                  .find("one drive"),
              std::string::npos);
}

// Real operating conditions in the generated data: stamp latency, jitter and drops per sensor,
// auto-exposure, duty-cycle plans (stops, reversing, either direction), odometry slip and
// dropouts, lidar scan skew and dust, and per-traverse overrides (another day, another vehicle).

#include "lookup/test/support.h"
#include "test_worlds.h"

#include <gtest/gtest.h>
#include <lookup/common/config.h>
#include <lookup/common/pose_files.h>
#include <lookup/common/rawlog_io.h>
#include <lookup/sim/camera_renderer.h>
#include <lookup/sim/simulator.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/core/Clock.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/poses/CPose2D.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <map>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using lookup::common::ConfigError;
using lookup::sim::ScenarioOptions;
using lookup::sim::SimulationResult;
using lookup::sim::Simulator;

/// One traverse of a 30 m straight tunnel with small images, quick enough for every CI run.
ScenarioOptions quickScenario() {
    ScenarioOptions s;
    s.name = "ops";
    s.seed = 5;
    s.world = lookup::sim::testing::straightTunnel(false);
    s.world.length_m = 30;
    s.ceiling_camera.width_px = 64;
    s.ceiling_camera.height_px = 48;
    s.forward_camera.width_px = 32;
    s.forward_camera.height_px = 24;
    s.threads = 2;
    lookup::sim::TraverseOptions a;
    a.name = "drive";
    a.roles = "mapping,reference";
    a.speed_kmh = 30;
    s.traverses = {a};
    return s;
}

/// Every observation of traverse `name`, in file order.
std::vector<mrpt::obs::CObservation::Ptr> readRawlog(const fs::path& dir, const std::string& name) {
    lookup::common::RawlogReader reader((dir / (name + ".rawlog")).string());
    std::vector<mrpt::obs::CObservation::Ptr> all;
    mrpt::obs::CObservation::Ptr obs;
    while (reader.next(obs)) all.push_back(obs);
    return all;
}

/// Offsets of a sensor's stamps from its nominal clock t0 + phase + k / rate [s].
std::vector<double> stampOffsets(const std::vector<mrpt::obs::CObservation::Ptr>& obs,
                                 const std::string& label, double t0, double phase, double rate) {
    std::vector<double> out;
    for (const auto& o : obs) {
        if (o->sensorLabel != label) continue;
        const double t = mrpt::Clock::toDouble(o->timestamp) - t0 - phase;
        out.push_back(t - std::round(t * rate) / rate);
    }
    return out;
}

SimulationResult runOk(const ScenarioOptions& sc, const fs::path& dir) {
    const SimulationResult r = Simulator(sc).run(dir.string());
    EXPECT_EQ(r.status, SimulationResult::Status::Ok) << r.reason;
    return r;
}

TEST(Operations, LatencyJitterAndDropsArePerSensor) {
    ScenarioOptions sc = quickScenario();
    sc.ceiling_camera.timing.latency_ms = 12;  // less than half the 40 ms period
    sc.lidar.timing.latency_ms = -10;
    sc.forward_camera.timing.jitter_ms = 3;
    sc.odometry.timing.drop_rate = 0.25;
    const fs::path dir = lookup::test::freshDir("lookup_sim_ops_timing");
    const SimulationResult r = runOk(sc, dir);
    const Simulator sim(sc);
    const double t0 = sim.groundTruth(0).front().time_s;
    const auto obs = readRawlog(dir, "drive");
    for (double d : stampOffsets(obs, "CEILING_CAM", t0, sc.ceiling_camera.phase_s, 25)) {
        ASSERT_NEAR(d, 0.012, 1e-5);
    }
    for (double d : stampOffsets(obs, "LIDAR", t0, sc.lidar.phase_s, 10)) {
        ASSERT_NEAR(d, -0.010, 1e-5);
    }
    const auto jitter = stampOffsets(obs, "FORWARD_CAM", t0, sc.forward_camera.phase_s, 10);
    ASSERT_GT(jitter.size(), 20u);
    cv::Scalar mean, sd;
    cv::meanStdDev(jitter, mean, sd);
    EXPECT_NEAR(sd[0], 0.003, 0.0012);
    EXPECT_NEAR(mean[0], 0.0, 0.0015);
    // Odometry: a quarter of the records lost, the others still on the 50 Hz clock.
    const double expected =
        std::floor((sim.groundTruth(0).back().time_s - t0 - sc.odometry.phase_s) *
                   sc.odometry.rate_hz) +
        1;
    EXPECT_NEAR(r.traverses[0].odometry_records / expected, 0.75, 0.06);
    // The file is in stamp order, as a logger writes it.
    for (std::size_t i = 1; i < obs.size(); ++i) {
        ASSERT_LE(obs[i - 1]->timestamp, obs[i]->timestamp) << "record " << i;
    }
}

/// Mean grey level of the ceiling frames after `from_s` into the traverse.
double meanCeilingLevel(const fs::path& dir, double t0, double from_s) {
    double sum = 0;
    int n = 0;
    for (const auto& o : readRawlog(dir, "drive")) {
        auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(o);
        if (!img || img->sensorLabel != "CEILING_CAM") continue;
        if (mrpt::Clock::toDouble(img->timestamp) - t0 < from_s) continue;
        const fs::path file = fs::path(img->image.getExternalStorageFile()).filename();
        const cv::Mat m = cv::imread((dir / "drive_Images" / file).string(), cv::IMREAD_GRAYSCALE);
        if (m.empty()) ADD_FAILURE() << "cannot read " << file;
        sum += cv::mean(m)[0];
        ++n;
    }
    return n ? sum / n : -1;
}

TEST(Operations, AutoExposureBringsTheImageToItsTarget) {
    for (const double target : {50.0, 150.0}) {
        SCOPED_TRACE(target);
        ScenarioOptions sc = quickScenario();
        sc.ceiling_camera.auto_exposure_target_dn = target;
        sc.ceiling_camera.auto_exposure_tau_s = 0.2;
        sc.ceiling_camera.exposure_variation = 0;
        const fs::path dir =
            lookup::test::freshDir("lookup_sim_ops_ae" + std::to_string(int(target)));
        runOk(sc, dir);
        const double t0 = Simulator(sc).groundTruth(0).front().time_s;
        EXPECT_NEAR(meanCeilingLevel(dir, t0, 1.5), target, 0.12 * target);
    }
}

/// Vehicle-frame forward velocity between ground-truth rows i-1 and i [m/s].
double forwardSpeed(const lookup::common::PoseTrack& gt, std::size_t i) {
    const mrpt::poses::CPose2D a(gt[i - 1].pose), b(gt[i].pose);
    return (b - a).x() / (gt[i].time_s - gt[i - 1].time_s);
}

TEST(Operations, PlanDrivesStopsAndReverses) {
    ScenarioOptions sc = quickScenario();
    sc.traverses[0].plan = "drive 18, stop 3, reverse 6, stop 1.5, drive 24";
    sc.traverses[0].start_m = 2;
    const Simulator sim(sc);
    const auto& gt = sim.groundTruth(0);
    double min_v = 0, max_v = 0, still = 0, longest_still = 0, max_side = 0;
    for (std::size_t i = 1; i < gt.size(); ++i) {
        const double v = forwardSpeed(gt, i);
        min_v = std::min(min_v, v);
        max_v = std::max(max_v, v);
        const mrpt::poses::CPose2D d =
            mrpt::poses::CPose2D(gt[i].pose) - mrpt::poses::CPose2D(gt[i - 1].pose);
        max_side = std::max(max_side, std::abs(d.y()) / 0.01);
        still = d.norm() == 0 ? still + 0.01 : 0;
        longest_still = std::max(longest_still, still);
    }
    EXPECT_LT(min_v, -3.0) << "the reversing leg backs up";
    EXPECT_GT(max_v, 3.0);
    EXPECT_LT(max_side, 0.2) << "no sideways motion";
    EXPECT_NEAR(longest_still, 3.0, 0.02);
    // The vehicle keeps facing +x (down the straight tunnel) throughout.
    for (const auto& row : gt) ASSERT_LT(std::abs(row.pose.yaw()), 0.2);
    // Odometry reads the reversing as negative forward velocity.
    const fs::path dir = lookup::test::freshDir("lookup_sim_ops_plan");
    runOk(sc, dir);
    double min_odo_v = 0;
    for (const auto& o : readRawlog(dir, "drive")) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            min_odo_v = std::min(min_odo_v, odo->velocityLocal.vx);
        }
    }
    EXPECT_LT(min_odo_v, -3.0);
}

// A survey drive that stops over surveyed marks: dataset.ini gives the operator's mark of each
// stop between the first and last motion (not the rest before it starts, nor the end, which is
// end_pose), at a time inside the stop, within a mark's error of the truth and never exactly it.
TEST(Operations, TheSurveyVehicleStopsOverAMarkAtEveryStopOfItsPlan) {
    ScenarioOptions sc = quickScenario();
    sc.traverses[0].plan = "stop 1, drive 10, stop 2, drive 20, stop 1.5, drive end, stop 1";
    sc.traverses[0].marks_at_stops = true;
    const fs::path dir = lookup::test::freshDir("lookup_sim_ops_marks");
    runOk(sc, dir);
    const Simulator sim(sc);
    const auto interp = lookup::common::makeInterpolator(sim.groundTruth(0), 1.0);
    mrpt::config::CConfigFile ini((dir / "dataset.ini").string());
    std::istringstream list(ini.read_string("traverse_0", "marks", ""));
    std::vector<double> xs;
    for (std::string item; std::getline(list, item, ';');) {
        std::istringstream in(item);
        double t = 0, x = 0, y = 0, yaw_deg = 0;
        ASSERT_TRUE(in >> t >> x >> y >> yaw_deg) << item;
        const auto truth = lookup::common::poseAt(interp, t);
        ASSERT_TRUE(truth.has_value()) << item;
        const auto before = lookup::common::poseAt(interp, t - 0.5);
        const auto after = lookup::common::poseAt(interp, t + 0.5);
        ASSERT_TRUE(before && after) << item;
        EXPECT_EQ(before->x(), after->x()) << "at rest around the mark's time: " << item;
        const double d = std::hypot(x - truth->x(), y - truth->y());
        EXPECT_GT(d, 0.01) << item;
        EXPECT_LT(d, 0.06) << item;
        EXPECT_LT(std::abs(yaw_deg - mrpt::RAD2DEG(truth->yaw())), 0.11) << item;
        xs.push_back(truth->x() - sim.groundTruth(0).front().pose.x());
    }
    ASSERT_EQ(xs.size(), 2u);
    EXPECT_NEAR(xs[0], 10, 0.5);
    EXPECT_NEAR(xs[1], 20, 0.5);
    // "drive end" went to the route's end, whatever its length came out as.
    EXPECT_NEAR(sim.groundTruth(0).back().pose.x() - sim.groundTruth(0).front().pose.x(),
                sim.world().routeLength(), 0.5);
    // Without the key, no marks.
    sc.traverses[0].marks_at_stops = false;
    const fs::path plain = lookup::test::freshDir("lookup_sim_ops_no_marks");
    runOk(sc, plain);
    EXPECT_FALSE(mrpt::config::CConfigFile((plain / "dataset.ini").string())
                     .keyExists("traverse_0", "marks"));
}

TEST(Operations, ReverseDirectionDrivesTheRouteBackwards) {
    ScenarioOptions sc = quickScenario();
    sc.traverses[0].direction = "reverse";
    const Simulator sim(sc);
    const auto& gt = sim.groundTruth(0);
    EXPECT_GT(gt.front().pose.x(), gt.back().pose.x() + 20);
    EXPECT_NEAR(std::abs(mrpt::math::wrapToPi(gt[gt.size() / 2].pose.yaw())), M_PI, 0.2);
    EXPECT_GT(forwardSpeed(gt, gt.size() / 2), 3.0) << "driving, not backing up";
}

TEST(Operations, ASpeedTheRouteIsTooShortForIsSaid) {
    // From rest to a stop at 1.5 m/s2, 30 m give 24 km/h at most: a 60 km/h condition there
    // would measure 24 km/h under its name.
    ScenarioOptions sc = quickScenario();
    sc.traverses[0].speed_kmh = 60;
    const Simulator short_route(sc);
    ASSERT_EQ(short_route.warnings().size(), 1u);
    EXPECT_NE(short_route.warnings()[0].find("[traverse_0] speed_kmh 60 is never reached"),
              std::string::npos)
        << short_route.warnings()[0];
    sc.world.length_m = 250;
    EXPECT_TRUE(Simulator(sc).warnings().empty());
    sc.world.length_m = 30;
    sc.traverses[0].speed_kmh = 20;
    EXPECT_TRUE(Simulator(sc).warnings().empty());
}

TEST(Operations, BadPlansAreRefusedNamingTheLeg) {
    ScenarioOptions sc = quickScenario();
    sc.traverses[0].plan = "drive 10, stop 2, drive 200";
    try {
        Simulator{sc};
        ADD_FAILURE() << "a leg beyond the route was accepted";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("[traverse_0] plan: leg 3"), std::string::npos)
            << e.what();
    }
    // A reversing segment that leaves the route at its start, a U-turn, malformed legs.
    sc.traverses[0].plan = "drive 20, stop 5, reverse -4";
    try {
        sc.check();
        ADD_FAILURE() << "a reversing leg off the route was accepted";
    } catch (const ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("traverse_0.plan leg 3"), std::string::npos)
            << e.what();
    }
    for (const char* bad :
         {"drive 10, drive 2", "drive 10, stop -1", "drive ten", "fly 3", "stop end", "drive 5x"}) {
        sc.traverses[0].plan = bad;
        EXPECT_THROW(sc.check(), ConfigError) << bad;
    }
    sc.traverses[0].plan = "drive 10, stop 2, reverse 4, stop 1, reverse 1";
    EXPECT_NO_THROW(sc.check());
}

/// Distance along the odometry records of traverse "drive" [m].
double odometryLength(const fs::path& dir) {
    double length = 0;
    mrpt::poses::CPose2D last;
    bool have = false;
    for (const auto& o : readRawlog(dir, "drive")) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            if (have) length += (odo->odometry - last).norm();
            last = odo->odometry;
            have = true;
        }
    }
    return length;
}

TEST(Operations, WheelSlipOverReadsByItsFactorAndDropoutsLeaveGaps) {
    ScenarioOptions sc = quickScenario();
    sc.ceiling_camera.rate_hz = 2;
    sc.forward_camera.rate_hz = 2;
    sc.odometry.slip_fraction = 1;
    sc.odometry.slip_factor = 1.3;
    const fs::path dir = lookup::test::freshDir("lookup_sim_ops_slip");
    const SimulationResult r = runOk(sc, dir);
    EXPECT_NEAR(odometryLength(dir) / r.traverses[0].length_m, 1.3 * (1 + sc.odometry.scale_error),
                0.01);
    sc.odometry.slip_fraction = 0;
    sc.odometry.dropout_fraction = 0.3;
    sc.odometry.dropout_s = 0.5;
    const fs::path dir2 = lookup::test::freshDir("lookup_sim_ops_dropout");
    runOk(sc, dir2);
    double last = -1, longest_gap = 0;
    for (const auto& o : readRawlog(dir2, "drive")) {
        if (o->sensorLabel != "ODOMETRY") continue;
        const double t = mrpt::Clock::toDouble(o->timestamp);
        if (last > 0) longest_gap = std::max(longest_gap, t - last);
        last = t;
    }
    EXPECT_GT(longest_gap, 0.49);
    // The counter runs on the vehicle: across a dropout the pose still follows the drive.
    EXPECT_NEAR(odometryLength(dir2) / r.traverses[0].length_m, 1 + sc.odometry.scale_error, 0.01);
}

TEST(Operations, LidarSweepSkewsTheScanAndDustReturnsEarly) {
    lookup::sim::WorldOptions w = lookup::sim::testing::straightTunnel(true);
    const lookup::sim::TunnelWorld world(w, 1);
    lookup::sim::LidarOptions lidar;
    lidar.noise_std_m = 0;
    const mrpt::poses::CPose2D start(10.0, 0.0, 0.0), end(10.0, 0.5, 0.0);  // 0.5 m to the left
    const auto still = lookup::sim::simulateLidar(world, start, lidar, 1);
    const auto skewed = lookup::sim::simulateLidar(world, start, lidar, 1, &end);
    const std::size_t n = still.getScanSize();
    // The first ray (-135 deg, right wall) is measured at the start pose, the last (+135 deg,
    // left wall) at the end pose, 0.5 m closer to the left wall: 0.5 / sin(45 deg) shorter.
    EXPECT_NEAR(skewed.getScanRange(0), still.getScanRange(0), 1e-3);
    EXPECT_NEAR(still.getScanRange(n - 1) - skewed.getScanRange(n - 1), 0.5 / std::sin(M_PI / 4),
                0.01);
    lidar.dust_rate = 0.2;
    lidar.dust_max_range_m = 5;
    const auto dusty = lookup::sim::simulateLidar(world, start, lidar, 1);
    int early = 0;
    for (std::size_t r = 0; r < n; ++r) {
        early += dusty.getScanRange(r) < still.getScanRange(r) - 0.05;
    }
    EXPECT_NEAR(double(early) / n, 0.2 * 0.95, 0.06);  // a few dust draws lie behind the wall
}

TEST(Operations, AnotherDayLooksDifferentOnTheSameRoute) {
    // Two identical drives (same speed profile: the names share length and first letter);
    // the second one months later: more mesh, lamps off, another camera.
    ScenarioOptions sc = quickScenario();
    sc.ceiling_camera.noise_std_dn = 0;
    sc.ceiling_camera.exposure_variation = 0;
    sc.ceiling_camera.rate_hz = 5;
    sc.forward_camera.rate_hz = 2;
    sc.traverses.push_back(sc.traverses[0]);
    sc.traverses[0].name = "d1";
    sc.traverses[1].name = "d2";
    sc.traverses[1].roles = "query";
    const fs::path same = lookup::test::freshDir("lookup_sim_ops_sameday");
    runOk(sc, same);
    sc.traverses[1].world = sc.world;
    sc.traverses[1].world->mesh_fraction = 1.0;
    sc.traverses[1].ceiling_camera = sc.ceiling_camera;
    sc.traverses[1].ceiling_camera->hfov_deg = 80;
    sc.traverses[1].ceiling_camera->noise_std_dn = 0;
    const fs::path later = lookup::test::freshDir("lookup_sim_ops_later");
    runOk(sc, later);
    auto frame = [](const fs::path& dir, const std::string& t) {
        std::ifstream f(dir / (t + "_Images") / "CEILING_CAM_000010.png", std::ios::binary);
        return std::string(std::istreambuf_iterator<char>(f), {});
    };
    EXPECT_FALSE(frame(same, "d1").empty());
    EXPECT_EQ(frame(same, "d1"), frame(same, "d2")) << "control: the same day looks the same";
    EXPECT_NE(frame(later, "d1"), frame(later, "d2"));
    EXPECT_EQ(frame(later, "d1"), frame(same, "d1")) << "the survey day is unchanged";
    double fx[2] = {0, 0};
    for (int k = 0; k < 2; ++k) {
        for (const auto& o : readRawlog(later, k ? "d2" : "d1")) {
            if (auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(o)) {
                if (img->sensorLabel == "CEILING_CAM") fx[k] = img->cameraParams.fx();
            }
        }
    }
    EXPECT_GT(fx[1], fx[0] * 1.1) << "the narrower camera has the longer focal length";
}

/// Every file under `root` by relative path (scenario.ini left out: it records `threads`).
std::map<std::string, std::string> datasetFiles(const fs::path& root) {
    std::map<std::string, std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(root)) {
        if (!e.is_regular_file() || e.path().filename() == "scenario.ini") continue;
        std::ifstream f(e.path(), std::ios::binary);
        files[fs::relative(e.path(), root).string()] =
            std::string(std::istreambuf_iterator<char>(f), {});
    }
    return files;
}

TEST(Operations, RealisticEffectsStayDeterministicWhateverTheThreadCount) {
    ScenarioOptions sc = ScenarioOptions::fromFile(lookup::sim::findPreset(
        "mine-b-real-mini", {std::string(LOOKUP_SOURCE_SHARE_DIR) + "/scenarios"}));
    sc.world.length_m = 20;
    // The other-day query (every override) and the drive against the survey, cameras slowed.
    sc.traverses = {sc.traverses.at(3), sc.traverses.at(4)};
    sc.ceiling_camera.rate_hz = 3;
    sc.forward_camera.rate_hz = 2;
    sc.traverses[0].ceiling_camera->rate_hz = 3;
    for (auto* cam : {&sc.ceiling_camera, &*sc.traverses[0].ceiling_camera}) {
        cam->width_px = 96;
        cam->height_px = 72;
    }
    sc.forward_camera.width_px = 48;
    sc.forward_camera.height_px = 36;
    const fs::path a = lookup::test::freshDir("lookup_sim_ops_real_t1"),
                   b = lookup::test::freshDir("lookup_sim_ops_real_t2");
    sc.threads = 1;
    runOk(sc, a);
    sc.threads = 2;
    runOk(sc, b);
    const auto fa = datasetFiles(a), fb = datasetFiles(b);
    EXPECT_GT(fa.size(), 20u);
    ASSERT_EQ(fa.size(), fb.size());
    for (const auto& [name, bytes] : fa) {
        ASSERT_TRUE(fb.count(name)) << name;
        EXPECT_TRUE(fb.at(name) == bytes) << name << " differs";
    }
}

/// The ground-truth pose at absolute time t (linear between the 100 Hz rows).
mrpt::poses::CPose3D interpolate(const lookup::common::PoseTrack& gt, double t) {
    std::size_t i = 1;
    while (i + 1 < gt.size() && gt[i].time_s < t) ++i;
    const double a = (t - gt[i - 1].time_s) / (gt[i].time_s - gt[i - 1].time_s);
    const auto& p = gt[i - 1].pose;
    const auto& q = gt[i].pose;
    auto lerp = [a](double x, double y) { return x + a * mrpt::math::wrapToPi(y - x); };
    return mrpt::poses::CPose3D(lerp(p.x(), q.x()), lerp(p.y(), q.y()), lerp(p.z(), q.z()),
                                lerp(p.yaw(), q.yaw()), lerp(p.pitch(), q.pitch()),
                                lerp(p.roll(), q.roll()));
}

TEST(Operations, RollingShutterRowsAreExposedAfterTheStampedRow) {
    // A recorded frame matches a re-rendering from the vehicle poses of its rows' exposure
    // times, t_row = stamp + (row - row_ref) * readout / (rows - 1), and not one with the other
    // reference row.
    for (const std::string ref : {"first", "middle"}) {
        SCOPED_TRACE(ref);
        ScenarioOptions sc = quickScenario();
        lookup::sim::CameraOptions& cam = sc.ceiling_camera;
        cam.readout_ms = 35;
        cam.stamp_row =
            ref == "first" ? lookup::common::StampRow::First : lookup::common::StampRow::Middle;
        cam.noise_std_dn = 0;
        cam.exposure_variation = 0;
        cam.exposure_ms = 0;
        sc.forward_camera.rate_hz = 1;
        const fs::path dir = lookup::test::freshDir("lookup_sim_ops_rs_" + ref);
        runOk(sc, dir);
        const Simulator sim(sc);
        const auto& gt = sim.groundTruth(0);
        const int k = 40;  // mid-drive, at speed
        const double stamp = gt.front().time_s + cam.phase_s + k / cam.rate_hz;
        const cv::Mat recorded = cv::imread(
            (dir / "drive_Images" / "CEILING_CAM_000040.png").string(), cv::IMREAD_GRAYSCALE);
        ASSERT_FALSE(recorded.empty());
        const lookup::sim::CameraRenderer renderer(sim.world(), cam,
                                                   lookup::sim::CameraRenderer::Kind::Ceiling, 1);
        auto rerender = [&](double row_ref) {
            std::vector<mrpt::poses::CPose3D> rows;
            for (int v = 0; v < cam.height_px; ++v) {
                const double t =
                    stamp + 1e-3 * cam.readout_ms * (v - row_ref) / (cam.height_px - 1);
                rows.push_back(interpolate(gt, t) + cam.mount.pose());
            }
            cv::Mat m;
            renderer.render(rows, {}).asCvMat(m, mrpt::img::DEEP_COPY);
            cv::Mat diff;
            cv::absdiff(m, recorded, diff);
            return cv::mean(diff)[0];
        };
        const double right = ref == "first" ? 0.0 : (cam.height_px - 1) / 2.0;
        const double wrong = ref == "first" ? (cam.height_px - 1) / 2.0 : 0.0;
        const double matched = rerender(right), mismatched = rerender(wrong);
        EXPECT_LT(matched, 0.5);
        EXPECT_GT(mismatched, 3 * matched + 0.5) << "matched " << matched;
    }
}

}  // namespace

// Declines: a grade profile along the route lifts or lowers floor, roof and furniture; the
// vehicle pitches on it, the lidar's scan plane tilts with it, the ground truth is 3-D; and a
// scenario without a grade generates the same bytes as before the profile existed.

#include "lookup/test/support.h"
#include "test_worlds.h"

#include <gtest/gtest.h>
#include <lookup/common/pose_files.h>
#include <lookup/common/rawlog_io.h>
#include <lookup/sim/simulator.h>
#include <lookup/sim/world.h>
#include <mrpt/obs/CObservationIMU.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <string>

namespace {

namespace fs = std::filesystem;
using lookup::sim::SurfaceKind;
using lookup::sim::TunnelWorld;
using lookup::sim::WorldOptions;

constexpr double kGrade = 1.0 / 7.0;

/// The straight 60 m test tunnel descending at 1:7 from 10 m to 40 m (10 m vertical curves).
WorldOptions rampWorld() {
    WorldOptions w = lookup::sim::testing::straightTunnel(false);
    w.length_m = 60;
    w.grade = "10 40 -1:7";
    w.grade_transition_m = 10;
    return w;
}

TEST(Decline, ProfileJoinsTwoLevelsAtTheGrade) {
    const TunnelWorld world(rampWorld(), 1);
    ASSERT_TRUE(world.graded());
    EXPECT_NEAR(world.levelAtRoute(3), 0, 1e-9);
    EXPECT_NEAR(world.levelAtRoute(55), -30 * kGrade, 0.01);
    EXPECT_NEAR(world.levelAtRoute(26) - world.levelAtRoute(24), -2 * kGrade, 1e-3);
    // The vertical curve: half the grade at the ramp's start.
    EXPECT_NEAR(world.levelAtRoute(10.5) - world.levelAtRoute(9.5), -0.5 * kGrade, 0.01);
    // Across the tunnel the level is the centre line's.
    EXPECT_NEAR(world.level(25, 2.0), world.levelAtRoute(25), 0.01);
    EXPECT_NEAR(world.level(25, -2.0), world.levelAtRoute(25), 0.01);
    EXPECT_FALSE(TunnelWorld(lookup::sim::testing::straightTunnel(false), 1).graded());
}

TEST(Decline, RoofAndFloorFollowTheRamp) {
    const TunnelWorld world(rampWorld(), 1);
    const double h = world.options().ceiling_height_m;
    const double base = world.level(25, 0);
    const Eigen::Vector3d o(25, 0, base + 1.5);
    const auto up = world.traceStatic(o, Eigen::Vector3d(0, 0, 1), 0, 20);
    EXPECT_EQ(up.kind, SurfaceKind::Roof);
    EXPECT_NEAR(up.t, h - 1.5, 0.01);
    const auto down = world.traceStatic(o, Eigen::Vector3d(0, 0, -1), 0, 20);
    EXPECT_EQ(down.kind, SurfaceKind::Floor);
    EXPECT_NEAR(down.t, 1.5, 0.01);
    // Level, from the top of the ramp: the descending roof comes down to meet the ray where
    // the level has dropped by h - 1.5 (at about 10 + 5 + 3.5 * 7 m).
    const auto ahead =
        world.traceStatic(Eigen::Vector3d(3, 0, 1.5), Eigen::Vector3d(1, 0, 0), 0, 60);
    EXPECT_EQ(ahead.kind, SurfaceKind::Roof);
    EXPECT_GT(ahead.t, 30);
    EXPECT_LT(ahead.t, 40);
}

TEST(Decline, VehiclePitchesOnTheGradeAndTheGroundTruthIsThreeD) {
    WorldOptions smooth = rampWorld();
    smooth.floor_roughness_m = 0;  // the grade's pitch alone
    const TunnelWorld world(smooth, 1);
    lookup::sim::TraverseOptions tr;
    tr.name = "down";
    tr.roles = "query";
    tr.speed_kmh = 15;
    const lookup::sim::VehicleOptions vehicle;
    const double pitch = std::atan(kGrade);  // MRPT: positive pitch lowers the nose
    int on_ramp = 0;
    for (const auto& row : lookup::sim::vehicleTrack(world, tr, vehicle, 0)) {
        const auto& p = row.pose;
        EXPECT_NEAR(p.z(), world.level(p.x(), p.y()), 0.01) << p;
        if (p.x() > 18 && p.x() < 32) {
            EXPECT_NEAR(p.pitch(), pitch, 0.002) << p;
            ++on_ramp;
        } else if (p.x() < 3 || p.x() > 50) {
            EXPECT_LT(std::abs(p.pitch()), 1e-3) << p;
        }
    }
    EXPECT_GT(on_ramp, 100);
    tr.direction = "reverse";  // up the ramp, facing the way of travel: nose up
    const auto up = lookup::sim::vehicleTrack(world, tr, vehicle, 0);
    const auto& mid = up[up.size() / 2].pose;
    ASSERT_GT(mid.x(), 18);
    ASSERT_LT(mid.x(), 32);
    EXPECT_NEAR(mid.pitch(), -pitch, 0.002) << mid;
    EXPECT_NEAR(up.front().pose.z(), -30 * kGrade, 0.01);
}

TEST(Decline, LidarScanPlaneTiltsWithTheVehicle) {
    const TunnelWorld world(rampWorld(), 1);
    lookup::sim::LidarOptions lidar;
    lidar.noise_std_m = 0;
    const std::size_t ahead = 270;  // the ray along the vehicle's +x (270 deg at 0.5 deg)
    // On the flat at the foot of the ramp, still pitched nose down: the beam ahead meets the
    // floor at the scanner's height over it / sin(pitch), where a level scanner would see the
    // tunnel's far end.
    const double pitch = std::atan(kGrade);
    const double x = 46, z = world.level(x, 0);
    const mrpt::poses::CPose3D vehicle(x, 0, z, 0, pitch, 0);
    const auto tilted = lookup::sim::simulateLidar(world, vehicle, lidar, 1);
    ASSERT_TRUE(tilted.getScanRangeValidity(ahead));
    const double height = (vehicle + lidar.mount.pose()).z() - z;
    EXPECT_NEAR(tilted.getScanRange(ahead), height / std::sin(pitch), 0.05);
    const auto level =
        lookup::sim::simulateLidar(world, mrpt::poses::CPose3D(x, 0, z, 0, 0, 0), lidar, 1);
    EXPECT_GT(level.getScanRange(ahead), 12);
    // On the ramp, tilted with it, the side walls are where a level mine has them.
    const double xr = 25;
    const auto on_ramp = lookup::sim::simulateLidar(
        world, mrpt::poses::CPose3D(xr, 0, world.level(xr, 0), 0, pitch, 0), lidar, 1);
    const auto flat =
        lookup::sim::simulateLidar(TunnelWorld(lookup::sim::testing::straightTunnel(false), 1),
                                   mrpt::poses::CPose3D(xr, 0, 0, 0, 0, 0), lidar, 1);
    for (std::size_t r : {90u, 450u}) {  // -90 and +90 deg
        EXPECT_NEAR(on_ramp.getScanRange(r), flat.getScanRange(r), 0.02) << r;
    }
}

// A short level scenario touching every sensor, a sweep and a duty-cycle plan.
const char* kLevelScenario = R"([scenario]
name = level-golden
seed = 5
threads = 0
start_time_s = 1700000000
traverse_gap_s = 100
traverse_count = 2
[world]
layout = single
length_m = 20
drawpoint_spacing_m = 12
grid_resolution_m = 0.1
[vehicle]
name = light vehicle
[ceiling_camera]
label = CEILING_CAM
rate_hz = 14
width_px = 64
height_px = 48
[forward_camera]
label = FORWARD_CAM
width_px = 32
height_px = 24
[lidar]
label = LIDAR
sweep_ms = 50
[odometry]
label = ODOMETRY
[traverse_0]
name = middle
roles = mapping,reference
speed_kmh = 25
[traverse_1]
name = back
roles = query
start_m = 2
plan = drive 15, stop 1, reverse 5
)";

/// FNV-1a 64 over every file under `root` in path order (path, NUL, bytes, NUL), without
/// scenario.ini's `threads` line (the machine's) and `marks_at_stops` lines (a key added since),
/// dataset.ini's `end_pose` line (written since the grades; Simulator.WritesTheDatasetLayout
/// checks it) and the camera images: those go through
/// OpenCV kernels that pick their SIMD code at run time, so another CPU may round a pixel
/// differently; rawlogs, ground truth, odometry, lidar and the map are plain double arithmetic.
uint64_t datasetHash(const fs::path& root) {
    std::map<std::string, std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(root)) {
        if (!e.is_regular_file()) continue;
        if (e.path().parent_path().filename().string().find("_Images") != std::string::npos) {
            continue;
        }
        std::ifstream f(e.path(), std::ios::binary);
        std::string bytes((std::istreambuf_iterator<char>(f)), {});
        const auto drop = [&bytes](const char* key, bool with_newline) {
            for (auto at = bytes.find(key); at != std::string::npos; at = bytes.find(key, at)) {
                bytes.erase(at, bytes.find('\n', at) - at + (with_newline ? 1 : 0));
            }
        };
        if (e.path().filename() == "scenario.ini") drop("threads", false);
        if (e.path().filename() == "scenario.ini") drop("marks_at_stops", true);
        if (e.path().filename() == "dataset.ini") drop("end_pose", true);
        files[fs::relative(e.path(), root).string()] = bytes;
    }
    uint64_t h = 0xcbf29ce484222325ull;
    auto feed = [&h](const std::string& s) {
        for (unsigned char c : s) h = (h ^ c) * 0x100000001b3ull;
        h = (h ^ 0) * 0x100000001b3ull;
    };
    for (const auto& [path, bytes] : files) {
        feed(path);
        feed(bytes);
    }
    return h;
}

TEST(Decline, ALevelScenarioGeneratesTheBytesItDidBeforeGrades) {
    const fs::path dir = fs::temp_directory_path() / "lookup_decline_test_level";
    fs::remove_all(dir);
    fs::create_directories(dir);
    {
        std::ofstream f(dir / "level.ini");
        f << kLevelScenario;
    }
    auto scenario = lookup::sim::ScenarioOptions::fromFile((dir / "level.ini").string());
    scenario.threads = 2;
    EXPECT_EQ(scenario.toIniText().find("grade"), std::string::npos)
        << "a level scenario.ini has no grade keys";
    const lookup::sim::Simulator sim(scenario);
    ASSERT_FALSE(sim.world().graded());
    const auto result = sim.run((dir / "out").string());
    ASSERT_EQ(result.status, lookup::sim::SimulationResult::Status::Ok) << result.reason;
    // What lookup-sim wrote for this scenario before the grade profile existed (images aside,
    // see datasetHash; the images were byte-identical too on the machine the grades were
    // written on). A change here means level datasets are no longer reproducible across
    // versions: find what changed the level path.
    EXPECT_EQ(datasetHash(dir / "out"), 0x3b50e3d31a2c7e77ull);
}

TEST(Decline, AGradedDatasetsGroundTruthDescendsTheRamp) {
    const fs::path dir = fs::temp_directory_path() / "lookup_decline_test_graded";
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::string text = kLevelScenario;
    const std::string anchor = "grid_resolution_m = 0.1\n";
    text.insert(text.find(anchor) + anchor.size(), "grade = 3 17 -1:7\ngrade_transition_m = 4\n");
    {
        std::ofstream f(dir / "graded.ini");
        f << text;
    }
    auto scenario = lookup::sim::ScenarioOptions::fromFile((dir / "graded.ini").string());
    scenario.traverses.resize(1);
    scenario.threads = 2;
    const lookup::sim::Simulator sim(scenario);
    ASSERT_TRUE(sim.world().graded());
    const auto result = sim.run((dir / "out").string());
    ASSERT_EQ(result.status, lookup::sim::SimulationResult::Status::Ok) << result.reason;
    const auto track =
        lookup::common::readPoseFile((dir / "out" / "middle.rawlog.GT.txt").string());
    ASSERT_GT(track.size(), 100u);
    EXPECT_NEAR(track.front().pose.z(), 0, 0.05);
    EXPECT_NEAR(track.back().pose.z(), -14 * kGrade, 0.05);  // 14 m of ramp at 1:7
    double steepest = 0;
    for (const auto& row : track) steepest = std::max(steepest, row.pose.pitch());
    EXPECT_NEAR(steepest, std::atan(kGrade), 0.03);  // plus the floor relief
    // Wheel odometry measures the distance along the slope: (1 + scale_error) times the 3-D
    // path, measurably more than that times the plan path.
    double plan = 0, slope = 0, odometry = 0;
    for (std::size_t i = 1; i < track.size(); ++i) {
        const auto& a = track[i - 1].pose;
        const auto& b = track[i].pose;
        plan += std::hypot(b.x() - a.x(), b.y() - a.y());
        slope += std::sqrt(std::pow(b.x() - a.x(), 2) + std::pow(b.y() - a.y(), 2) +
                           std::pow(b.z() - a.z(), 2));
    }
    lookup::common::RawlogReader reader((dir / "out" / "middle.rawlog").string());
    mrpt::obs::CObservation::Ptr obs;
    std::optional<mrpt::poses::CPose2D> last;
    std::size_t odometry_records = 0;
    std::vector<double> pitch_error;  // inclinometer minus the truth [deg]
    while (reader.next(obs)) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(obs)) {
            if (last) odometry += (odo->odometry - *last).norm();
            last = odo->odometry;
            ++odometry_records;
        } else if (auto imu = std::dynamic_pointer_cast<mrpt::obs::CObservationIMU>(obs)) {
            ASSERT_TRUE(imu->has(mrpt::obs::IMU_PITCH) && imu->has(mrpt::obs::IMU_ROLL));
            const double t = mrpt::Clock::toDouble(imu->timestamp);
            const auto truth = std::min_element(track.begin(), track.end(), [t](auto& a, auto& b) {
                return std::abs(a.time_s - t) < std::abs(b.time_s - t);
            });
            pitch_error.push_back(
                mrpt::RAD2DEG(imu->get(mrpt::obs::IMU_PITCH) - truth->pose.pitch()));
        }
    }
    // One inclinometer reading per odometry record, off the truth by the traverse's bias (one
    // draw of 0.5 deg spread) and 0.2 deg of noise (plus the pitch change within the 10 ms
    // between a record and the nearest ground-truth row).
    ASSERT_EQ(pitch_error.size(), odometry_records);
    double mean = 0, var = 0;
    for (double e : pitch_error) mean += e / pitch_error.size();
    for (double e : pitch_error) var += (e - mean) * (e - mean) / pitch_error.size();
    EXPECT_LT(std::abs(mean), 2.0);
    EXPECT_NEAR(std::sqrt(var), scenario.imu.noise_std_deg, 0.1);
    const double k = 1 + scenario.odometry.scale_error;
    EXPECT_NEAR(odometry / slope, k, 0.002);
    EXPECT_GT(odometry / plan, k + 0.004);
    const std::string resolved = lookup::test::readText(dir / "out" / "scenario.ini");
    EXPECT_NE(resolved.find("grade = 3 17 -1:7"), std::string::npos);
    // The inclinometer is on by default in a graded mine, and the resolved file says so.
    EXPECT_NE(resolved.find("[imu]\nenabled = true"), std::string::npos) << resolved;
    EXPECT_NE(lookup::test::readText(dir / "out" / "dataset.ini").find("imu_label = IMU"),
              std::string::npos);
}

TEST(Decline, GradeKeysRoundTripInTheResolvedScenario) {
    lookup::sim::ScenarioOptions s;
    s.world.grade = "10 40 -1:7";
    lookup::sim::TraverseOptions t;
    t.name = "a";
    t.roles = "mapping";
    s.traverses = {t};
    const std::string text = s.toIniText();
    EXPECT_NE(text.find("grade = 10 40 -1:7"), std::string::npos) << text;
    EXPECT_NE(text.find("grade_transition_m"), std::string::npos) << text;
    EXPECT_NE(text.find("[imu]"), std::string::npos) << text;  // auto: on in a graded mine
    s.imu.enabled = lookup::sim::ImuOptions::Mode::Off;
    EXPECT_EQ(s.toIniText().find("[imu]"), std::string::npos);
    s.world.grade.clear();
    s.imu.enabled = lookup::sim::ImuOptions::Mode::Auto;
    EXPECT_EQ(s.toIniText().find("[imu]"), std::string::npos);  // ... off on the level
    const auto ramps = lookup::sim::parseGrade("10 40 -1:7, 50 60 0.1");
    ASSERT_EQ(ramps.size(), 2u);
    EXPECT_NEAR(ramps[0].grade, -kGrade, 1e-12);
    EXPECT_EQ(ramps[1].start_m, 50);
    EXPECT_THROW(lookup::sim::parseGrade("10 40 -1:3"), std::invalid_argument);
    EXPECT_THROW(lookup::sim::parseGrade("10 40 steep"), std::invalid_argument);
    EXPECT_THROW(lookup::sim::parseGrade("40 10 0.1"), std::invalid_argument);
}

}  // namespace

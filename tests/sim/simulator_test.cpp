// The generated dataset: layout per docs/dataset-format.md, sensors on their own clocks inside the
// ground truth, drifting odometry, same seed same bytes, and the mini presets' size budget.

#include <gtest/gtest.h>

#include <lookup/common/pose_files.h>
#include <lookup/common/rawlog_io.h>
#include <lookup/sim/simulator.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/core/Clock.h>
#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/serialization/CArchive.h>
#include <sstream>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include "lookup/test/support.h"
#include "test_worlds.h"

namespace {

namespace fs = std::filesystem;
using lookup::sim::ScenarioOptions;
using lookup::sim::SimulationResult;
using lookup::sim::Simulator;
using lookup::sim::testing::tinyScenario;

/// Every file under `root` by relative path; scenario.ini without its `threads` line, the one
/// key that may differ between runs that must give the same data.
std::map<std::string, std::string> allFiles(const fs::path& root) {
    std::map<std::string, std::string> files;
    for (const auto& e : fs::recursive_directory_iterator(root)) {
        if (!e.is_regular_file()) continue;
        std::string bytes = lookup::test::readText(e.path());
        if (e.path().filename() == "scenario.ini") {
            const auto at = bytes.find("threads");
            if (at == std::string::npos) {
                ADD_FAILURE() << "scenario.ini has no threads key";
            } else {
                bytes.erase(at, bytes.find('\n', at) - at);
            }
        }
        files[fs::relative(e.path(), root).string()] = bytes;
    }
    return files;
}

TEST(Simulator, WritesTheDatasetLayout) {
    const fs::path dir = lookup::test::freshDir("lookup_sim_test_layout");
    const ScenarioOptions sc = tinyScenario();
    const Simulator sim(sc);
    const SimulationResult r = sim.run(dir.string());
    ASSERT_EQ(r.status, SimulationResult::Status::Ok) << r.reason;
    for (const char* f : {"dataset.ini", "scenario.ini", "map.gridmap.gz", "map.png",
                          "middle.rawlog", "middle.rawlog.GT.txt", "zigzag.rawlog"}) {
        EXPECT_TRUE(fs::is_regular_file(dir / f)) << f;
    }
    mrpt::config::CConfigFile ini((dir / "dataset.ini").string());
    EXPECT_EQ(ini.read_int("dataset", "traverse_count", 0), 2);
    EXPECT_EQ(ini.read_string("dataset", "ceiling_camera_label", ""), "CEILING_CAM");
    EXPECT_EQ(ini.read_string("traverse_1", "rawlog", ""), "zigzag.rawlog");
    EXPECT_EQ(ini.read_string("traverse_1", "roles", ""), "query");
    // No truth for the survey: no ceiling height, and the mapping traverse's start and end
    // poses (where the drive ends at rest) as an operator gives them, each with an error of its
    // own within 0.05 m and 0.1 deg of the truth, never exactly it.
    EXPECT_FALSE(ini.keyExists("dataset", "ceiling_height_m"));
    const auto expectMark = [&](const char* key, const mrpt::poses::CPose3D& truth) {
        EXPECT_FALSE(ini.keyExists("traverse_1", key));
        std::istringstream in(ini.read_string("traverse_0", key, ""));
        double x = 0, y = 0, yaw_deg = 0;
        ASSERT_TRUE(in >> x >> y >> yaw_deg) << key;
        const double d = std::hypot(x - truth.x(), y - truth.y());
        EXPECT_GT(d, 0.01) << key;
        EXPECT_LT(d, 0.06) << key;
        EXPECT_LT(std::abs(yaw_deg - mrpt::RAD2DEG(truth.yaw())), 0.11) << key;
    };
    expectMark("start_pose", sim.groundTruth(0).front().pose);
    expectMark("end_pose", sim.groundTruth(0).back().pose);
    // The map is an MRPT occupancy grid: free along the route, occupied rock beside it.
    mrpt::maps::COccupancyGridMap2D grid;
    {
        mrpt::io::CFileGZInputStream f((dir / "map.gridmap.gz").string());
        auto arch = mrpt::serialization::archiveFrom(f);
        arch >> grid;
    }
    const auto& start = sim.world().route()[20];
    EXPECT_GT(grid.getPos(start.x(), start.y()), 0.9f);
    EXPECT_LT(grid.getPos(start.x(), start.y() + sc.world.width_m), 0.1f);
    // The resolved scenario reads back as the same scenario.
    EXPECT_EQ(ScenarioOptions::fromFile((dir / "scenario.ini").string()).toIniText(),
              sc.toIniText());
}

TEST(Simulator, SensorsRunOnTheirOwnClocksInsideTheGroundTruth) {
    const fs::path dir = lookup::test::freshDir("lookup_sim_test_clocks");
    const ScenarioOptions sc = tinyScenario();
    const SimulationResult r = Simulator(sc).run(dir.string());
    ASSERT_EQ(r.status, SimulationResult::Status::Ok) << r.reason;
    double previous_end = 0;
    for (const auto& t : r.traverses) {
        const auto gt = lookup::common::readPoseFile((dir / (t.name + ".rawlog.GT.txt")).string());
        ASSERT_GT(gt.size(), 100u);
        EXPECT_GT(gt.front().time_s, previous_end) << "traverses overlap in time";
        previous_end = gt.back().time_s;
        lookup::common::RawlogReader reader((dir / (t.name + ".rawlog")).string());
        mrpt::obs::CObservation::Ptr obs;
        std::map<std::string, std::size_t> count;
        std::map<std::string, double> last;
        double odo_length = 0;
        mrpt::poses::CPose2D last_odo;
        bool have_odo = false;
        while (reader.next(obs)) {
            const double ts = mrpt::Clock::toDouble(obs->timestamp);
            EXPECT_GE(ts, gt.front().time_s);
            EXPECT_LE(ts, gt.back().time_s);
            if (count[obs->sensorLabel]) {
                EXPECT_GT(ts, last[obs->sensorLabel]);
            }
            last[obs->sensorLabel] = ts;
            ++count[obs->sensorLabel];
            if (auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(obs)) {
                if (count[obs->sensorLabel] == 1) {
                    const auto& image = img->image;
                    EXPECT_EQ(image.getWidth(), img->cameraParams.ncols);
                    EXPECT_TRUE(image.isExternallyStored());
                }
            }
            if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(obs)) {
                if (have_odo) odo_length += (odo->odometry - last_odo).norm();
                last_odo = odo->odometry;
                have_odo = true;
            }
        }
        EXPECT_EQ(count["CEILING_CAM"], t.ceiling_frames);
        EXPECT_EQ(count["FORWARD_CAM"], t.forward_frames);
        EXPECT_EQ(count["LIDAR"], t.lidar_scans);
        EXPECT_EQ(count["ODOMETRY"], t.odometry_records);
        // 25 Hz ceiling camera: about rate * duration frames.
        EXPECT_NEAR(double(t.ceiling_frames), 25.0 * t.duration_s, 2.0);
        // Odometry drifts: its path is (1 + scale_error) times the true one.
        EXPECT_NEAR(odo_length / t.length_m, 1 + sc.odometry.scale_error, 0.006);
    }
}

TEST(Simulator, SameSeedGivesTheSameBytesWhateverTheThreadCount) {
    ScenarioOptions sc = tinyScenario();
    sc.traverses.resize(1);
    const fs::path a = lookup::test::freshDir("lookup_sim_test_seed_a"),
                   b = lookup::test::freshDir("lookup_sim_test_seed_b"),
                   c = lookup::test::freshDir("lookup_sim_test_seed_c");
    sc.threads = 1;
    ASSERT_EQ(Simulator(sc).run(a.string()).status, SimulationResult::Status::Ok);
    sc.threads = 2;
    ASSERT_EQ(Simulator(sc).run(b.string()).status, SimulationResult::Status::Ok);
    const auto fa = allFiles(a), fb = allFiles(b);
    ASSERT_EQ(fa.size(), fb.size());
    EXPECT_GT(fa.size(), 50u);
    for (const auto& [name, bytes] : fa) {
        ASSERT_TRUE(fb.count(name)) << name;
        EXPECT_TRUE(fb.at(name) == bytes) << name << " differs";
    }
    // A different seed gives a different mine.
    sc.seed = 12;
    ASSERT_EQ(Simulator(sc).run(c.string()).status, SimulationResult::Status::Ok);
    const auto fc = allFiles(c);
    EXPECT_NE(fc.at("middle_Images/CEILING_CAM_000010.png"),
              fa.at("middle_Images/CEILING_CAM_000010.png"));
}

TEST(Simulator, UnwritableOutputIsAnOutcomeNotACrash) {
    const SimulationResult r = Simulator(tinyScenario()).run("/proc/lookup-sim-cannot-write");
    EXPECT_EQ(r.status, SimulationResult::Status::Failed);
    EXPECT_NE(r.reason.find("/proc/lookup-sim-cannot-write"), std::string::npos) << r.reason;
}

TEST(Simulator, MiniPresetsStayUnder50MB) {
    // Generating both minis in full takes minutes on a loaded 2-core CI machine, so the cameras
    // run at 1/20 of their rate over the whole route and the image bytes are scaled back up;
    // the full-rate figures are measured by `lookup-sim --preset ...` (docs/sim.md).
    constexpr double kDecimation = 20;
    for (const char* name : {"mine-b-mini", "mine-a-mini"}) {
        ScenarioOptions sc = ScenarioOptions::fromFile(
            lookup::sim::findPreset(name, {std::string(LOOKUP_SOURCE_SHARE_DIR) + "/scenarios"}));
        sc.ceiling_camera.rate_hz /= kDecimation;
        sc.forward_camera.rate_hz /= kDecimation;
        const fs::path dir = lookup::test::freshDir(std::string("lookup_sim_test_") + name);
        const auto start = std::chrono::steady_clock::now();
        const SimulationResult r = Simulator(sc).run(dir.string());
        const double secs =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
        ASSERT_EQ(r.status, SimulationResult::Status::Ok) << r.reason;
        uint64_t images = 0;
        for (const auto& e : fs::recursive_directory_iterator(dir)) {
            if (e.is_regular_file() && e.path().extension() == ".png" &&
                e.path().parent_path() != dir) {
                images += e.file_size();
            }
        }
        const double estimate = double(r.total_bytes - images) + kDecimation * images;
        std::cout << name << ": estimated full size " << estimate / 1e6 << " MB (1/" << kDecimation
                  << " camera rate generated in " << secs << " s)\n";
        EXPECT_LT(estimate, 50e6) << name;
    }
}

}  // namespace

// The health monitor and the fix persister on their own, with times given by the test.

#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <thread>

#include "lookup/localize/fix_store.h"
#include "lookup/localize/health.h"
#include "lookup/test/support.h"

using namespace lookup::localize;
namespace fs = std::filesystem;

TEST(HealthMonitor, ReportsAStoppedCameraAtItsTimeoutAndItsReturn) {
    HealthMonitor health("CEILING_CAM", /*interval_s=*/1.0, /*camera_timeout_s=*/1.0);
    EXPECT_FALSE(health.tick(0.5));
    for (int k = 0; k <= 10; ++k) health.observe("CEILING_CAM", 100 + 0.1 * k, 0.5 + 0.1 * k);
    const auto periodic = health.tick(1.55);  // one second in: the periodic message
    ASSERT_TRUE(periodic);
    EXPECT_EQ((*periodic)["camera"], "ok");
    EXPECT_EQ((*periodic)["frames_received"]["CEILING_CAM"], 11);
    EXPECT_TRUE((*periodic)["events"].empty());
    // The last frame came at 1.5 s: silent up to the timeout, reported just after it.
    const auto before = health.tick(2.45);  // the next periodic one (due since 2.0 s)
    ASSERT_TRUE(before);
    EXPECT_EQ((*before)["camera"], "ok");
    EXPECT_TRUE((*before)["events"].empty());
    EXPECT_FALSE(health.tick(2.49));
    const auto stopped = health.tick(2.501);
    ASSERT_TRUE(stopped);
    EXPECT_EQ((*stopped)["camera"], "stopped");
    ASSERT_EQ((*stopped)["events"].size(), 1u);
    EXPECT_NE((*stopped)["events"][0].get<std::string>().find("CEILING_CAM stopped: no frame "
                                                              "for 1.00 s"),
              std::string::npos)
        << (*stopped)["events"][0];
    EXPECT_FALSE(health.tick(2.6));  // reported once, not at every tick
    health.observe("CEILING_CAM", 103.0, 4.0);
    const auto resumed = health.tick(4.0);
    ASSERT_TRUE(resumed);
    EXPECT_EQ((*resumed)["camera"], "ok");
    EXPECT_NE((*resumed)["events"][0].get<std::string>().find("resumed after 2.50 s"),
              std::string::npos)
        << (*resumed)["events"][0];
    EXPECT_EQ(health.summary()["camera_stops"], 1);
}

TEST(HealthMonitor, ReportsAClockJumpWithItsSensorAndSize) {
    HealthMonitor health("CEILING_CAM", 0, 0);  // no periodic messages, no camera timeout
    health.observe("ODOMETRY", 10.0, 0);
    health.observe("ODOMETRY", 10.5, 0.5);
    EXPECT_FALSE(health.tick(0.5));
    health.observe("ODOMETRY", 7.25, 0.6);
    const auto m = health.tick(0.6);
    ASSERT_TRUE(m);
    EXPECT_EQ((*m)["clock_jumps"]["ODOMETRY"], 1);
    EXPECT_NE((*m)["events"][0].get<std::string>().find("ODOMETRY clock jumped back 3.250 s"),
              std::string::npos)
        << (*m)["events"][0];
    EXPECT_DOUBLE_EQ(health.summary()["clock_jumps"]["ODOMETRY"]["largest_s"].get<double>(), 3.25);
}

TEST(FixPersister, WritesTheLastRefinedFixAtItsIntervalAndAtFlush) {
    const auto dir = lookup::test::freshDir("lookup_fix_persister");
    const std::string path = (dir / "fix.json").string();
    FixPersister persister(path, /*interval_s=*/0.05, "/db", "id-1");
    FrameResult frame;
    frame.status = FrameStatus::Refined;
    frame.has_pose = true;
    for (int k = 0; k < 10; ++k) {
        frame.time_s = 100 + k;
        frame.pose.mean = mrpt::poses::CPose2D(k, 2 * k, 0.1);
        persister.update(frame);
        std::this_thread::sleep_for(std::chrono::milliseconds(30));
    }
    FrameResult lost;  // not trusted: does not replace the fix
    lost.status = FrameStatus::Fallback;
    lost.has_pose = true;
    lost.pose.mean = mrpt::poses::CPose2D(-50, -50, 0);
    persister.update(lost);
    EXPECT_GE(persister.writes(), 2u);  // while running, not only at the end
    persister.flush();
    std::string why_not;
    const auto fix = readFixFile(path, "id-1", why_not);
    ASSERT_TRUE(fix) << why_not;
    EXPECT_DOUBLE_EQ(fix->time_s, 109);
    EXPECT_DOUBLE_EQ(fix->pose.mean.x(), 9);
    EXPECT_DOUBLE_EQ(fix->pose.mean.y(), 18);
    EXPECT_FALSE(readFixFile(path, "id-2", why_not));
    EXPECT_NE(why_not.find("another database"), std::string::npos) << why_not;
    for (const auto& entry : fs::directory_iterator(dir)) {
        EXPECT_EQ(entry.path().filename(), "fix.json") << "left behind: " << entry.path();
    }
    std::ofstream(path) << R"({"format": "lookup-fix", "t_fix": 1, "t_saved": 2, "x": NaN})";
    EXPECT_FALSE(readFixFile(path, "id-1", why_not));
    EXPECT_NE(why_not.find("corrupt"), std::string::npos) << why_not;
}

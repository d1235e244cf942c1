// The survey's estimate of the lidar's sweep time from the scans of a lookup-sim tunnel drive.
#include <gtest/gtest.h>

#include <mrpt/config/CConfigFile.h>

#include <cmath>

#include "lidar_drives.h"
#include "lookup/survey/lidar_sweep.h"

using namespace lookup::survey;

namespace {

const mrpt::config::CConfigFile& surveyIni() {
    static mrpt::config::CConfigFile ini(std::string(LOOKUP_SOURCE_SHARE_DIR) + "/survey.ini");
    return ini;
}

LidarSweepEstimate estimateOn(const lookup::test::Drive& d, SurveyOptions o = {}) {
    PoseGraphOptions graph;
    graph.loadFromConfigFile(surveyIni(), "pose_graph");
    return estimateLidarSweep(d.data, graph, surveyIni(), o);
}

float firstRange(const TraverseData& d) {
    for (const auto& o : d.laser_sequence) {
        if (auto s = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            return s->getScanRange(s->getScanSize() / 3);
        }
    }
    return 0;
}

}  // namespace

TEST(LidarSweep, A75MillisecondSweepIsFoundFromTheScans) {
    const lookup::sim::TunnelWorld world(lookup::test::bentTunnel(80), 5);
    const auto d = lookup::test::drive(world, 0.0, 1000, 1, 0.075);
    const float before = firstRange(d.data);
    const LidarSweepEstimate e = estimateOn(d);
    EXPECT_EQ(e.source, "estimated") << e.warning;
    EXPECT_NEAR(e.sweep_ms, 75, 8);
    EXPECT_NEAR(e.scan_period_ms, 100, 1);
    EXPECT_GE(e.tried.size(), 5u);
    EXPECT_EQ(firstRange(d.data), before);  // the traverse's own scans stay as read
}

TEST(LidarSweep, AnInstantaneousScannerKeepsTheConfiguredZero) {
    const lookup::sim::TunnelWorld world(lookup::test::bentTunnel(80), 5);
    const LidarSweepEstimate e = estimateOn(lookup::test::drive(world, 0.0, 1000, 1));
    EXPECT_EQ(e.source, "configured");
    EXPECT_EQ(e.warning, "");
    EXPECT_EQ(e.sweep_ms, 0);
    // The scans are what kept it: the 75 ms sweep of the test above costs far more.
    ASSERT_GE(e.tried.size(), 5u);
    EXPECT_GT(e.tried[3].second, 1.5 * e.tried[0].second);
}

TEST(LidarSweep, TooShortADriveKeepsTheConfiguredSweepWithAWarning) {
    const lookup::sim::TunnelWorld world(lookup::test::bentTunnel(80), 5);
    SurveyOptions o;
    o.lidar_sweep_ms = 60;
    o.lidar_sweep_estimate_m = 5;  // 10 scans
    const LidarSweepEstimate e = estimateOn(lookup::test::drive(world, 0.0, 1000, 1, 0.075), o);
    EXPECT_EQ(e.source, "configured");
    EXPECT_EQ(e.sweep_ms, 60);
    EXPECT_NE(e.warning.find("lidar sweep not estimated"), std::string::npos) << e.warning;
}

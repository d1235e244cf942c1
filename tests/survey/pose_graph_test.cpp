// The survey's pose-graph back end on scans of a bent, rough-walled lookup-sim tunnel.
#include <gtest/gtest.h>

#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <algorithm>
#include <cmath>

#include "lidar_drives.h"
#include "lookup/common/config.h"
#include "lookup/common/options_table.h"
#include "lookup/sim/simulator.h"
#include "lookup/sim/world.h"
#include "lookup/survey/pose_graph.h"

using namespace lookup::survey;
using lookup::test::bentTunnel;
using lookup::test::drive;
using lookup::test::Drive;

namespace {

/// Mean and max position error of `track` against `truth`.
std::pair<double, double> errors(const lookup::common::PoseTrack& track,
                                 const lookup::common::PoseTrack& truth) {
    double sum = 0, worst = 0;
    for (std::size_t i = 0; i < track.size(); ++i) {
        const double e = std::hypot(track[i].pose.x() - truth[i].pose.x(),
                                    track[i].pose.y() - truth[i].pose.y());
        sum += e;
        worst = std::max(worst, e);
    }
    return {sum / double(track.size()), worst};
}

}  // namespace

TEST(PoseGraph, RegistrationsRemoveTheOdometryDrift) {
    const lookup::sim::TunnelWorld world(bentTunnel(), 5);
    const Drive d = drive(world, 0.0, 1000, 1);
    const auto [odo_mean, odo_max] = errors(d.odometry, d.truth);
    ASSERT_GT(odo_max, 2.0);  // 0.05 deg/m over 150 m: metres off at the end

    PoseGraphOptions options;
    options.max_correction_m = 3.0;  // the first estimate is dead reckoning here
    options.max_correction_deg = 3.0;
    PoseGraphReport report;
    std::vector<std::vector<mrpt::math::CMatrixDouble33>> covs;
    const auto out = optimisePoseGraph({{&d.data, d.odometry}}, options, &report, {}, &covs);
    ASSERT_EQ(out.size(), 1u);
    // Marginal covariances: zero at the fixed start, growing along the open drive, and the
    // actual error inside their 99 % bound almost everywhere.
    ASSERT_TRUE(report.covariance_ok);
    ASSERT_EQ(covs.at(0).size(), d.truth.size());
    const auto& c = covs[0];
    EXPECT_LT(c.front()(0, 0) + c.front()(1, 1), 1e-12);
    EXPECT_GT(c.back()(0, 0) + c.back()(1, 1), c[c.size() / 2](0, 0) + c[c.size() / 2](1, 1));
    std::size_t inside = 0;
    for (std::size_t i = 1; i < c.size(); ++i) {
        const double e2 = std::pow(out[0][i].pose.x() - d.truth[i].pose.x(), 2) +
                          std::pow(out[0][i].pose.y() - d.truth[i].pose.y(), 2);
        inside += e2 <= 9.21 * (c[i](0, 0) + c[i](1, 1));  // chi2(2 dof, 99 %) on the trace
    }
    EXPECT_GT(double(inside), 0.9 * double(c.size()));
    ASSERT_EQ(out[0].size(), d.truth.size());
    const auto [mean, worst] = errors(out[0], d.truth);
    EXPECT_LT(mean, 0.05) << "odometry " << odo_mean;
    EXPECT_LT(worst, 0.12);
    // Beyond ~8 m two scans of a 5.5 m wide tunnel share too few walls and are dropped.
    EXPECT_GT(report.registrations, 8 * report.keyframes);
    EXPECT_LT(report.rejected_registrations, report.registrations / 2);
    EXPECT_EQ(report.cross_registrations, 0u);
    EXPECT_EQ(out[0][7].time_s, d.truth[7].time_s);
}

TEST(PoseGraph, TwoTraversesAreTiedTogether) {
    const lookup::sim::TunnelWorld world(bentTunnel(), 5);
    const Drive a = drive(world, 0.8, 1000, 1);
    const Drive b = drive(world, -0.8, 2000, 2);
    PoseGraphOptions options;
    options.max_correction_m = 3.0;
    options.max_correction_deg = 3.0;
    // The second traverse's first estimate: its truth moved by 0.25 m and turned by 0.1 deg
    // (0.3 m more at the far end), as if localised on a distorted map: the registrations
    // across the traverses must undo it.
    lookup::common::PoseTrack shifted = b.truth;
    const mrpt::poses::CPose3D offset(mrpt::poses::CPose2D(0.2, -0.15, mrpt::DEG2RAD(0.1)));
    for (auto& p : shifted) p.pose = offset + p.pose;
    PoseGraphReport report;
    const auto out = optimisePoseGraph({{&a.data, a.truth}, {&b.data, shifted}}, options, &report);
    ASSERT_EQ(out.size(), 2u);
    EXPECT_GT(report.cross_registrations, a.truth.size());
    EXPECT_LT(errors(out[0], a.truth).first, 0.03);
    EXPECT_LT(errors(out[1], b.truth).first, 0.05);
    EXPECT_GT(errors(shifted, b.truth).first, 0.2);
}

TEST(PoseGraph, ThroughAnOdometryDropoutTheScansFollowTheOdometry) {
    const lookup::sim::TunnelWorld world(bentTunnel(), 5);
    Drive d = drive(world, 0.0, 1000, 1);
    // 1.2 s without odometry readings in the middle of the drive (6 m at 5 m/s); the first
    // estimate stands still there, as ICP-SLAM does without odometry along a featureless drive.
    const double t_from = d.truth[d.truth.size() / 2].time_s;
    const double t_to = t_from + 1.2;
    auto& seq = d.data.laser_sequence;
    seq.erase(std::remove_if(seq.begin(), seq.end(),
                             [&](const mrpt::obs::CObservation::Ptr& o) {
                                 const double t = mrpt::Clock::toDouble(o->timestamp);
                                 return IS_CLASS(*o, mrpt::obs::CObservationOdometry) &&
                                        t > t_from + 1e-6 && t < t_to - 1e-6;
                             }),
              seq.end());
    lookup::common::PoseTrack first = d.truth;
    std::vector<std::size_t> inside;
    for (std::size_t i = 1; i < first.size(); ++i) {
        if (first[i].time_s > t_from + 1e-6 && first[i].time_s < t_to - 1e-6) {
            first[i].pose = first[i - 1].pose;
            inside.push_back(i);
        }
    }
    ASSERT_GE(inside.size(), 10u);
    PoseGraphReport report;
    const auto out = optimisePoseGraph({{&d.data, first}}, PoseGraphOptions(), &report);
    ASSERT_EQ(out.size(), 1u);
    // Without the odometry's interpolated motion the scans stood with the last one before the
    // dropout (up to 6 m behind) and the graph's odometry links held them there.
    for (std::size_t i : inside) {
        EXPECT_NEAR(out[0][i].pose.x(), d.truth[i].pose.x(), 0.15) << i;
        EXPECT_NEAR(out[0][i].pose.y(), d.truth[i].pose.y(), 0.15) << i;
    }
    EXPECT_LT(errors(out[0], d.truth).first, 0.05);
}

TEST(PoseGraph, SameResultWhateverTheThreadCount) {
    const lookup::sim::TunnelWorld world(bentTunnel(), 5);
    const Drive d = drive(world, 0.0, 1000, 1);
    PoseGraphOptions options;
    options.max_correction_m = 3.0;
    options.max_correction_deg = 3.0;
    const auto run = [&](int threads, std::vector<std::vector<mrpt::math::CMatrixDouble33>>& covs) {
        options.threads = threads;
        PoseGraphReport report;
        auto out = optimisePoseGraph({{&d.data, d.odometry}}, options, &report, {}, &covs);
        EXPECT_TRUE(report.covariance_ok);
        return out;
    };
    std::vector<std::vector<mrpt::math::CMatrixDouble33>> one_covs;
    const auto one = run(1, one_covs);
    for (const int threads : {3}) {
        std::vector<std::vector<mrpt::math::CMatrixDouble33>> covs;
        const auto out = run(threads, covs);
        ASSERT_EQ(out.size(), one.size());
        ASSERT_EQ(covs.size(), one_covs.size());
        for (std::size_t t = 0; t < out.size(); ++t) {
            ASSERT_EQ(out[t].size(), one[t].size());
            ASSERT_EQ(covs[t].size(), one_covs[t].size());
            for (std::size_t i = 0; i < out[t].size(); ++i) {
                // The poses bit for bit: exact comparisons on purpose.
                ASSERT_EQ(out[t][i].pose.x(), one[t][i].pose.x()) << threads << " threads";
                ASSERT_EQ(out[t][i].pose.y(), one[t][i].pose.y()) << threads << " threads";
                ASSERT_EQ(out[t][i].pose.yaw(), one[t][i].pose.yaw()) << threads << " threads";
                // SuiteSparseQR's factorisation may differ in the last bits between runs.
                for (int k = 0; k < 9; ++k) {
                    const double want = one_covs[t][i](k / 3, k % 3);
                    ASSERT_NEAR(covs[t][i](k / 3, k % 3), want, 1e-9 * std::abs(want) + 1e-18)
                        << threads << " threads, pose " << i;
                }
            }
        }
    }
}

TEST(PoseGraph, MismatchedTrackIsRefusedNamingTheRawlog) {
    const lookup::sim::TunnelWorld world(bentTunnel(), 5);
    const Drive d = drive(world, 0.0, 1000, 1);
    auto short_track = d.truth;
    short_track.pop_back();
    try {
        optimisePoseGraph({{&d.data, short_track}}, PoseGraphOptions());
        FAIL() << "no exception";
    } catch (const std::invalid_argument& e) {
        EXPECT_NE(std::string(e.what()).find(d.data.rawlog), std::string::npos) << e.what();
    }
}

TEST(PoseGraph, GridFromTracksSeesTheWalls) {
    const lookup::sim::TunnelWorld world(bentTunnel(), 5);
    const Drive d = drive(world, 0.0, 1000, 1);
    mrpt::config::CConfigFileMemory ini;
    ini.write("MappingApplication_occupancyGrid_00_creationOpts", "resolution", 0.1);
    const auto grid = gridFromTracks({{&d.data, d.truth}}, {d.truth}, ini);
    EXPECT_NEAR(grid.getResolution(), 0.1, 1e-6);
    // Free on the centre line, occupied just beyond a wall.
    const auto& p = d.truth[d.truth.size() / 2].pose;
    EXPECT_GT(grid.getPos(float(p.x()), float(p.y())), 0.6f);
    // Occupied somewhere across the rough wall band on each side.
    const double c = std::cos(p.yaw()), s = std::sin(p.yaw());
    for (const double side : {1.0, -1.0}) {
        float wall = 1.0f;
        for (double r = 2.0; r <= 3.6; r += 0.05) {
            wall = std::min(wall,
                            grid.getPos(float(p.x() - side * s * r), float(p.y() + side * c * r)));
        }
        EXPECT_LT(wall, 0.3f) << "side " << side;
    }
}

TEST(PoseGraphOptions, LoadsSavesAndRefusesBadValues) {
    mrpt::config::CConfigFileMemory ini;
    PoseGraphOptions o;
    o.edges_per_keyframe = 7;
    o.all_traverses = false;
    o.saveToConfigFile(ini, "pose_graph");
    PoseGraphOptions back;
    back.loadFromConfigFile(ini, "pose_graph");
    EXPECT_EQ(back.edges_per_keyframe, 7);
    EXPECT_FALSE(back.all_traverses);
    ini.write("pose_graph", "point_std_m", -1.0);
    EXPECT_THROW(lookup::common::loadAndCheck(back, ini, "pose_graph"),
                 lookup::common::ConfigError);
    mrpt::config::CConfigFileMemory unknown;
    unknown.write("pose_graph", "edges_per_keyframes", 3);
    EXPECT_THROW(back.loadFromConfigFile(unknown, "pose_graph"), lookup::common::ConfigError);
}

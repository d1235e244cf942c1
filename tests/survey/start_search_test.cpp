// Where a survey traverse starts in the map (start_search.h) on a drive the lidar cannot tell
// apart: a straight corridor with smooth walls, the same to a scan everywhere but near its ends,
// under a textured ceiling that is distinct everywhere (or repeats, or changed). The traverse's
// scans and odometry are simulated in memory, its ceiling images rendered at the true poses;
// the mapping traverse's images are placed by its true poses.

#include <gtest/gtest.h>
#include <mrpt/math/wrap2pi.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/random/RandomGenerators.h>

#include <cmath>

#include "lookup/common/pose_files.h"
#include "lookup/refine/testing/synthetic_ceiling.h"
#include "lookup/survey/start_search.h"
#include "lookup/survey/survey.h"
#include "survey_fixture.h"

namespace lookup::survey {
namespace {

namespace synth = refine::synthetic;

constexpr double kCeiling_m = 4.0;
constexpr double kEnd_m = 32;  ///< the corridor's end walls at x = +-kEnd_m

// Smooth walls 3.2 m apart from one end wall to the other.
mrpt::maps::COccupancyGridMap2D uniformCorridor() {
    mrpt::maps::COccupancyGridMap2D grid(-kEnd_m - 2, kEnd_m + 2, -3, 3, 0.05f);
    grid.fill(0.5f);
    for (double x = -kEnd_m; x <= kEnd_m; x += 0.025) {
        for (double y = -1.6; y <= 1.6; y += 0.025) grid.setPos(x, y, 1.0f);
        grid.setPos(x, 1.65, 0.0f);
        grid.setPos(x, -1.65, 0.0f);
    }
    for (double y = -1.65; y <= 1.65; y += 0.025) {
        grid.setPos(-kEnd_m - 0.05, y, 0.0f);
        grid.setPos(kEnd_m + 0.05, y, 0.0f);
    }
    return grid;
}

synth::SyntheticCeiling distinctCeiling() {
    static const auto c = synth::SyntheticCeiling::make(kCeiling_m, 2 * kEnd_m + 8, 0.02, 21);
    return c;
}

// The same 10 m of ceiling over and over (shotcrete panels cast from one mould).
synth::SyntheticCeiling repeatingCeiling() {
    auto c = synth::SyntheticCeiling::make(kCeiling_m, 10.0, 0.02, 22);
    const int tiles = int(std::ceil((2 * kEnd_m + 8) / 10.0)) + 1;
    c.texture = cv::repeat(c.texture, 1, tiles);
    c.x0_m = -5.0 * tiles;
    return c;
}

mrpt::obs::CObservationImage::Ptr ceilingImage(const synth::SyntheticCeiling& ceiling,
                                               const mrpt::poses::CPose3D& vehicle, double t) {
    auto obs = mrpt::obs::CObservationImage::Create();
    obs->sensorLabel = "CEILING_CAM";
    obs->timestamp = mrpt::Clock::fromDouble(t);
    obs->cameraParams = synth::makeCamera(160, 120, 100);
    obs->cameraPose = synth::ceilingCameraOnVehicle();
    obs->image = mrpt::img::CImage(ceiling.render(obs->cameraParams, vehicle + obs->cameraPose),
                                   mrpt::img::DEEP_COPY);
    return obs;
}

// The mapping traverse: the corridor's centre line from one end to the other at 2 m/s.
struct Mapped {
    std::vector<mrpt::obs::CObservationImage::Ptr> images;
    common::PoseTrack track;
    mrpt::poses::CPose3DInterpolator poses;
    CeilingTraverse traverse() const { return {"mapping", &images, &poses}; }
};

Mapped mapped(const synth::SyntheticCeiling& ceiling) {
    Mapped m;
    for (double x = -kEnd_m + 2; x <= kEnd_m - 2; x += 0.05) {
        const double t = 1000 + (x + kEnd_m) / 2.0;
        m.track.push_back({t, mrpt::poses::CPose3D(x, 0, 0, 0, 0, 0)});
    }
    m.poses = common::makeInterpolator(m.track, 1.0);
    for (std::size_t k = 0; k < m.track.size(); k += 5) {
        m.images.push_back(ceilingImage(ceiling, m.track[k].pose, m.track[k].time_s));
    }
    return m;
}

// A traverse driven 6 m at 1 m/s from `start`: odometry exact, scans of the corridor at 8 m
// range, ceiling images every 0.1 s.
TraverseData traverseFrom(const mrpt::poses::CPose2D& start,
                          const synth::SyntheticCeiling& ceiling) {
    mrpt::random::getRandomGenerator().randomize(3);
    const auto grid = uniformCorridor();
    TraverseData d;
    d.rawlog = "start.rawlog";
    for (int k = 0; k <= 60; ++k) {
        const double t = 2000 + 0.1 * k;
        const double s = 0.1 * k;  // a gentle weave, starting straight
        const mrpt::poses::CPose2D moved(s, 0.2 * (1 - std::cos(0.5 * s)), 0.1 * std::sin(0.5 * s));
        const auto pose = start + moved;
        auto odo = mrpt::obs::CObservationOdometry::Create();
        odo->sensorLabel = "ODOMETRY";
        odo->timestamp = mrpt::Clock::fromDouble(t);
        odo->odometry = moved;
        d.laser_sequence.push_back(odo);
        auto scan = mrpt::obs::CObservation2DRangeScan::Create();
        scan->sensorLabel = "LIDAR";
        scan->timestamp = odo->timestamp;
        scan->aperture = mrpt::DEG2RAD(270.0);
        scan->maxRange = 8;
        grid.laserScanSimulator(*scan, pose, 0.5f, 271, 0.01f);
        d.laser_sequence.push_back(scan);
        d.ceiling.push_back(ceilingImage(ceiling, mrpt::poses::CPose3D(pose), t));
    }
    return d;
}

SurveyOptions options() { return lookup::test::shareSurveyOptions(false); }

// The start search as the survey runs it: guesses along the mapping traverse's track.
StartFix findStart(const TraverseData& d, const Mapped& m) {
    return findStartInMap(d, uniformCorridor(), m.track, mrpt::poses::CPose2D(), options());
}

double headingError(const mrpt::poses::CPose2D& a, const mrpt::poses::CPose2D& b) {
    return std::abs(mrpt::math::wrapToPi(a.phi() - b.phi()));
}

TEST(StartSearch, ATraverseStartedAtTheFarEndOfAUniformDriveIsPlacedByTheCeiling) {
    const auto ceiling = distinctCeiling();
    const Mapped m = mapped(ceiling);
    const mrpt::poses::CPose2D truth(18, 0.3, M_PI);  // 14 m from the far end, driving back
    const auto d = traverseFrom(truth, ceiling);
    StartFix fix = findStart(d, m);
    // The lidar alone: fits as good all along the corridor, the one nearest the mapping
    // traverse's start taken, tens of metres off.
    EXPECT_GT(fix.tied.size(), 20u);
    EXPECT_GT(fix.pose.distanceTo(truth), 10.0);
    decideStartByCeiling(fix, d, m.traverse(), kCeiling_m, options());
    EXPECT_EQ(fix.ceiling, "placed");
    EXPECT_LT(fix.pose.distanceTo(truth), 0.1) << fix.pose;
    EXPECT_LT(headingError(fix.pose, truth), mrpt::DEG2RAD(1.0));
}

TEST(StartSearch, ATraverseStartedAtThePortalKeepsItsFitWhenTheCeilingConfirmsIt) {
    const auto ceiling = distinctCeiling();
    const Mapped m = mapped(ceiling);
    // Beside a guess of the search (every metre along the mapping track from its start).
    const mrpt::poses::CPose2D truth(-kEnd_m + 2.1, -0.4, 0.0);
    const auto d = traverseFrom(truth, ceiling);
    StartFix fix = findStart(d, m);
    ASSERT_FALSE(fix.tied.empty());
    const auto lidar = fix.pose;
    decideStartByCeiling(fix, d, m.traverse(), kCeiling_m, options());
    EXPECT_EQ(fix.ceiling, "confirmed");
    EXPECT_EQ(fix.pose, lidar);
    EXPECT_LT(fix.pose.distanceTo(truth), 0.3);
}

// The ceiling's verdict on a far-end start; the lidar's fit must stay when it decides nothing.
std::string verdictLeavingTheFit(const Mapped& m, const TraverseData& d) {
    StartFix fix = findStart(d, m);
    const auto lidar = fix.pose;
    decideStartByCeiling(fix, d, m.traverse(), kCeiling_m, options());
    EXPECT_EQ(fix.pose, lidar);
    return fix.ceiling;
}

TEST(StartSearch, ARepeatingCeilingLeavesTheTieUndecidedAndTheFitNearestTheMappingStart) {
    const auto ceiling = repeatingCeiling();
    EXPECT_EQ(verdictLeavingTheFit(mapped(ceiling), traverseFrom({18, 0.3, M_PI}, ceiling)),
              "ambiguous");
}

TEST(StartSearch, ACeilingChangedSinceTheMappingDriveMatchesNoTie) {
    const auto other = synth::SyntheticCeiling::make(kCeiling_m, 2 * kEnd_m + 8, 0.02, 23);
    EXPECT_EQ(verdictLeavingTheFit(mapped(distinctCeiling()), traverseFrom({18, 0.3, M_PI}, other)),
              "no match");
}

TEST(StartSearch, AStartPlacedByTheCeilingIsSaidInTheSurveysSummary) {
    SurveyResult r;
    r.status = SurveyStatus::Ok;
    for (const std::string verdict : {"placed", "confirmed"}) {
        TraverseReport t;
        t.name = verdict == "placed" ? "against" : "left";
        t.start_ceiling = verdict;
        r.traverses.push_back(t);
    }
    const auto line = r.summaryLine();
    EXPECT_NE(line.find("against's start placed by the ceiling"), std::string::npos) << line;
    EXPECT_EQ(line.find("left's start"), std::string::npos) << line;
}

}  // namespace
}  // namespace lookup::survey

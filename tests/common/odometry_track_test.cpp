// OdometryTrack: interpolation between readings, extrapolation at the last velocity past them.

#include "lookup/common/odometry_track.h"

#include <gtest/gtest.h>

#include <cmath>

using lookup::common::OdometryTrack;
using mrpt::poses::CPose2D;

namespace {

// A vehicle on a circle of radius 10 m at 5 m/s, odometry at 50 Hz for one second.
CPose2D onCircle(double t) {
    const double w = 0.5;  // rad/s
    return CPose2D(10 * std::sin(w * t), 10 * (1 - std::cos(w * t)), w * t);
}

OdometryTrack circleTrack() {
    OdometryTrack track;
    for (int k = 0; k <= 50; ++k) track.add(0.02 * k, onCircle(0.02 * k));
    return track;
}

}  // namespace

TEST(OdometryTrack, InterpolatesBetweenReadingsAndRefusesOutOfOrderOnes) {
    OdometryTrack track = circleTrack();
    EXPECT_FALSE(track.add(0.5, CPose2D(100, 100, 0)));  // earlier than the last: ignored
    EXPECT_FALSE(track.add(1.0, CPose2D(100, 100, 0)));  // as late as the last: ignored
    const auto p = track.at(0.31);
    ASSERT_TRUE(p);
    EXPECT_EQ(p->extrapolated_s, 0.0);
    EXPECT_NEAR(p->pose.x(), onCircle(0.31).x(), 1e-3);
    EXPECT_NEAR(p->pose.y(), onCircle(0.31).y(), 1e-3);
    EXPECT_FALSE(track.at(-0.01));
    EXPECT_FALSE(track.at(1.01));  // no extrapolation allowed by default
}

TEST(OdometryTrack, ExtrapolatesAtTheLastVelocityNotTheLastPose) {
    const OdometryTrack track = circleTrack();
    const auto p = track.at(1.4, 0.5);
    ASSERT_TRUE(p);
    EXPECT_NEAR(p->extrapolated_s, 0.4, 1e-12);
    // The constant turn rate carries on: 2 m further round the circle within a few centimetres
    // (holding the last pose would be 2 m off).
    const CPose2D truth = onCircle(1.4);
    EXPECT_LT(std::hypot(p->pose.x() - truth.x(), p->pose.y() - truth.y()), 0.05);
    EXPECT_NEAR(p->pose.phi(), truth.phi(), 0.01);
    EXPECT_FALSE(track.at(1.6, 0.5));
}

TEST(OdometryTrack, ForgetsOldReadingsButKeepsOneForInterpolation) {
    OdometryTrack track = circleTrack();
    track.forgetBefore(0.51);
    EXPECT_FALSE(track.at(0.49));
    EXPECT_TRUE(track.at(0.505));  // the reading at 0.50 is kept for it
    EXPECT_EQ(track.size(), 26u);
    OdometryTrack single;
    single.add(1.0, CPose2D(1, 2, 0));
    const auto held = single.at(1.2, 1.0);  // one reading: no velocity, the pose is held
    ASSERT_TRUE(held);
    EXPECT_DOUBLE_EQ(held->pose.x(), 1.0);
    EXPECT_NEAR(held->extrapolated_s, 0.2, 1e-12);
}

TEST(OdometryTrack, TravelIsSignedByTheDirectionTheVehicleMovedIn) {
    const CPose2D heading_north(1, 2, M_PI / 2);
    EXPECT_NEAR(lookup::common::signedTravel(heading_north, CPose2D(1, 2.5, M_PI / 2)), 0.5, 1e-12);
    EXPECT_NEAR(lookup::common::signedTravel(heading_north, CPose2D(1, 1.7, M_PI / 2)), -0.3,
                1e-12);
    EXPECT_EQ(lookup::common::signedTravel(heading_north, heading_north), 0.0);
}

TEST(OdometryTrack, APoseInsideADropoutTellsHowFarItIsFromAReading) {
    OdometryTrack track;
    track.add(0.0, onCircle(0.0));
    track.add(0.02, onCircle(0.02));
    track.add(1.02, onCircle(1.02));  // a 1 s dropout
    const auto regular = track.at(0.01), early = track.at(0.32), late = track.at(0.92);
    ASSERT_TRUE(regular && early && late);
    EXPECT_NEAR(regular->gap_s, 0.02, 1e-9);
    EXPECT_NEAR(early->gap_s, 1.0, 1e-9);
    EXPECT_NEAR(early->inside_gap_s, 0.30, 1e-9);  // from the reading before
    EXPECT_NEAR(late->inside_gap_s, 0.10, 1e-9);   // from the reading after
    EXPECT_EQ(late->extrapolated_s, 0.0);
    // What the dropout's readings bracket: 0.5 rad of turn over a 4.95 m chord.
    EXPECT_NEAR(early->gap_turn_rad, 0.5, 1e-9);
    EXPECT_NEAR(early->gap_distance_m, 20 * std::sin(0.25), 1e-9);
    EXPECT_NEAR(regular->gap_turn_rad, 0.01, 1e-9);
}

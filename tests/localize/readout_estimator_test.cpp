// The ceiling cameras' rolling-shutter readouts, estimated from the travel each refined frame's
// rows show: applied where one camera is a rolling shutter nobody configured, left alone where
// both are global shutters, where the two cameras' readouts could cancel, or where one is
// configured.

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "lookup/localize/readout_estimator.h"

using lookup::localize::ReadoutEstimator;
using lookup::localize::ReadoutEstimatorOptions;

namespace {

/// 120 frames of a vehicle speeding up from rest to 11 m/s and braking again over references
/// the survey drove at 5 m/s give or take 1 (or, `survey_as_query`, as the query drives); the
/// rows show `query_s` x its speed less `survey_s` x the survey's, beyond the readouts modelled
/// then, with 1 cm of noise.
ReadoutEstimator drive(double query_s, double survey_s, double configured_query_s = 0,
                       bool survey_as_query = false,
                       const ReadoutEstimatorOptions& options = ReadoutEstimatorOptions()) {
    ReadoutEstimator estimator(options, configured_query_s, 0.0);
    std::mt19937 rng(3);
    std::normal_distribution<double> noise(0, 0.01), wobble(0, 1.0);
    for (int k = 0; k < 120; ++k) {
        const double speed = 11 * std::sin(M_PI * k / 120.0);
        const double survey_speed = survey_as_query ? speed + 0.1 * wobble(rng) : 5 + wobble(rng);
        const double shown = query_s * speed - survey_s * survey_speed;
        const double modelled =
            estimator.queryReadout() * speed - estimator.surveyReadout() * survey_speed;
        estimator.addFrame(speed, survey_speed, {shown - modelled + noise(rng), 0.01});
    }
    return estimator;
}

}  // namespace

TEST(ReadoutEstimator, ARollingShutterNobodyConfiguredIsFoundAndApplied) {
    const auto r = drive(0.030, 0.0);
    ASSERT_TRUE(r.estimate());
    EXPECT_NEAR(r.estimate()->query_s, 0.030, 0.002);
    EXPECT_LT(r.estimate()->query_sigma_s, 0.002);
    EXPECT_TRUE(r.queryApplied());
    EXPECT_NEAR(r.queryReadout(), 0.030, 0.002);
    EXPECT_FALSE(r.surveyApplied());  // its estimate stays near zero
    EXPECT_EQ(r.surveyReadout(), 0.0);
}

TEST(ReadoutEstimator, GlobalShuttersShowNothingToApply) {
    const auto r = drive(0.0, 0.0);
    ASSERT_TRUE(r.estimate());
    EXPECT_NEAR(r.estimate()->query_s, 0.0, 0.002);
    EXPECT_FALSE(r.queryApplied());
    EXPECT_FALSE(r.surveyApplied());
}

TEST(ReadoutEstimator, TwoAlikeCamerasAreAppliedTogetherOrNotAtAll) {
    // The survey drove as the query does: the two readouts cancel in every frame alike, and
    // neither is pinned down alone.
    const auto same = drive(0.020, 0.020, 0.0, true);
    EXPECT_FALSE(same.queryApplied());
    EXPECT_FALSE(same.surveyApplied());
    // At 5 m/s against the query's 0-11 m/s both show, and both are applied.
    const auto both = drive(0.020, 0.020);
    ASSERT_TRUE(both.estimate());
    EXPECT_NEAR(both.estimate()->query_s, 0.020, 0.003);
    EXPECT_NEAR(both.estimate()->survey_s, 0.020, 0.003);
    EXPECT_TRUE(both.queryApplied());
    EXPECT_TRUE(both.surveyApplied());
}

TEST(ReadoutEstimator, WhereTheSurveysReadoutIsNotAppliedOnlyAVehicleAloneIs) {
    // A survey camera clock nobody knows: the survey's readout is never applied, so a vehicle's
    // alike stays out too (the two cancel), and one beside a global shutter is applied.
    ReadoutEstimatorOptions options;
    options.apply_survey = false;
    const auto alike = drive(0.020, 0.020, 0.0, false, options);
    ASSERT_TRUE(alike.estimate());
    EXPECT_NEAR(alike.estimate()->survey_s, 0.020, 0.003);
    EXPECT_FALSE(alike.queryApplied());
    EXPECT_FALSE(alike.surveyApplied());
    const auto alone = drive(0.030, 0.0, 0.0, false, options);
    EXPECT_TRUE(alone.queryApplied());
    EXPECT_NEAR(alone.queryReadout(), 0.030, 0.002);
}

TEST(ReadoutEstimator, AConfiguredReadoutIsKeptAndTheEstimateOnlyReported) {
    const auto r = drive(0.030, 0.0, 0.025);
    ASSERT_TRUE(r.estimate());
    EXPECT_NEAR(r.estimate()->query_s, 0.030, 0.002);  // the rows still show the truth
    EXPECT_FALSE(r.queryApplied());
    EXPECT_EQ(r.queryReadout(), 0.025);
}

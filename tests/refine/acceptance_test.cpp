// The acceptance policy: N_th and d_th decide, and every pose that is not a fix carries the
// configured uncertainty, growing with the distance dead-reckoned.
#include <gtest/gtest.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <cmath>

#include "lookup/common/config.h"
#include "lookup/refine/acceptance.h"

namespace {

using lookup::refine::AcceptanceOptions;
using lookup::refine::AcceptancePolicy;
using lookup::refine::RefineStatus;

AcceptanceOptions options() {
    AcceptanceOptions o;
    o.min_inlier_share = 0.5;
    o.max_offset_m = 1.0;
    return o;
}

TEST(AcceptancePolicy, InlierShareThenOffsetDecide) {
    const AcceptancePolicy policy(options());
    EXPECT_FALSE(policy.judge(0.5, 1.0, true));
    const auto low = policy.judge(0.49, 0.1, true);
    ASSERT_TRUE(low);
    EXPECT_EQ(low->status, RefineStatus::LowInlierShare);
    EXPECT_NE(low->reason.find("N_th"), std::string::npos) << low->reason;
    const auto far = policy.judge(0.9, 1.01, false);
    ASSERT_TRUE(far);
    EXPECT_EQ(far->status, RefineStatus::OffsetTooLarge);
    EXPECT_NE(far->reason.find("nearest reference"), std::string::npos) << far->reason;
    EXPECT_NE(policy.judge(0.9, 1.01, true)->reason.find("coarse pose"), std::string::npos);
}

TEST(AcceptancePolicy, ATrackedFrameHasItsOwnInlierShare) {
    AcceptanceOptions o = options();
    o.min_inlier_share_tracked = 0.3;
    const AcceptancePolicy policy(o);
    EXPECT_FALSE(policy.judge(0.35, 0.1, true, /*tracked=*/true));
    const auto matched = policy.judge(0.35, 0.1, true, /*tracked=*/false);
    ASSERT_TRUE(matched);
    EXPECT_EQ(matched->status, RefineStatus::LowInlierShare);
    const auto tracked = policy.judge(0.29, 0.1, true, /*tracked=*/true);
    ASSERT_TRUE(tracked);
    EXPECT_NE(tracked->reason.find("N_th 0.3"), std::string::npos) << tracked->reason;
    EXPECT_NE(tracked->reason.find("tracked"), std::string::npos) << tracked->reason;
    // d_th holds for a tracked frame too.
    EXPECT_EQ(policy.judge(0.9, 1.01, true, true)->status, RefineStatus::OffsetTooLarge);
    // A tracked frame never needs more than any other.
    o.min_inlier_share_tracked = 0.9;
    EXPECT_FALSE(AcceptancePolicy(o).judge(0.5, 0.1, true, /*tracked=*/true));
}

TEST(AcceptancePolicy, DeadReckoningGrowsWithTheDistance) {
    AcceptanceOptions o = options();
    o.dead_reckoning_sigma_xy_m = 0.1;
    o.dead_reckoning_sigma_xy_per_m = 0.02;
    o.dead_reckoning_sigma_yaw_deg = 1.0;
    o.dead_reckoning_sigma_yaw_deg_per_m = 0.5;
    const AcceptancePolicy policy(o);
    const auto at_fix = policy.deadReckoned(mrpt::poses::CPose2D(1, 2, 0.3), {0.0});
    const auto later = policy.deadReckoned(mrpt::poses::CPose2D(1, 2, 0.3), {10.0});
    EXPECT_NEAR(std::sqrt(at_fix.cov(0, 0)), 0.1, 1e-12);
    EXPECT_NEAR(std::sqrt(later.cov(1, 1)), 0.3, 1e-12);
    EXPECT_NEAR(std::sqrt(later.cov(2, 2)), mrpt::DEG2RAD(6.0), 1e-12);
    EXPECT_DOUBLE_EQ(later.mean.x(), 1.0);
    const auto fallback = policy.fallback(mrpt::poses::CPose2D(0, 0, 0));
    EXPECT_NEAR(std::sqrt(fallback.cov(0, 0)), o.fallback_sigma_xy_m, 1e-12);
}

TEST(AcceptancePolicy, TimeWithoutOdometryGrowsTheUncertainty) {
    AcceptanceOptions o = options();
    o.dead_reckoning_sigma_xy_m = 0.1;
    o.dead_reckoning_sigma_xy_per_m = 0.0;
    o.dead_reckoning_sigma_yaw_deg = 1.0;
    o.dead_reckoning_sigma_yaw_deg_per_m = 0.0;
    o.extrapolation_accel_mps2 = 2.0;
    o.extrapolation_yaw_accel_deg_s2 = 20.0;
    o.unknown_motion_speed_mps = 8.0;
    o.unknown_motion_yaw_rate_deg_s = 10.0;
    const AcceptancePolicy policy(o);
    const mrpt::poses::CPose2D p(1, 2, 0.3);
    // Extrapolated at a known velocity for 0.5 s: half the acceleration times t^2.
    const auto extrapolated = policy.deadReckoned(p, {0.0, 0.5, true});
    EXPECT_NEAR(std::sqrt(extrapolated.cov(0, 0)), 0.1 + 0.25, 1e-12);
    EXPECT_NEAR(std::sqrt(extrapolated.cov(2, 2)), mrpt::DEG2RAD(1.0 + 2.5), 1e-12);
    EXPECT_NEAR(policy.extrapolationSigmaXy({0.0, 0.5, true}), 0.25, 1e-12);
    // No velocity at all: the vehicle may have driven at the assumed speed the whole time.
    const auto unknown = policy.deadReckoned(p, {0.0, 0.5, false});
    EXPECT_NEAR(std::sqrt(unknown.cov(1, 1)), 0.1 + 4.0, 1e-12);
    EXPECT_NEAR(std::sqrt(unknown.cov(2, 2)), mrpt::DEG2RAD(1.0 + 5.0), 1e-12);
}

TEST(AcceptancePolicy, ReadFromItsSectionAndRefusedWhenInvalid) {
    lookup::common::NamedConfigFile ini(
        "[refine.acceptance]\ndead_reckoning_sigma_xy_per_m = 0.03\n", "loc.ini");
    AcceptanceOptions o;
    o.loadFromConfigFile(ini, "refine.acceptance");
    EXPECT_DOUBLE_EQ(o.dead_reckoning_sigma_xy_per_m, 0.03);
    mrpt::config::CConfigFileMemory saved;
    o.saveToConfigFile(saved, "refine.acceptance");
    AcceptanceOptions back;
    back.loadFromConfigFile(saved, "refine.acceptance");
    EXPECT_DOUBLE_EQ(back.dead_reckoning_sigma_xy_per_m, 0.03);
    o.dead_reckoning_sigma_xy_m = 0.0;
    EXPECT_THROW(AcceptancePolicy{o}, lookup::common::ConfigError);
}

}  // namespace

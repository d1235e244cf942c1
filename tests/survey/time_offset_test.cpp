// The survey's camera time offset (time_offset.h) on a drive the test makes: a textured plane
// ceiling rendered at the true exposure times, stamps late by a known latency, a pose track
// at the true times.

#include <gtest/gtest.h>
#include <mrpt/obs/CObservationImage.h>

#include <cmath>

#include "lookup/common/pose_files.h"
#include "lookup/refine/rolling_shutter.h"
#include "lookup/refine/testing/synthetic_ceiling.h"
#include "lookup/survey/time_offset.h"

namespace lookup::survey {
namespace {

namespace synth = refine::synthetic;

constexpr double kT0 = 1000.0;  // time base [s]
constexpr double kCeiling_m = 4.0;

struct Drive {
    std::vector<mrpt::obs::CObservationImage::Ptr> images;
    mrpt::poses::CPose3DInterpolator track;
};

// Travel along the drive at time t: from rest, 1.5 m/s^2 to 3 m/s, cruise, brake to rest
// (`accelerate`), or 3 m/s throughout.
double travelAt(double t, bool accelerate) {
    if (!accelerate) return 3.0 * t;
    const double a = 1.5, v = 3.0, ta = v / a, cruise = 3.0;
    const double s_a = 0.5 * a * ta * ta;
    if (t <= 0) return 0;
    if (t < ta) return 0.5 * a * t * t;
    if (t < ta + cruise) return s_a + v * (t - ta);
    const double tb = std::min(t - ta - cruise, ta);
    return s_a + v * cruise + v * tb - 0.5 * a * tb * tb;
}

// The vehicle on a gently bending path (turning adds to what the images see).
mrpt::poses::CPose3D vehicleAt(double t, bool accelerate) {
    const double s = travelAt(t, accelerate) - 7.5;
    const double y = 0.5 * std::sin(s / 4.0), dy = 0.125 * std::cos(s / 4.0);
    return mrpt::poses::CPose3D(s, y, 0, std::atan(dy), 0, 0);
}

// The vehicle's velocity in its own frame at t (central difference over 2 ms).
refine::VehicleMotion velocityAt(double t, bool accelerate) {
    const double h = 0.001;
    const mrpt::poses::CPose3D d = vehicleAt(t + h, accelerate) - vehicleAt(t - h, accelerate);
    return {d.x() / (2 * h), d.y() / (2 * h), d.yaw() / (2 * h)};
}

// Stamps `latency_s` late; a rolling shutter reading its rows in `readout_s` (0: global)
// stamps its first row.
Drive makeDrive(bool accelerate, double latency_s, bool textured, double readout_s = 0) {
    static const auto ceiling = synth::SyntheticCeiling::make(kCeiling_m, 30.0, 0.015, 7);
    auto flat = ceiling;
    flat.texture = cv::Mat(ceiling.texture.size(), CV_8UC1, cv::Scalar(128));
    const auto& seen = textured ? ceiling : flat;
    const auto camera = synth::makeCamera(160, 120, 100);
    const auto mount = synth::ceilingCameraOnVehicle();
    const double start = -0.5, end = accelerate ? 7.5 : 4.0;
    Drive d;
    common::PoseTrack poses;
    for (double t = start - 0.5; t <= end + 0.5; t += 0.01) {
        poses.push_back({kT0 + t, vehicleAt(t, accelerate)});
    }
    d.track = common::makeInterpolator(poses, 1.0);
    for (double t = start; t <= end; t += 1.0 / 15) {
        auto obs = mrpt::obs::CObservationImage::Create();
        obs->sensorLabel = "CEILING_CAM";
        obs->timestamp = mrpt::Clock::fromDouble(kT0 + t + latency_s);
        obs->cameraParams = camera;
        obs->cameraPose = mount;
        refine::RowTiming rows;
        rows.readout_s = readout_s;
        rows.velocity = velocityAt(t, accelerate);
        const cv::Mat image =
            readout_s > 0 ? seen.renderRollingShutter(camera, mount, vehicleAt(t, accelerate), rows)
                          : seen.render(camera, vehicleAt(t, accelerate) + mount);
        obs->image = mrpt::img::CImage(image, mrpt::img::DEEP_COPY);
        d.images.push_back(obs);
    }
    return d;
}

TimeOffsetEstimate estimate(const Drive& d, const SurveyOptions& o) {
    return estimateTimeOffset({{"drive", &d.images, &d.track}}, kCeiling_m, o);
}

TEST(TimeOffset, EstimatesAKnownLatencyWhileAcceleratingAndBraking) {
    const Drive d = makeDrive(true, 0.040, true);
    SurveyOptions o;
    const auto e = estimate(d, o);
    EXPECT_EQ(e.source, "estimated") << e.warning;
    EXPECT_NEAR(e.offset_s, -0.040, 0.004);
    EXPECT_LT(e.sigma_s, o.time_offset_max_sigma_s);
    EXPECT_GT(e.pairs_used, std::size_t(o.time_offset_min_pairs));
    EXPECT_TRUE(e.warning.empty());
}

TEST(TimeOffset, ARollingShutterOffsetRefersToTheStampedRow) {
    // The image motion is the middle row's: without the readout the fit finds the middle
    // row's offset, half the readout after the first row's; with it, the stamped row's.
    const Drive d = makeDrive(true, 0.040, true, 0.030);
    SurveyOptions o;
    const auto middle = estimate(d, o);
    EXPECT_EQ(middle.source, "estimated") << middle.warning;
    EXPECT_NEAR(middle.offset_s, -0.025, 0.004);
    o.ceiling_readout_ms = 30;
    o.ceiling_stamp_row = common::StampRow::First;
    const auto first = estimate(d, o);
    EXPECT_EQ(first.source, "estimated") << first.warning;
    EXPECT_NEAR(first.offset_s, -0.040, 0.004);
}

TEST(TimeOffset, ConfiguredOffsetIsTheStartOfTheEstimate) {
    // Stamps already corrected by a configured -0.030 s: the images add the remaining -0.010.
    Drive d = makeDrive(true, 0.040, true);
    SurveyOptions o;
    o.ceiling_time_offset_s = -0.030;
    shiftStamps(d.images, o.ceiling_time_offset_s);
    const auto e = estimate(d, o);
    EXPECT_EQ(e.source, "estimated") << e.warning;
    EXPECT_NEAR(e.configured_s, -0.030, 1e-12);
    EXPECT_NEAR(e.offset_s, -0.040, 0.004);
}

TEST(TimeOffset, ARefusedFitBoundsTheConfiguredOffsetByTwiceItsDeviation) {
    // A right configured offset and a fit refused for a (made) strict precision: the applied
    // deviation is the fit's distance from the configured offset and twice its deviation.
    Drive d = makeDrive(true, 0.040, true);
    SurveyOptions o;
    o.ceiling_time_offset_s = -0.040;
    o.time_offset_max_sigma_s = 1e-5;
    shiftStamps(d.images, o.ceiling_time_offset_s);
    const auto e = estimate(d, o);
    EXPECT_EQ(e.source, "configured");
    EXPECT_DOUBLE_EQ(e.offset_s, -0.040);
    ASSERT_GT(e.sigma_s, 0.0);
    EXPECT_NEAR(e.applied_sigma_s, std::hypot(e.fitted_s + 0.040, 2 * e.sigma_s), 1e-12);
    EXPECT_LT(e.applied_sigma_s, 0.005);
}

TEST(TimeOffset, AFitFarFromTheConfiguredOffsetWidensItsDeviationToCoverIt) {
    // The camera is 40 ms late; configured +150 ms (a wrong calibration) with a 50 ms sigma and
    // the fit refused for a (made) strict precision: 190 ms apart contradicts the configured
    // offset, which stays but with the fit's distance as its deviation, and the warning says so.
    // 60 ms apart (configured -100 ms) is within what the fit's bias allows: the sigma stays.
    SurveyOptions o;
    o.time_offset_max_sigma_s = 1e-5;
    for (const double configured : {0.150, -0.100}) {
        Drive d = makeDrive(true, 0.040, true);
        o.ceiling_time_offset_s = configured;
        shiftStamps(d.images, configured);
        const auto e = estimate(d, o);
        EXPECT_EQ(e.source, "configured");
        EXPECT_DOUBLE_EQ(e.offset_s, configured);
        EXPECT_NEAR(e.fitted_s, -0.040, 0.004);
        const bool contradicted = configured > 0;
        EXPECT_EQ(e.contradicted, contradicted);
        EXPECT_EQ(e.warning.find("contradicts it") != std::string::npos, contradicted) << e.warning;
        if (contradicted) {
            EXPECT_NEAR(e.applied_sigma_s, std::hypot(e.fitted_s - configured, 2 * e.sigma_s),
                        1e-12);
            EXPECT_GT(e.applied_sigma_s, 0.18);
        } else {
            EXPECT_DOUBLE_EQ(e.applied_sigma_s, o.ceiling_time_offset_sigma_s);
        }
    }
}

TEST(TimeOffset, ConstantSpeedWarnsAndKeepsTheConfiguredOffset) {
    const Drive d = makeDrive(false, 0.040, true);
    SurveyOptions o;
    o.ceiling_time_offset_s = -0.010;
    const auto e = estimate(d, o);
    EXPECT_EQ(e.source, "configured");
    EXPECT_DOUBLE_EQ(e.offset_s, -0.010);
    EXPECT_NE(e.warning.find("CEILING_CAM time offset not estimated"), std::string::npos)
        << e.warning;
    EXPECT_NE(e.warning.find("ceiling_time_offset_s = -0.0100"), std::string::npos) << e.warning;
}

TEST(TimeOffset, NoTextureWarnsAndKeepsTheConfiguredOffset) {
    const Drive d = makeDrive(true, 0.040, false);
    const auto e = estimate(d, SurveyOptions());
    EXPECT_EQ(e.source, "configured");
    EXPECT_DOUBLE_EQ(e.offset_s, 0.0);
    EXPECT_EQ(e.pairs_measured, 0u);
    EXPECT_NE(e.warning.find("texture"), std::string::npos) << e.warning;
    EXPECT_EQ(timeOffsetJson(e)["estimated"], false);
}

}  // namespace
}  // namespace lookup::survey

// The survey's audit of its laser poses by the ceiling images (pose_audit.h) on drives the test
// makes: three parallel traverses under one textured plane ceiling, images rendered at the true
// poses, and the pose tracks handed to the audit either true or with a stretch moved along the
// drive, as ICP-SLAM does on a featureless drive or through an odometry dropout.

#include <gtest/gtest.h>
#include <mrpt/obs/CObservationImage.h>

#include <cmath>

#include "lookup/common/pose_files.h"
#include "lookup/refine/testing/synthetic_ceiling.h"
#include "lookup/survey/pose_audit.h"
#include "lookup/survey/time_offset.h"

namespace lookup::survey {
namespace {

namespace synth = refine::synthetic;

constexpr double kCeiling_m = 4.0;
constexpr double kSpeed_mps = 3.0;
constexpr double kLength_m = 24.0;

struct Drive {
    std::string name;
    std::vector<mrpt::obs::CObservationImage::Ptr> images;
    mrpt::poses::CPose3DInterpolator track;  ///< what the audit is told
    double t0 = 0;
};

// Along x at `lateral_m`, or back along it when `reverse`.
mrpt::poses::CPose3D truePose(double travel_m, double lateral_m, bool reverse = false) {
    if (reverse) return mrpt::poses::CPose3D(0.5 * kLength_m - travel_m, lateral_m, 0, M_PI, 0, 0);
    return mrpt::poses::CPose3D(travel_m - 0.5 * kLength_m, lateral_m, 0, 0, 0, 0);
}

struct DriveSpec {
    bool reverse = false;
    double latency_s = 0;  ///< image stamps this late
    double speed_mps = kSpeed_mps;
};

// A drive at `lateral_m`; its track is moved `shift_m` along the drive between travel
// `from_m` and `to_m` (ramped over 1 m at each end).
Drive makeDrive(const std::string& name, double t0, double lateral_m, double shift_m = 0,
                double from_m = 0, double to_m = 0, DriveSpec spec = {}) {
    static const auto ceiling = synth::SyntheticCeiling::make(kCeiling_m, 30.0, 0.015, 11);
    const auto camera = synth::makeCamera(160, 120, 100);
    const auto mount = synth::ceilingCameraOnVehicle();
    Drive d{name, {}, {}, t0};
    common::PoseTrack poses;
    for (double s = 0; s <= kLength_m; s += 0.05) {
        const double w = std::clamp(std::min(s - from_m + 1, to_m + 1 - s), 0.0, 1.0);
        poses.push_back(
            {t0 + s / spec.speed_mps, truePose(s + w * shift_m, lateral_m, spec.reverse)});
    }
    d.track = common::makeInterpolator(poses, 1.0);
    for (double s = 0.1; s < kLength_m; s += 0.25) {
        auto obs = mrpt::obs::CObservationImage::Create();
        obs->sensorLabel = "CEILING_CAM";
        obs->timestamp = mrpt::Clock::fromDouble(t0 + s / spec.speed_mps + spec.latency_s);
        obs->cameraParams = camera;
        obs->cameraPose = mount;
        const cv::Mat image = ceiling.render(camera, truePose(s, lateral_m, spec.reverse) + mount);
        obs->image = mrpt::img::CImage(image, mrpt::img::DEEP_COPY);
        d.images.push_back(obs);
    }
    return d;
}

std::vector<CeilingTraverse> traversesOf(const std::vector<Drive>& drives) {
    std::vector<CeilingTraverse> traverses;
    for (const auto& d : drives) traverses.push_back({d.name, &d.images, &d.track});
    return traverses;
}

PoseAudit audit(const std::vector<Drive>& drives, const SurveyOptions& o = {}) {
    return auditLaserPoses(traversesOf(drives), kCeiling_m, o);
}

double timeAt(const Drive& d, double travel_m) { return d.t0 + travel_m / kSpeed_mps; }

TEST(PoseAudit, TrueLaserPosesAgreeEverywhere) {
    const std::vector<Drive> drives{makeDrive("left", 100, 0.5), makeDrive("middle", 200, 0),
                                    makeDrive("right", 300, -0.5)};
    const auto a = audit(drives);
    ASSERT_TRUE(a.ran);
    EXPECT_EQ(a.suspect, 0u);
    EXPECT_EQ(a.disagreed, 0u);
    EXPECT_TRUE(a.stretches.empty());
    // Every sample sees both other traverses; nearly all comparisons find the fix.
    EXPECT_EQ(a.compared, 2 * a.sampled);
    EXPECT_GT(a.agreed, 0.9 * double(a.compared));
    EXPECT_LT(a.max_agreed_m, 0.05);
}

TEST(PoseAudit, AStretchMetresOffAlongTheDriveIsFoundOnThatTraverseOnly) {
    // The middle traverse's track 1.5 m ahead of its images from 8 to 14 m of travel.
    const std::vector<Drive> drives{makeDrive("left", 100, 0.5),
                                    makeDrive("middle", 200, 0, 1.5, 8, 14),
                                    makeDrive("right", 300, -0.5)};
    const auto a = audit(drives);
    ASSERT_FALSE(a.stretches.empty());
    for (const auto& s : a.stretches) {
        EXPECT_EQ(s.traverse, "middle");
        EXPECT_GT(s.sample_s, timeAt(drives[1], 7));
        EXPECT_LT(s.sample_s, timeAt(drives[1], 15));
    }
    const auto& worst = *std::max_element(
        a.stretches.begin(), a.stretches.end(),
        [](const auto& x, const auto& y) { return x.disagreement_m < y.disagreement_m; });
    EXPECT_NEAR(worst.disagreement_m, 1.5, 0.1);
    // Inside the stretch nothing is kept; well outside it everything is.
    EXPECT_TRUE(a.excludes("middle", timeAt(drives[1], 11)));
    EXPECT_FALSE(a.excludes("middle", timeAt(drives[1], 3)));
    EXPECT_FALSE(a.excludes("middle", timeAt(drives[1], 20)));
    EXPECT_FALSE(a.excludes("left", timeAt(drives[0], 11)));
}

// A traverse whose start was found at the wrong place (a uniform drive aliases its lidar) is off
// as a whole: its images match nowhere near its poses, so nothing disagrees; the audit leaves
// the whole traverse out, and only when the other traverses' comparisons agree.
TEST(PoseAudit, AWholeTraversePlacedMetresOffMatchesNowhereAndIsLeftOut) {
    const std::vector<Drive> drives{makeDrive("left", 100, 0.5),
                                    makeDrive("middle", 200, 0, 8.0, -2, kLength_m + 2),
                                    makeDrive("right", 300, -0.5)};
    const auto a = audit(drives);
    EXPECT_EQ(a.traverses_discarded, 1u);
    for (double s : {1.0, 6.0, 12.0, 23.0}) {
        EXPECT_TRUE(a.excludes("middle", timeAt(drives[1], s))) << s;
        EXPECT_FALSE(a.excludes("left", timeAt(drives[0], s))) << s;
        EXPECT_FALSE(a.excludes("right", timeAt(drives[2], s))) << s;
    }
    EXPECT_EQ(poseAuditJson(a)["traverses_discarded"], 1);
    // Placed right, the same traverse is kept whole.
    const std::vector<Drive> right_place{makeDrive("left", 100, 0.5), makeDrive("middle", 200, 0),
                                         makeDrive("right", 300, -0.5)};
    const auto b = audit(right_place);
    EXPECT_EQ(b.traverses_discarded, 0u);
    EXPECT_FALSE(b.excludes("middle", timeAt(right_place[1], 12)));
}

TEST(PoseAudit, ASmallerOffsetBeyondTheLimitIsFoundTooAndOneWithinItIsNot) {
    SurveyOptions o;
    const std::vector<Drive> beyond{makeDrive("left", 100, 0.5),
                                    makeDrive("middle", 200, 0, 0.5, 8, 14),
                                    makeDrive("right", 300, -0.5)};
    const auto a = audit(beyond, o);
    EXPECT_TRUE(a.excludes("middle", timeAt(beyond[1], 11)));
    o.pose_audit_max_disagreement_m = 0.6;
    const auto b = audit(beyond, o);
    EXPECT_TRUE(b.stretches.empty());
}

TEST(PoseAudit, WithTwoTraversesBothSidesOfADisagreementAreDropped) {
    // Nothing tells which of two traverses is wrong: neither keeps references there.
    const std::vector<Drive> drives{makeDrive("left", 100, 0.4, 1.5, 8, 14),
                                    makeDrive("right", 300, -0.4)};
    const auto a = audit(drives);
    EXPECT_TRUE(a.excludes("left", timeAt(drives[0], 11)));
    EXPECT_TRUE(a.excludes("right", timeAt(drives[1], 11.5)));
    EXPECT_FALSE(a.excludes("right", timeAt(drives[1], 3)));
}

TEST(PoseAudit, TraversesFarApartAreNotCompared) {
    const std::vector<Drive> drives{makeDrive("left", 100, 3.0, 1.5, 8, 14),
                                    makeDrive("right", 300, -3.0)};
    const auto a = audit(drives);
    EXPECT_TRUE(a.ran);
    EXPECT_EQ(a.compared, 0u);
    EXPECT_TRUE(a.stretches.empty());
    EXPECT_NE(a.note.find("no two traverses"), std::string::npos) << a.note;
}

TEST(PoseAudit, OneTraverseOrTheAuditOffIsNotAudited) {
    const std::vector<Drive> one{makeDrive("only", 100, 0, 1.5, 8, 14)};
    const auto alone = audit(one);
    EXPECT_FALSE(alone.ran);
    EXPECT_NE(alone.note.find("one reference traverse"), std::string::npos) << alone.note;
    SurveyOptions off;
    off.pose_audit = false;
    const std::vector<Drive> two{makeDrive("left", 100, 0.4, 1.5, 8, 14),
                                 makeDrive("right", 300, -0.4)};
    const auto a = audit(two, off);
    EXPECT_FALSE(a.ran);
    EXPECT_NE(a.note.find("pose_audit = false"), std::string::npos) << a.note;
    EXPECT_FALSE(a.excludes("left", timeAt(two[0], 11)));
}

TEST(PoseAudit, AnUnreadableImageIsInconclusiveNotAnError) {
    std::vector<Drive> drives{makeDrive("left", 100, 0.5), makeDrive("middle", 200, 0),
                              makeDrive("right", 300, -0.5)};
    for (auto& obs : drives[1].images) obs->image.setExternalStorage("/nonexistent/lookup.png");
    PoseAudit a;
    ASSERT_NO_THROW(a = audit(drives));
    EXPECT_TRUE(a.stretches.empty());
    EXPECT_GT(a.inconclusive, 0u);
    EXPECT_GT(a.agreed, 0u);  // left and right still agree with each other
}

TEST(TimeOffsetAcrossTraverses, TraversesDrivenBothWaysPinDownALateCamera) {
    // Stamps 40 ms late: each traverse's references sit 0.12 m ahead along its own motion,
    // so fixes across the two directions lie 0.24 m from the laser poses.
    DriveSpec out, back;
    out.latency_s = back.latency_s = 0.040;
    back.reverse = true;
    const std::vector<Drive> drives{makeDrive("in", 100, 0.3, 0, 0, 0, out),
                                    makeDrive("out", 300, -0.3, 0, 0, 0, back)};
    SurveyOptions o;
    const auto a = audit(drives, o);
    ASSERT_GT(a.fixes.size(), std::size_t(o.time_offset_min_pairs));
    const auto e = estimateTimeOffsetAcrossTraverses(a, traversesOf(drives), 0.0, o);
    EXPECT_EQ(e.source, "estimated") << e.warning;
    EXPECT_EQ(e.method, "across traverses");
    EXPECT_NEAR(e.offset_s, -0.040, 0.004);
    EXPECT_LT(e.sigma_s, o.time_offset_max_sigma_s);
    // Starting from a configured -30 ms (the stamps already corrected by it): the rest.
    DriveSpec out2 = out, back2 = back;
    out2.latency_s = back2.latency_s = 0.010;
    const std::vector<Drive> corrected{makeDrive("in", 100, 0.3, 0, 0, 0, out2),
                                       makeDrive("out", 300, -0.3, 0, 0, 0, back2)};
    const auto b =
        estimateTimeOffsetAcrossTraverses(audit(corrected, o), traversesOf(corrected), -0.030, o);
    EXPECT_EQ(b.source, "estimated") << b.warning;
    EXPECT_NEAR(b.offset_s, -0.040, 0.004);
}

TEST(TimeOffsetAcrossTraverses, TraversesDrivenTheSameWayAtOneSpeedDoNot) {
    // Both references sit equally far ahead: the fixes agree whatever the lateness.
    DriveSpec late;
    late.latency_s = 0.040;
    const std::vector<Drive> drives{makeDrive("left", 100, 0.3, 0, 0, 0, late),
                                    makeDrive("right", 300, -0.3, 0, 0, 0, late)};
    SurveyOptions o;
    const auto e = estimateTimeOffsetAcrossTraverses(audit(drives, o), traversesOf(drives), 0.0, o);
    EXPECT_EQ(e.source, "configured");
    EXPECT_DOUBLE_EQ(e.offset_s, 0.0);
    EXPECT_NE(e.warning.find("velocities differ by"), std::string::npos) << e.warning;
}

}  // namespace
}  // namespace lookup::survey

// Self-supervised labels on the pipe fixture: both classes appear, pipes are outliers, the
// clean ceiling inliers; the time split and the same-traverse exclusion hold; bad input is
// refused naming the file.

#include <gtest/gtest.h>

#include <opencv2/imgproc.hpp>

#include "fixture.h"
#include "lookup/database/reference_database.h"
#include "lookup/fcn/labels.h"
#include "lookup/refine/geometry.h"
#include "lookup/refine/labels.h"

using namespace lookup;
using namespace lookup::fcn;
namespace fs = std::filesystem;

namespace {

struct Shares {
    double inlier_in_pipes = 0, inlier_on_ceiling = 0;
    int in_pipes = 0, on_ceiling = 0;
};

Shares sharesByRegion(const std::vector<refine::PointMatch>& matches, const cv::Mat& mask) {
    Shares s;
    double in_p = 0, in_c = 0;
    for (const auto& m : matches) {
        // Points whose patch is fully inside one region.
        const cv::Rect patch(int(m.reference_px.x) - 10, int(m.reference_px.y) - 10, 20, 20);
        const double pipe_share = cv::mean(mask(patch))[0] / 255.0;
        if (pipe_share > 0.99) {
            ++s.in_pipes;
            in_p += m.inlier;
        } else if (pipe_share < 0.01) {
            ++s.on_ceiling;
            in_c += m.inlier;
        }
    }
    s.inlier_in_pipes = s.in_pipes ? in_p / s.in_pipes : 0;
    s.inlier_on_ceiling = s.on_ceiling ? in_c / s.on_ceiling : 0;
    return s;
}

}  // namespace

TEST(Labels, PipesAreOutliersAndTheCeilingInliers) {
    const auto& sc = fixture::scene();
    const mrpt::poses::CPose3D ref_pose(1.0, 0, 0, 0, 0, 0), query_pose(1.3, 0.2, 0, 0.03, 0, 0);
    const cv::Mat ref = sc.render(ref_pose), query = sc.render(query_pose);
    const auto options = fixture::smallOptions().labels;

    refine::Pinhole cam;
    ASSERT_TRUE(refine::pinholeFrom(sc.camera, cam, nullptr));
    const cv::Matx33d H = refine::ceilingHomography(cam, ref_pose + sc.mount, cam,
                                                    query_pose + sc.mount, fixture::kCeilingHeight);
    const auto labels = labelPair(ref, query, options, &H);
    ASSERT_TRUE(labels.fit.ok) << labels.fit.reason;
    const Shares s = sharesByRegion(labels.matches, sc.pipeMask(ref_pose));
    ASSERT_GT(s.in_pipes, 10);
    ASSERT_GT(s.on_ceiling, 10);
    EXPECT_LT(s.inlier_in_pipes, 0.2);
    EXPECT_GT(s.inlier_on_ceiling, 0.7);

    // Same grid and the same labels as refine::labelGridPoints when the prior is zero motion.
    const auto plain = labelPair(ref, query, options, nullptr).matches;
    const auto reference_impl = refine::labelGridPoints(ref, query, options.grid_step_px,
                                                        options.matcher, options.homography);
    ASSERT_EQ(plain.size(), reference_impl.size());
    for (std::size_t i = 0; i < plain.size(); ++i) {
        EXPECT_EQ(plain[i].reference_px, reference_impl[i].reference_px);
        EXPECT_EQ(plain[i].inlier, reference_impl[i].inlier);
    }
}

// Another vehicle's camera, 0.6 m nearer the ceiling (a fifth larger) and turned 14°: the
// reference patches are warped by the pose prior's homography before SAD compares them, as the
// localiser matches, so the ceiling is labelled on the plane; matched unwarped, at the prior's
// offsets only, most of it is not.
TEST(Labels, AnotherCameraHeightAndHeadingAreLabelledThroughThePriorsWarp) {
    const auto& sc = fixture::scene();
    const mrpt::poses::CPose3D ref_pose(1.0, 0, 0, 0, 0, 0), query_pose(1.2, 0.1, 0.6, 0.25, 0, 0);
    const cv::Mat ref = sc.render(ref_pose), query = sc.render(query_pose);
    const cv::Mat pipes = sc.pipeMask(ref_pose);
    refine::Pinhole cam;
    ASSERT_TRUE(refine::pinholeFrom(sc.camera, cam, nullptr));
    const cv::Matx33d H = refine::ceilingHomography(cam, ref_pose + sc.mount, cam,
                                                    query_pose + sc.mount, fixture::kCeilingHeight);
    const auto ceilingInliers = [&](bool warp) {
        auto options = fixture::smallOptions().labels;
        options.matcher.compensate_motion = warp;
        const auto labels = labelPair(ref, query, options, &H);
        int matched = 0, inliers = 0;  // ceiling points that the query sees
        for (const auto& m : labels.matches) {
            if (!m.matched() || pipes.at<std::uint8_t>(cv::Point(m.reference_px)) != 0) continue;
            ++matched;
            inliers += labels.fit.ok && m.inlier;
        }
        return matched > 20 ? double(inliers) / matched : 0.0;
    };
    const double warped = ceilingInliers(true), unwarped = ceilingInliers(false);
    EXPECT_GT(warped, 0.8);
    EXPECT_GT(warped, unwarped + 0.25) << "warped " << warped << ", unwarped " << unwarped;
}

// `image` of the scene's pinhole camera as `lens` (its intrinsics with distortion) takes it.
cv::Mat throughLens(const cv::Mat& image, const mrpt::img::TCamera& lens) {
    std::vector<cv::Point2f> raw;
    for (int y = 0; y < image.rows; ++y)
        for (int x = 0; x < image.cols; ++x) raw.emplace_back(float(x), float(y));
    const auto pinhole = refine::undistortPixels(raw, lens);
    cv::Mat map_x(image.size(), CV_32FC1), map_y(image.size(), CV_32FC1);
    for (std::size_t i = 0; i < raw.size(); ++i) {
        map_x.at<float>(raw[i]) = float(pinhole[i].x);
        map_y.at<float>(raw[i]) = float(pinhole[i].y);
    }
    cv::Mat out;
    cv::remap(image, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_REPLICATE);
    return out;
}

// Through a strong barrel lens the raw pixels of the ceiling seen twice are no homography:
// labelled on the raw images, most of the ceiling away from the image's centre is labelled off
// the plane; on the rectified images, as the localiser matches them, much less.
TEST(Labels, ThroughADistortingLensTheCeilingIsLabelledOnRectifiedImages) {
    const auto& sc = fixture::scene();
    mrpt::img::TCamera lens = sc.camera;
    lens.setDistortionPlumbBob(-0.35, 0.1, 0, 0, 0);
    const mrpt::poses::CPose3D ref_pose(1.0, 0, 0, 0, 0, 0), query_pose(1.4, 0.2, 0, 0.03, 0, 0);
    const cv::Mat ref = throughLens(sc.render(ref_pose), lens);
    const cv::Mat query = throughLens(sc.render(query_pose), lens);
    auto options = fixture::smallOptions().labels;
    options.precise_inlier_px = 0.75;
    options.matcher.compensate_motion = false;  // the rectification alone: the warp helps both
    refine::Pinhole cam;
    ASSERT_TRUE(refine::pinholeFrom(sc.camera, cam, nullptr));
    const cv::Matx33d H = refine::ceilingHomography(cam, ref_pose + sc.mount, cam,
                                                    query_pose + sc.mount, fixture::kCeilingHeight);
    const cv::Mat pipes = throughLens(sc.pipeMask(ref_pose), lens);
    const auto ceiling_targets = [&](const fcn::PairLabels& labels) {
        int ceiling = 0, targets = 0;
        for (std::size_t i = 0; i < labels.matches.size(); ++i) {
            const auto& m = labels.matches[i];
            if (!m.matched() || pipes.at<std::uint8_t>(cv::Point(m.reference_px)) != 0) continue;
            ++ceiling;
            targets += m.inlier && labels.residual_px[i] <= options.precise_inlier_px;
        }
        return ceiling > 20 ? double(targets) / ceiling : 0.0;
    };
    const fcn::PairCameras cameras{lens, lens};
    const auto raw = labelPair(ref, query, options, &H);
    const auto rectified = labelPair(ref, query, options, &H, &cameras);
    ASSERT_TRUE(rectified.fit.ok) << rectified.fit.reason;
    for (const auto& m : rectified.matches) {  // reference points are raw pixels, inside
        EXPECT_GE(m.reference_px.x, options.matcher.patch_px / 2);
        EXPECT_LT(m.reference_px.x, ref.cols - options.matcher.patch_px / 2);
    }
    EXPECT_GT(ceiling_targets(rectified), ceiling_targets(raw) + 0.15)
        << "raw " << ceiling_targets(raw) << ", rectified " << ceiling_targets(rectified);
}

TEST(Labels, GeneratedFromRawlogsWithATimeSplit) {
    const auto dir = lookup::test::freshDir("lookup_fcn_labels");
    std::vector<double> xs;
    for (double x = -3; x <= 3.01; x += 0.5) xs.push_back(x);
    fixture::writeDatabase((dir / "db").string(), xs);
    const auto track = fixture::drive(-2.6, 2.6, 0.2, 0.15);
    fixture::writeQuery((dir / "q.rawlog").string(), track);

    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    auto options = fixture::smallOptions().labels;
    std::size_t calls = 0;
    const std::string q = (dir / "q.rawlog").string();
    const auto set = generateLabels(db, {q}, {fixture::posesFile(q)}, options,
                                    [&](std::size_t, std::size_t) { ++calls; });
    EXPECT_EQ(set.stats.query_frames, track.size());
    EXPECT_EQ(calls, track.size());
    EXPECT_EQ(set.stats.pairs, 2 * track.size());
    EXPECT_GT(set.stats.training_pairs, 10u);
    EXPECT_GT(set.stats.held_out_pairs, 2u);
    EXPECT_GT(set.stats.inlierShare(), 0.3);
    EXPECT_LT(set.stats.inlierShare(), 0.95);
    // Every held-out frame comes after every training frame.
    double last_train = 0, first_held = 1e18;
    for (const auto& p : set.pairs) {
        if (p.held_out)
            first_held = std::min(first_held, p.query_time_s);
        else
            last_train = std::max(last_train, p.query_time_s);
        EXPECT_EQ(p.points.size(), p.inlier.size());
        EXPECT_LE(p.distance_m, options.max_reference_distance_m);
    }
    EXPECT_LT(last_train, first_held);

    // References surveyed at the query's own time are skipped (a traverse in the database).
    options.min_time_gap_s = 1e12;
    const auto none = generateLabels(db, {q}, {fixture::posesFile(q)}, options);
    EXPECT_EQ(none.stats.pairs, 0u);
    EXPECT_EQ(none.stats.frames_without_reference, track.size());
}

TEST(Labels, PreciseTargetsAreTheInliersThatFitTheHomographyClosely) {
    const auto dir = lookup::test::freshDir("lookup_fcn_labels-precise");
    std::vector<double> xs;
    for (double x = -2; x <= 2.01; x += 0.5) xs.push_back(x);
    fixture::writeDatabase((dir / "db").string(), xs);
    const std::string q = (dir / "q.rawlog").string();
    fixture::writeQuery(q, fixture::drive(-1.6, 1.6, 0.2, 0.15));
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    auto options = fixture::smallOptions().labels;

    // 0: the paper's labels, the targets are the RANSAC inliers.
    options.precise_inlier_px = 0;
    const auto paper = generateLabels(db, {q}, {fixture::posesFile(q)}, options);
    ASSERT_GT(paper.stats.inlier_points, 0u);
    EXPECT_EQ(paper.stats.target_points, paper.stats.inlier_points);
    for (const auto& p : paper.pairs) EXPECT_EQ(p.target, p.inlier);

    // A tight residual keeps a subset of the inliers (and the same inliers for the metric).
    options.precise_inlier_px = 0.3;
    const auto precise = generateLabels(db, {q}, {fixture::posesFile(q)}, options);
    ASSERT_EQ(precise.pairs.size(), paper.pairs.size());
    EXPECT_EQ(precise.stats.inlier_points, paper.stats.inlier_points);
    EXPECT_GT(precise.stats.target_points, 0u);
    EXPECT_LT(precise.stats.target_points, precise.stats.inlier_points);
    for (const auto& p : precise.pairs) {
        ASSERT_EQ(p.target.size(), p.inlier.size());
        for (std::size_t i = 0; i < p.target.size(); ++i) EXPECT_LE(p.target[i], p.inlier[i]);
    }

    options.precise_inlier_px = -1;
    EXPECT_THROW(options.check(), std::runtime_error);
}

// A survey traverse needs no pose file: its frames take the survey's own poses (here the
// frames are the references, so each frame's nearest reference is its own, 0 m away).
TEST(Labels, ASurveyTraverseTrainsOnTheSurveysOwnPoses) {
    const auto dir = lookup::test::freshDir("lookup_fcn_labels_survey");
    const std::vector<double> xs = {-1.0, -0.5, 0.0, 0.5, 1.0, 1.5};
    fixture::writeDatabase((dir / "db").string(), xs);
    common::PoseTrack survey;
    for (std::size_t k = 0; k < xs.size(); ++k) {
        survey.push_back({100.0 + 0.1 * k, mrpt::poses::CPose3D(xs[k], 0, 0, 0, 0, 0)});
    }
    const std::string rawlog = (dir / "survey.rawlog").string();
    fixture::writeQuery(rawlog, survey);
    fs::remove(fixture::posesFile(rawlog));
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    auto options = fixture::smallOptions().labels;
    options.min_time_gap_s = 0;
    options.references_per_query = 1;
    const auto set = generateLabels(db, {rawlog}, {}, options);
    EXPECT_EQ(set.stats.query_frames, xs.size());
    ASSERT_EQ(set.pairs.size(), xs.size());
    for (const auto& p : set.pairs) EXPECT_LT(p.distance_m, 1e-6);
}

TEST(Labels, UnknownPosesAndWrongCameraLabelAreRefusedNamingTheFile) {
    const auto dir = lookup::test::freshDir("lookup_fcn_labels_bad");
    fixture::writeDatabase((dir / "db").string(), {0.0, 0.5});
    const std::string q = (dir / "q.rawlog").string();
    fixture::writeQuery(q, fixture::drive(0, 0.4, 0.2, 0.1));
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const auto options = fixture::smallOptions().labels;
    const auto refusal = [&](const std::vector<std::string>& poses) -> std::string {
        try {
            generateLabels(db, {q}, poses, options);
        } catch (const std::runtime_error& e) {
            return e.what();
        }
        return "";
    };
    // Driven at another time than the survey, without poses: they are unknown.
    const std::string unknown = refusal({});
    EXPECT_NE(unknown.find("q.rawlog"), std::string::npos) << unknown;
    EXPECT_NE(unknown.find("--train-poses"), std::string::npos) << unknown;
    const std::string missing = refusal({(dir / "nowhere.tum").string()});
    EXPECT_NE(missing.find("nowhere.tum"), std::string::npos) << missing;
    EXPECT_NE(refusal({fixture::posesFile(q), fixture::posesFile(q)}).find("2 pose files for 1"),
              std::string::npos);
    EXPECT_THROW(generateLabels(db, {(dir / "missing.rawlog").string()}, {}, options),
                 std::exception);
}

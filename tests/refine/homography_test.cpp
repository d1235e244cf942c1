#include <gtest/gtest.h>
#include <mrpt/poses/CPose3D.h>

#include <cmath>

#include "lookup/refine/homography.h"

using namespace lookup::refine;

namespace {

const cv::Matx33d K(250, 0, 159.5, 0, 250, 119.5, 0, 0, 1);

// H = K (R + t n^T / d) K^-1 for X_query = R X_ref + t (OpenCV's convention).
cv::Matx33d planeHomography(const cv::Matx33d& R, const cv::Vec3d& t, const cv::Vec3d& n,
                            double d) {
    return K * (R + t * n.t() * (1.0 / d)) * K.inv();
}

cv::Matx33d rotation(double yaw, double pitch, double roll) {
    const auto M = mrpt::poses::CPose3D(0, 0, 0, yaw, pitch, roll).getRotationMatrix();
    cv::Matx33d R;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) R(i, j) = M(i, j);
    return R;
}

std::vector<PointMatch> matchesFrom(const cv::Matx33d& H, int n) {
    std::vector<PointMatch> out;
    for (int i = 0; i < n; ++i) {
        PointMatch m;
        m.reference_px = cv::Point2f(30.f + 37.f * (i % 7), 25.f + 41.f * (i / 7));
        const cv::Vec3d q = H * cv::Vec3d(m.reference_px.x, m.reference_px.y, 1);
        m.query_px = cv::Point2f(float(q[0] / q[2]), float(q[1] / q[2]));
        m.status = MatchStatus::Matched;
        out.push_back(m);
    }
    return out;
}

}  // namespace

TEST(Homography, DecompositionPicksSmallestPitchAndRoll) {
    const cv::Matx33d R = rotation(0.2, 0.03, -0.02);  // ~2 deg of tilt
    const cv::Vec3d t(0.3, -0.2, 0.05);
    const cv::Matx33d H = planeHomography(R, t, {0, 0, 1}, 3.5);
    PlaneMotion chosen;
    std::vector<PlaneMotion> all;
    ASSERT_TRUE(decomposeHomography(H, K, K, chosen, &all));
    ASSERT_EQ(all.size(), 4u);
    const double true_tilt = std::acos(R(2, 2)) * 180 / CV_PI;
    EXPECT_NEAR(chosen.tilt_deg, true_tilt, 1e-6);
    EXPECT_LT(cv::norm(chosen.rotation - R), 1e-6);
    EXPECT_LT(cv::norm(chosen.translation_over_d - t * (1 / 3.5)), 1e-6);
    EXPECT_GT(chosen.normal[2], 0.99);
    EXPECT_NEAR(chosen.yaw_deg, 0.2 * 180 / CV_PI, 0.2);
    int larger = 0;
    for (const auto& m : all) larger += m.tilt_deg > chosen.tilt_deg + 1.0 ? 1 : 0;
    EXPECT_GE(larger, 2) << "the other pair of solutions is strongly tilted";
}

TEST(Homography, RansacFlagsOutliersAndIsDeterministic) {
    const cv::Matx33d H = planeHomography(rotation(0.05, 0, 0), {0.1, 0.05, 0}, {0, 0, 1}, 3.5);
    auto matches = matchesFrom(H, 28);
    const std::vector<int> outliers = {3, 9, 17, 22, 26};
    for (int i : outliers) matches[i].query_px += cv::Point2f(15.f, -11.f);
    matches[5].status = MatchStatus::LowTexture;  // never an inlier
    HomographyOptions o;
    auto again = matches;
    const auto r = estimateHomography(matches, o, &K, &K);
    ASSERT_TRUE(r.ok) << r.reason;
    EXPECT_TRUE(r.ransac);
    EXPECT_EQ(r.used_points, 27);
    EXPECT_EQ(r.inliers, 22);
    for (int i : outliers) EXPECT_FALSE(matches[i].inlier) << i;
    EXPECT_FALSE(matches[5].inlier);
    EXPECT_TRUE(matches[0].inlier);
    EXPECT_LT(cv::norm(r.H - H * (1.0 / H(2, 2))), 1e-3);
    const auto r2 = estimateHomography(again, o, &K, &K);
    EXPECT_EQ(r2.H, r.H);
    for (std::size_t i = 0; i < matches.size(); ++i) EXPECT_EQ(again[i].inlier, matches[i].inlier);
}

TEST(Homography, FewPointsUseLeastSquaresAndTooFewFail) {
    const cv::Matx33d H = planeHomography(rotation(0.1, 0, 0), {0.1, 0.0, 0}, {0, 0, 1}, 3.5);
    auto eight = matchesFrom(H, 8);
    const auto r = estimateHomography(eight, HomographyOptions());
    ASSERT_TRUE(r.ok);
    EXPECT_FALSE(r.ransac);
    EXPECT_EQ(r.inliers, 8);
    auto three = matchesFrom(H, 3);
    const auto bad = estimateHomography(three, HomographyOptions());
    EXPECT_FALSE(bad.ok);
    EXPECT_NE(bad.reason.find("3 matched"), std::string::npos) << bad.reason;
}

// The survey without the simulator's truth: the ceiling height measured from images a known
// baseline apart, the map frame from an operator's (inexact) start pose, other traverses found
// in the map by scan matching, dataset.ini without ceiling_height_m.
#include <gtest/gtest.h>

#include <mrpt/config/CConfigFile.h>
#include <mrpt/math/wrap2pi.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "lookup/database/reference_database.h"
#include "lookup/survey/ceiling_distance.h"
#include "lookup/survey/survey.h"
#include "lookup/survey/survey_app.h"
#include "lookup/test/support.h"
#include "survey_fixture.h"

namespace fs = std::filesystem;
using namespace lookup::survey;

namespace {

const mrpt::config::CConfigFile& shareIni() { return lookup::test::shareSurveyIni(); }

SurveyOptions shareOptions() { return lookup::test::shareSurveyOptions(false); }

// Smooth world-fixed value noise on the ceiling plane (8 cm cells, bilinear).
double ceilingGrey(double x, double y) {
    const auto cell = [](long i, long j) {
        const unsigned long h = (i * 73856093UL) ^ (j * 19349663UL);
        return double((h * 2654435761UL >> 9) % 170);
    };
    const double gx = x / 0.08, gy = y / 0.08;
    const long i = long(std::floor(gx)), j = long(std::floor(gy));
    const double fx = gx - i, fy = gy - j;
    return 40 + (1 - fx) * (1 - fy) * cell(i, j) + fx * (1 - fy) * cell(i + 1, j) +
           (1 - fx) * fy * cell(i, j + 1) + fx * fy * cell(i + 1, j + 1);
}

// A pinhole camera looking up at the plane z = h from `camera_in_map`.
cv::Mat renderCeiling(const mrpt::poses::CPose3D& camera_in_map, const mrpt::img::TCamera& cam,
                      double h) {
    cv::Mat img(int(cam.nrows), int(cam.ncols), CV_8UC1);
    const double d = h - camera_in_map.z();
    for (int v = 0; v < img.rows; ++v) {
        for (int u = 0; u < img.cols; ++u) {
            const mrpt::math::TPoint3D local((u - cam.cx()) / cam.fx() * d,
                                             (v - cam.cy()) / cam.fy() * d, d);
            const auto w = camera_in_map.composePoint(local);
            img.at<uint8_t>(v, u) = cv::saturate_cast<uint8_t>(ceilingGrey(w.x, w.y));
        }
    }
    return img;
}

struct GeneratedTraverse {
    std::vector<mrpt::obs::CObservationImage::Ptr> images;
    mrpt::poses::CPose3DInterpolator poses;
};

// 12 m along x at 0.1 m per frame with a gentle heading wobble, ceiling at `h`.
GeneratedTraverse generateTraverse(double h) {
    GeneratedTraverse g;
    const mrpt::img::TCamera cam = lookup::test::pinholeCamera(320, 240, 160);
    const mrpt::poses::CPose3D mount(0.5, 0, 2.0, M_PI / 2, 0, 0);
    for (int k = 0; k <= 120; ++k) {
        const double x = 0.1 * k;
        const mrpt::poses::CPose3D vehicle(x, 0.2 * std::sin(x / 4), 0, 0.05 * std::cos(x / 4), 0,
                                           0);
        const auto t = mrpt::Clock::fromDouble(1.7e9 + 0.1 * k);
        g.poses.insert(t, vehicle.asTPose());
        auto obs = std::make_shared<mrpt::obs::CObservationImage>();
        obs->sensorLabel = "CEILING_CAM";
        obs->timestamp = t;
        obs->cameraPose = mount;
        obs->cameraParams = cam;
        obs->image =
            mrpt::img::CImage(renderCeiling(vehicle + mount, cam, h), mrpt::img::DEEP_COPY);
        g.images.push_back(obs);
    }
    return g;
}

// The known frame offset of a survey whose start pose was `given` while the truth was `truth`:
// map = offset + truth-frame.
mrpt::poses::CPose2D frameOffset(const mrpt::poses::CPose2D& given,
                                 const mrpt::poses::CPose2D& truth) {
    return given + (-truth);
}

void writeDataset(const fs::path& path, const std::string& rawlog, const std::string& extra) {
    std::ofstream f(path);
    f << "[dataset]\nname = corridor\ntraverse_count = 1\n"
      << extra << "\n[traverse_0]\nname = corridor\nrawlog = " << rawlog
      << "\nroles = mapping,reference\nstart_pose = 0 0 5.7106\n";
}

}  // namespace

TEST(CeilingDistance, MeasuredFromGeneratedImagesWithinTwoCentimetres) {
    const double kTrue = 4.2;  // camera at 2.0 m: 2.2 m from the ceiling
    const auto g = generateTraverse(kTrue);
    SurveyOptions o;
    o.ceiling_height_m = 5.0;  // the prior is 0.8 m off
    o.ceiling_sample_spacing_m = 0.5;
    const auto e = estimateCeilingDistance({{"gen", &g.images, &g.poses}}, o);
    ASSERT_TRUE(e.estimated) << e.warning;
    EXPECT_NEAR(e.ceiling_height_m, kTrue, 0.02);
    EXPECT_NEAR(e.camera_to_ceiling_m, kTrue - 2.0, 0.02);
    EXPECT_DOUBLE_EQ(e.camera_z_m, 2.0);
    EXPECT_GE(e.used, std::size_t(o.ceiling_min_pairs));
    EXPECT_LT(e.spread_m, 0.05);
    EXPECT_TRUE(e.warning.empty());
}

TEST(CeilingDistance, APriorFarOffIsSearchedForTheDistanceTheImagesShow) {
    // The camera 1.2 m from the ceiling where 3 m are configured: from the configured prior the
    // matcher looks for every point far outside its window, and no triple is accepted.
    const double kTrue = 3.2;
    const auto g = generateTraverse(kTrue);
    SurveyOptions o;
    o.ceiling_height_m = 5.0;
    o.ceiling_sample_spacing_m = 0.5;
    const auto e = estimateCeilingDistance({{"gen", &g.images, &g.poses}}, o);
    ASSERT_TRUE(e.estimated) << e.warning;
    EXPECT_NEAR(e.ceiling_height_m, kTrue, 0.02);
    EXPECT_TRUE(e.warning.empty());
}

TEST(CeilingDistance, TooFewTriplesWarnAndUseTheConfiguredValue) {
    const auto g = generateTraverse(4.2);
    SurveyOptions o;
    o.ceiling_height_m = 5.0;
    o.ceiling_min_pairs = 1000;  // more than 12 m can give
    const auto e = estimateCeilingDistance({{"gen", &g.images, &g.poses}}, o);
    EXPECT_FALSE(e.estimated);
    EXPECT_DOUBLE_EQ(e.ceiling_height_m, 5.0);
    EXPECT_NE(e.warning.find("ceiling height not estimated"), std::string::npos) << e.warning;
    EXPECT_EQ(ceilingJson(e, "configured")["estimated"], false);
}

TEST(CeilingDistance, SurveyReportsTheConfiguredValueWhenTooFewTriples) {
    const auto dir = lookup::test::freshDir("lookup_nogt_fewpairs");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 4.0);
    SurveyInputs in;
    in.traverses.push_back({"corridor", f.rawlog, f.ground_truth, true, true});
    in.out_dir = (dir / "db").string();
    in.poses_file = kPosesFromGroundTruth;
    auto o = shareOptions();
    o.ceiling_min_pairs = 100000;
    o.ceiling_height_m = 3.7;
    const auto r = Survey(o, shareIni()).run(in);
    ASSERT_TRUE(r.ok()) << r.reason;
    EXPECT_EQ(r.ceiling_source, "configured");
    bool warned = false;
    for (const auto& w : r.warnings) warned |= w.find("ceiling height not estimated") == 0;
    EXPECT_TRUE(warned);
    EXPECT_EQ(nlohmann::json::parse(r.toJson())["ceiling"]["source"], "configured");
    const auto db = lookup::database::ReferenceDatabase::load(in.out_dir);
    EXPECT_DOUBLE_EQ(db.info().ceiling_height_m, 3.7);
}

TEST(StartSearch, StartPoseOffByMetresStillPlacesTheOtherTraverse) {
    const auto dir = lookup::test::freshDir("lookup_nogt_startoff");
    const auto a = lookup::test::makeSurveyRawlog(dir.string(), "a", 12.0);
    const auto b = lookup::test::makeSurveyRawlog(dir.string(), "b", 12.0);
    SurveyInputs in;
    in.traverses.push_back({"a", a.rawlog, a.ground_truth, true, true});
    in.traverses.push_back({"b", b.rawlog, b.ground_truth, false, true});
    in.out_dir = (dir / "db").string();
    const auto truth0 = lookup::test::truePoseAt(0);
    // 1.5 m and 8 deg off the true start: the map frame is this pose, not the truth's.
    const mrpt::poses::CPose2D given(truth0.x() + 1.2, truth0.y() - 0.9,
                                     truth0.phi() + mrpt::DEG2RAD(8.0));
    auto o = shareOptions();
    o.start_pose = "1.2 -0.9 " + std::to_string(mrpt::RAD2DEG(given.phi()));
    o.ceiling_estimate = false;
    const auto r = Survey(o, shareIni()).run(in);
    ASSERT_TRUE(r.ok()) << r.reason;
    ASSERT_EQ(r.traverses.size(), 2u);
    EXPECT_EQ(r.traverses[1].start_source, "scan match");
    EXPECT_GT(r.traverses[1].start_goodness, o.start_min_goodness);
    const auto start = nlohmann::json::parse(r.toJson())["traverses"][1]["start"];
    EXPECT_EQ(start["ceiling"], "confirmed") << start;
    EXPECT_GT(start["tied_places"], 0) << start;
    // In the map frame, b (driven where a was) starts where a started.
    const auto& sb = r.traverses[1].start;
    EXPECT_LT(std::hypot(sb.x() - given.x(), sb.y() - given.y()), 0.3) << r.toJson();
    EXPECT_LT(std::abs(mrpt::math::wrapToPi(sb.phi() - given.phi())), mrpt::DEG2RAD(2.0));
    // Every reference of both traverses, brought back through the known frame offset, is
    // where the truth says (the same bound as the laser path's own test).
    const auto offset = frameOffset(given, truth0);
    const auto db = lookup::database::ReferenceDatabase::load(in.out_dir);
    std::size_t of_b = 0;
    double worst = 0;
    for (const auto& ref : db.references()) {
        const auto in_truth = (-offset) + mrpt::poses::CPose2D(ref.vehicle_pose);
        const auto truth = lookup::test::truePoseAt(ref.time_s - 1.7e9);
        worst = std::max(worst, std::hypot(in_truth.x() - truth.x(), in_truth.y() - truth.y()));
        of_b += ref.traverse == "b";
    }
    EXPECT_GT(of_b, 20u);
    EXPECT_LT(worst, 0.5) << r.toJson();
}

TEST(DatasetIni, WithoutCeilingHeightWorksAndAStatedOneIsIgnored) {
    const auto dir = lookup::test::freshDir("lookup_nogt_dataset");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 6.0);
    for (const std::string extra : {"", "ceiling_height_m = 7.5\n"}) {
        writeDataset(dir / "dataset.ini", "corridor.rawlog", extra);
        const std::string ds = (dir / "dataset.ini").string(), out = (dir / "db").string();
        const char* argv[] = {"lookup-survey", "--dataset", ds.c_str(), "--out", out.c_str(), "-q"};
        SurveyApp app;
        ASSERT_TRUE(app.initialize(6, argv));
        EXPECT_EQ(app.inputs().start_pose, "0 0 5.7106");
        EXPECT_EQ(app.run(), 0) << app.result().reason;
        const auto db = lookup::database::ReferenceDatabase::load(out);
        EXPECT_GT(db.info().ceiling_height_m, 0.0);
        EXPECT_NE(db.info().ceiling_height_m, 7.5);
        bool noted = false;
        for (const auto& w : app.result().warnings) noted |= w.find("ignored") != std::string::npos;
        EXPECT_EQ(noted, !extra.empty());
    }
}

TEST(DatasetIni, MalformedStartOrEndPoseOrMarksRefusedNamingTheKey) {
    const auto dir = lookup::test::freshDir("lookup_nogt_badstart");
    const auto f = lookup::test::makeSurveyRawlog(dir.string(), "corridor", 2.0);
    for (const std::string bad : {"start_pose = 1 2\n", "start_pose = 0 0 0\nend_pose = 2 0 x\n",
                                  "start_pose = 0 0 0\nmarks = 1700000001 1 0 5; 1 2\n"}) {
        {
            std::ofstream d(dir / "dataset.ini");
            d << "[dataset]\ntraverse_count = 1\n[traverse_0]\nrawlog = corridor.rawlog\n" << bad;
        }
        const std::string key = bad.find("end_pose") != std::string::npos ? "end_pose"
                                : bad.find("marks") != std::string::npos  ? "marks"
                                                                          : "start_pose";
        const std::string ds = (dir / "dataset.ini").string(), out = (dir / "db").string();
        const char* argv[] = {"lookup-survey", "--dataset", ds.c_str(), "--out", out.c_str(), "-q"};
        SurveyApp app;
        testing::internal::CaptureStderr();
        EXPECT_FALSE(app.initialize(6, argv));
        const std::string err = testing::internal::GetCapturedStderr();
        EXPECT_NE(app.exitCode(), 0);
        EXPECT_NE(err.find(key), std::string::npos) << err;
        EXPECT_NE(err.find("traverse_0"), std::string::npos) << err;
    }
    SurveyOptions o;
    o.start_pose = "1 2 x";
    EXPECT_THROW(o.check(), std::exception);
}

#include <gtest/gtest.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <limits>

#include "../common/round_trip.h"
#include "lookup/common/config.h"
#include "lookup/common/pose_files.h"
#include "lookup/eval/eval_app.h"
#include "lookup/eval/evaluator.h"
#include "lookup/eval/report_json.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using namespace lookup::eval;

namespace {

// Straight drive along x at 1 m/s for 100 s from t = 5000 s: x = t - 5000.
GroundTruth straightTruth() {
    GroundTruth gt;
    gt.traverse = "zigzag";
    for (int i = 0; i <= 1000; ++i) {
        const double t = 5000 + 0.1 * i;
        gt.track.push_back({t, mrpt::poses::CPose3D(0.1 * i, 0, 0, 0, 0, 0)});
    }
    return gt;
}

Run runWithOffsets(const std::vector<double>& offsets_m, double coarse_offset_m) {
    Run run;
    run.method = "lookup-grid24";
    run.directory = "memory";
    for (size_t i = 0; i < offsets_m.size(); ++i) {
        FrameRow f;
        f.time_s = 5001 + i;  // truth x = 1 + i
        f.status = "refined";
        f.has_pose = true;
        f.x = 1.0 + i + offsets_m[i];
        f.cov_xx = f.cov_yy = 0.01;  // sigma 0.1 m
        f.has_coarse = true;
        f.coarse_x = 1.0 + i + coarse_offset_m;
        run.frames.push_back(f);
    }
    return run;
}

}  // namespace

TEST(Summarize, MeanMedianP95OfKnownErrors) {
    std::vector<double> e;
    for (int i = 1; i <= 100; ++i) e.push_back(i);
    const auto s = summarize(e);
    EXPECT_EQ(s.count, 100u);
    EXPECT_DOUBLE_EQ(s.mean_m, 50.5);
    EXPECT_DOUBLE_EQ(s.median_m, 50.5);
    EXPECT_NEAR(s.p95_m, 95.05, 1e-9);
    EXPECT_DOUBLE_EQ(s.max_m, 100);
}

TEST(Evaluate, ErrorsAgainstInterpolatedTruthAndEllipseShare) {
    // 0.05 and 0.15 m are inside the 95 % ellipse of sigma 0.1 m (radius 0.245 m); 0.5 is not.
    const auto report =
        evaluate({straightTruth()}, {runWithOffsets({0.05, 0.15, 0.5, -0.05}, 2.0)}, {});
    ASSERT_EQ(report.rows.size(), 2u);
    const auto& coarse = report.rows[0];
    const auto& lookup = report.rows[1];
    EXPECT_EQ(coarse.method, "coarse");
    EXPECT_NEAR(coarse.error.mean_m, 2.0, 1e-6);
    EXPECT_EQ(lookup.traverse, "zigzag");
    EXPECT_EQ(lookup.frames, 4u);
    EXPECT_NEAR(lookup.error.mean_m, (0.05 + 0.15 + 0.5 + 0.05) / 4, 1e-6);
    EXPECT_NEAR(lookup.error.max_m, 0.5, 1e-6);
    EXPECT_DOUBLE_EQ(lookup.acceptance_share, 1.0);
    EXPECT_DOUBLE_EQ(lookup.inside_95_share, 0.75);
}

TEST(Evaluate, ExcludesFramesWithCoarseErrorOverThreshold) {
    auto run = runWithOffsets({0.1, 0.1, 0.1}, 0.0);
    run.frames[1].coarse_x += 12.0;  // coarse 12 m off: excluded from every method
    run.frames[2].status = "fallback";
    const auto report = evaluate({straightTruth()}, {run}, {});
    const auto& lookup = report.rows[1];
    EXPECT_EQ(lookup.excluded, 1u);
    EXPECT_EQ(lookup.error.count, 2u);
    EXPECT_DOUBLE_EQ(lookup.acceptance_share, 0.5);
}

TEST(Evaluate, ConfidentWrongFixesAreFarOffAndOutsideTheirEllipseOverEveryFrame) {
    // sigma 0.1 m: 0.6 m off is far outside the 99.7 % ellipse (radius 0.34 m); with sigma
    // 1 m it is inside; 0.3 m off is outside sigma 0.01 m's ellipse but under the 0.5 m floor.
    auto run = runWithOffsets({0.05, 0.6, 0.6, 0.3, 0.6, 0.6}, 0.0);
    run.frames[2].cov_xx = run.frames[2].cov_yy = 1.0;
    run.frames[3].cov_xx = run.frames[3].cov_yy = 1e-4;
    run.frames[4].coarse_x += 12.0;  // excluded from the accuracy, not from the integrity
    run.frames[5].cov_xx = run.frames[5].cov_yy = 0;  // a zero covariance claims certainty
    run.frames[5].status = "fallback";
    const auto report = evaluate({straightTruth()}, {run}, {});
    const auto& lookup = report.rows[1];
    EXPECT_EQ(lookup.excluded, 1u);
    EXPECT_EQ(lookup.confident_wrong, 3u);
}

TEST(Evaluate, FirstFixFrameDistanceAndTrackingShare) {
    // Frames 1 s apart at 1 m/s: the first refined frame (index 3) comes 3 m into the drive.
    auto run = runWithOffsets({0, 0, 0, 0, 0, 0, 0, 0}, 0.0);
    for (int i = 0; i < 3; ++i) {
        run.frames[i].status = "lost";
        run.frames[i].has_pose = false;
    }
    run.frames[6].status = "fallback";
    for (size_t i = 0; i < run.frames.size(); ++i) run.frames[i].ms = 1.0 + i;
    const auto report = evaluate({straightTruth()}, {run}, {});
    const auto& lookup = report.rows[1];
    EXPECT_EQ(lookup.first_fix_frame, 3);
    EXPECT_NEAR(lookup.first_fix_s, 3.0, 1e-9);
    EXPECT_NEAR(lookup.first_fix_distance_m, 3.0, 1e-6);
    EXPECT_DOUBLE_EQ(lookup.refined_after_first_fix_share, 4.0 / 5.0);
    EXPECT_DOUBLE_EQ(lookup.acceptance_share, 4.0 / 8.0);
    EXPECT_NEAR(lookup.frame_ms_p99, 7.93, 1e-9);  // between the 7th and 8th of 1..8 ms
    EXPECT_EQ(lookup.without_pose, 3u);
}

TEST(Evaluate, NoFixMeansNoFirstFix) {
    auto run = runWithOffsets({0, 0}, 0.0);
    for (auto& f : run.frames) f.status = "fallback";
    const auto report = evaluate({straightTruth()}, {run}, {});
    EXPECT_EQ(report.rows[1].first_fix_frame, -1);
    EXPECT_DOUBLE_EQ(report.rows[1].refined_after_first_fix_share, 0);
}

TEST(Evaluate, RunOutsideEveryTruthIsReportedNotMatched) {
    auto run = runWithOffsets({0.1}, 0.0);
    run.frames[0].time_s = 1.0;
    const auto report = evaluate({straightTruth()}, {run}, {});
    EXPECT_TRUE(report.rows.empty());
    ASSERT_EQ(report.warnings.size(), 1u);
}

TEST(RunIo, RoundTripAndMalformedRowNamesFileAndLine) {
    const auto dir = lookup::test::freshDir("lookup_eval_run");
    auto run = runWithOffsets({0.1, 0.2}, 1.0);
    run.frames[1].reason = "inliers 40%, below N_th";
    writeFramesCsv((dir / "frames.csv").string(), run.frames);
    std::ofstream(dir / "run.ini") << "[run]\nmethod = lookup-fcn12\n";
    std::ofstream(dir / "timing.json")
        << R"({"frames_per_s": 120.5, "refine_ms_per_frame": {"match": 1.25, "select": 0.5}})";
    const auto back = loadRun(dir.string());
    EXPECT_EQ(back.method, "lookup-fcn12");
    EXPECT_DOUBLE_EQ(back.frames_per_s, 120.5);
    EXPECT_DOUBLE_EQ(back.match_ms_per_frame, 1.25);
    ASSERT_EQ(back.frames.size(), 2u);
    EXPECT_NEAR(back.frames[1].x, run.frames[1].x, 1e-5);
    EXPECT_EQ(back.frames[1].reason, "inliers 40%; below N_th");

    std::ofstream(dir / "frames.csv", std::ios::app) << "5003,refined,,abc,0,0,0,0,0,0,,,,0,0,0\n";
    try {
        loadRun(dir.string());
        FAIL();
    } catch (const lookup::eval::RunError& e) {
        EXPECT_NE(std::string(e.what()).find("frames.csv:4"), std::string::npos) << e.what();
    }
}

TEST(RunIo, HeightsAreScoredAgainstTheTruthsZAndRunsWithoutTheColumnHaveNone) {
    // Down a 1:10 grade: the truth's z falls 0.1 m per metre; the last frame's height 0.3 m off.
    GroundTruth gt = straightTruth();
    for (auto& p : gt.track) p.pose.z(-0.1 * p.pose.x());
    auto run = runWithOffsets({0, 0, 0, 0}, 0.5);
    for (size_t i = 0; i < run.frames.size(); ++i) {
        run.frames[i].has_z = true;
        run.frames[i].z = -0.1 * (1.0 + i) + (i == 3 ? 0.3 : 0.0);
    }
    const auto dir = lookup::test::freshDir("lookup_eval_heights");
    writeFramesCsv((dir / "frames.csv").string(), run.frames);
    std::ofstream(dir / "run.ini") << "[run]\nmethod = lookup-grid24\n";
    std::ofstream(dir / "timing.json") << R"({"frames_per_s": 100, "frames": 4})";
    const auto row = evaluate({gt}, {loadRun(dir.string())}, {}).rows[1];
    EXPECT_EQ(row.height.count, 4u);
    EXPECT_NEAR(row.height.mean_m, 0.3 / 4, 1e-4);
    EXPECT_NEAR(row.height.max_m, 0.3, 1e-4);
    EXPECT_EQ(methodResultFromJson(toJson(row)).height.count, 4u);

    // frames.csv as written before the column: read, scored, no heights.
    std::ifstream in(dir / "frames.csv");
    std::string text, line;
    while (std::getline(in, line)) text += line.substr(0, line.rfind(',')) + "\n";
    in.close();
    std::ofstream(dir / "frames.csv") << text;
    const auto old = loadRun(dir.string());
    ASSERT_EQ(old.frames.size(), 4u);
    for (const auto& f : old.frames) EXPECT_FALSE(f.has_z);
    EXPECT_EQ(evaluate({gt}, {old}, {}).rows[1].height.count, 0u);
}

TEST(Report, WritesMarkdownJsonAndChart) {
    const auto dir = fs::temp_directory_path() / "lookup_eval_report";
    fs::remove_all(dir);
    auto run = runWithOffsets({0.1, 0.2}, 1.0);
    run.frames_per_s = 99.5;
    run.match_ms_per_frame = 2.125;  // the matcher's time per frame, a column of its own
    writeReport(evaluate({straightTruth()}, {run}, {}), dir.string());
    EXPECT_TRUE(fs::exists(dir / "report.md"));
    EXPECT_TRUE(fs::exists(dir / "report.json"));
    std::ifstream md(dir / "report.md");
    std::string text((std::istreambuf_iterator<char>(md)), {});
    EXPECT_NE(text.find("| zigzag | lookup-grid24 | 2 |"), std::string::npos) << text;
    EXPECT_NE(text.find("| 99.5 | 2.12 |"), std::string::npos) << text;
    EXPECT_NE(text.find("| frames/s | match ms/frame |"), std::string::npos) << text;
    EXPECT_NE(text.find("| confident wrong |"), std::string::npos) << text;
    if (std::system("command -v gnuplot >/dev/null 2>&1") == 0) {
        EXPECT_GT(fs::file_size(dir / "errors.png"), 1000u);
    }
}

TEST(RunIo, HugeValuesRoundTripThroughFramesCsv) {
    const auto dir = lookup::test::freshDir("lookup_eval_huge");
    FrameRow r;
    r.time_s = 1.7e9;
    r.status = "fallback";
    r.reason = std::string(300, 'x');
    r.has_pose = r.has_coarse = true;
    r.x = 1e300, r.y = -1e300, r.yaw = 1e300;
    r.cov_xx = r.cov_yy = r.cov_tt = 1e300, r.cov_xy = -1e300;
    r.coarse_x = r.coarse_y = 1e300;
    r.ms = 1e300;
    const std::string row = formatFramesCsvRow(r);
    EXPECT_GT(row.size(), 256u);  // once cut at a fixed 256-byte buffer
    writeFramesCsv((dir / "frames.csv").string(), {r, r});
    const auto back = loadRun(dir.string());
    ASSERT_EQ(back.frames.size(), 2u);
    EXPECT_EQ(back.frames[1].x, 1e300);
    EXPECT_EQ(back.frames[1].cov_xy, -1e300);
    EXPECT_EQ(back.frames[1].coarse_y, 1e300);
    EXPECT_EQ(back.frames[1].ms, 1e300);
    EXPECT_DOUBLE_EQ(back.frames[1].time_s, 1.7e9);
}

TEST(RunIo, IncompleteEmptyAndNonFiniteRunsAreNamedProblems) {
    const auto dir = lookup::test::freshDir("lookup_eval_problems");
    auto run = runWithOffsets({0.1, 0.2, 0.3}, 1.0);
    writeFramesCsv((dir / "frames.csv").string(), run.frames);
    EXPECT_NE(runProblem(loadRun(dir.string())).find("no timing.json"), std::string::npos);
    std::ofstream(dir / "timing.json") << R"({"frames": 3})";
    EXPECT_EQ(runProblem(loadRun(dir.string())), "");
    std::ofstream(dir / "timing.json") << R"({"frames": 178})";
    EXPECT_NE(runProblem(loadRun(dir.string())).find("178"), std::string::npos);
    writeFramesCsv((dir / "frames.csv").string(), {});
    EXPECT_NE(runProblem(loadRun(dir.string())).find("no frames"), std::string::npos);

    run.frames[1].x = std::numeric_limits<double>::quiet_NaN();
    writeFramesCsv((dir / "frames.csv").string(), run.frames);
    std::ofstream(dir / "timing.json") << R"({"frames": 3})";
    const auto back = loadRun(dir.string());
    EXPECT_EQ(back.non_finite_rows, 1u);
    EXPECT_FALSE(back.frames[1].has_pose);  // never scored as a position
    EXPECT_NE(runProblem(back).find("non-finite"), std::string::npos);
}

TEST(Report, RowRoundTripsThroughJson) {
    auto run = runWithOffsets({0.05, 0.6, 0.1}, 1.0);
    run.frames[0].status = "lost";
    run.frames[0].has_pose = false;
    run.frames_per_s = 42.5;
    run.flagged = "partial: no timing.json";
    const auto row = evaluate({straightTruth()}, {run}, {}).rows[1];
    const auto back = methodResultFromJson(nlohmann::json::parse(toJson(row).dump()));
    EXPECT_EQ(toJson(back), toJson(row));
    EXPECT_EQ(back.first_fix_frame, 1);
    EXPECT_EQ(back.confident_wrong, 1u);
    EXPECT_EQ(back.flagged, run.flagged);
    auto broken = toJson(row);
    broken.erase("confident_wrong");
    EXPECT_THROW(methodResultFromJson(broken), nlohmann::json::exception);
}

TEST(Pictures, EveryMethodHasItsOwnColour) {
    const auto& table = methodColourTable();
    std::vector<std::string> names, colours;
    for (const auto& [name, colour] : table) {
        EXPECT_EQ(colour.size(), 7u) << name;
        EXPECT_EQ(std::count(names.begin(), names.end(), name), 0) << name << " twice";
        EXPECT_EQ(std::count(colours.begin(), colours.end(), colour), 0)
            << name << " shares " << colour;
        names.push_back(name);
        colours.push_back(colour);
    }
    for (const char* known : {"coarse", "laser-ecc", "lookup-grid24", "lookup-fcn12", "lookup-orb",
                              "lookup-ecc", "surveyed-ecc", "oracle-grid"}) {
        EXPECT_NE(std::find(names.begin(), names.end(), known), names.end()) << known;
    }
    EXPECT_NE(methodColour("coarse", names), methodColour("laser-ecc", names));
    // Names the table does not know get spare colours, distinct among themselves and from it.
    std::vector<std::string> report = names;
    for (int i = 0; i < 8; ++i) report.push_back("custom-" + std::to_string(i));
    std::vector<std::string> seen;
    for (const auto& m : report) {
        const std::string c = methodColour(m, report);
        EXPECT_EQ(std::count(seen.begin(), seen.end(), c), 0) << m << " repeats " << c;
        seen.push_back(c);
    }
    EXPECT_EQ(methodColour("laser-ecc", {}), methodColour("laser-ecc", report))
        << "a known method's colour does not depend on the report";
}

TEST(Pictures, TrajectoryAndErrorAlongTheRouteForASmallRun) {
    const auto dir = lookup::test::freshDir("lookup_eval_pictures");
    auto grid_run = runWithOffsets({0.05, 0.1, 0.2, 0.1, 0.3, 0.05}, 1.0);
    grid_run.frames[2].status = "fallback";
    grid_run.frames[3].status = "lost";
    grid_run.frames[3].has_pose = false;
    auto ecc_run = runWithOffsets({0.4, 0.5, 0.6}, 2.0);
    ecc_run.method = "laser-ecc";
    // A 12 m x 4 m map: free inside, rock around.
    mrpt::maps::COccupancyGridMap2D grid(-1, 13, -2, 2, 0.1f);
    for (unsigned y = 0; y < grid.getSizeY(); ++y) {
        for (unsigned x = 0; x < grid.getSizeX(); ++x) {
            grid.setCell(x, y, std::abs(grid.idx2y(y)) < 1.5 ? 1.0f : 0.0f);
        }
    }
    {
        mrpt::io::CFileGZOutputStream f((dir / "map.gridmap.gz").string());
        auto arch = mrpt::serialization::archiveFrom(f);
        arch << grid;
    }
    Report report = evaluate({straightTruth()}, {grid_run, ecc_run}, {});
    ASSERT_EQ(report.traces.size(), 2u);
    EXPECT_EQ(report.traces[0].frames.size(), 6u);
    EXPECT_NEAR(report.traces[0].frames[5].distance_m, 5.0, 1e-9);
    report.map_walls = loadMapWalls((dir / "map.gridmap.gz").string());
    EXPECT_GT(report.map_walls.size(), 200u);
    const fs::path out = dir / "report";
    writeReport(report, out.string());
    EXPECT_THROW(loadMapWalls((dir / "none.gridmap.gz").string()), lookup::common::ConfigError);
    if (std::system("command -v gnuplot >/dev/null 2>&1") != 0) GTEST_SKIP() << "no gnuplot";
    for (const char* png :
         {"trajectory_zigzag_lookup-grid24.png", "trajectory_zigzag_laser-ecc.png",
          "error_along_zigzag.png", "errors.png"}) {
        EXPECT_TRUE(fs::exists(out / png)) << png;
        if (fs::exists(out / png)) {
            EXPECT_GT(fs::file_size(out / png), 1000u) << png;
        }
    }
    const std::string traj = lookup::test::readText(out / "trajectory_zigzag_lookup-grid24.gp");
    EXPECT_NE(traj.find("fallback"), std::string::npos) << traj;
    EXPECT_NE(traj.find("lost"), std::string::npos) << traj;
    EXPECT_NE(traj.find("map_walls.dat"), std::string::npos) << traj;
    const std::string along = lookup::test::readText(out / "error_along_zigzag.gp");
    const std::string errors = lookup::test::readText(out / "errors.gp");
    for (const char* m : {"lookup-grid24", "laser-ecc", "coarse"}) {
        const std::string colour = methodColour(m, {});
        EXPECT_NE(along.find(colour), std::string::npos) << m << "\n" << along;
        EXPECT_NE(errors.find(colour), std::string::npos) << m << "\n" << errors;
    }
}

TEST(EvalOptions, SaveThenLoadGivesTheSameOptions) {
    lookup::eval::EvalOptions o;
    o.max_gt_gap_s = 0.125;
    o.confident_wrong_min_error_m = 1.0 / 3.0;
    lookup::options_testing::expectRoundTrip(o, "eval");
}

// EvalApp, the lookup-eval program as a class.
namespace {

// A finished run folder (frames.csv, run.ini, timing.json) and the ground truth it drove.
void writeRunAndTruth(const fs::path& dir) {
    fs::create_directories(dir / "run");
    const auto run = runWithOffsets({0.1, 0.2, 0.3}, 1.0);
    writeFramesCsv((dir / "run" / "frames.csv").string(), run.frames);
    std::ofstream(dir / "run" / "run.ini") << "[run]\nmethod = lookup-grid24\n";
    std::ofstream(dir / "run" / "timing.json") << R"({"frames": 3, "frames_per_s": 10})";
    lookup::common::writeTumPoseFile((dir / "zigzag.rawlog.GT.txt").string(),
                                     straightTruth().track);
}

}  // namespace

TEST(EvalApp, RunScoresTheRunsAndPrintsTheReport) {
    const auto dir = lookup::test::freshDir("lookup_eval_app_run");
    writeRunAndTruth(dir);
    EvalApp app;
    const auto r =
        lookup::test::runApp("lookup-eval", app,
                             {"--gt", (dir / "zigzag.rawlog.GT.txt").string(), "--runs",
                              (dir / "run").string(), "--out", (dir / "report").string()});
    ASSERT_EQ(r.code, 0) << r.err;
    EXPECT_NE(r.out.find("| zigzag | lookup-grid24 | 3 |"), std::string::npos) << r.out;
    EXPECT_EQ(r.out, lookup::test::readText(dir / "report" / "report.md"));
    EXPECT_TRUE(fs::is_regular_file(dir / "report" / "report.json"));
}

TEST(EvalApp, AnUnfinishedRunIsRefusedUnlessPartial) {
    const auto dir = lookup::test::freshDir("lookup_eval_app_partial");
    writeRunAndTruth(dir);
    fs::remove(dir / "run" / "timing.json");
    const std::vector<std::string> args{"--gt",   (dir / "zigzag.rawlog.GT.txt").string(),
                                        "--runs", (dir / "run").string(),
                                        "--out",  (dir / "report").string()};
    EvalApp refused;
    const auto r = lookup::test::runApp("lookup-eval", refused, args);
    EXPECT_EQ(r.code, 2);
    EXPECT_NE(r.err.find("not scored: no timing.json"), std::string::npos) << r.err;
    EvalApp partial;
    std::vector<std::string> with_partial = args;
    with_partial.push_back("--partial");
    const auto p = lookup::test::runApp("lookup-eval", partial, with_partial);
    EXPECT_EQ(p.code, 0) << p.err;
    EXPECT_NE(p.err.find("scored, flagged"), std::string::npos) << p.err;
}

TEST(EvalApp, BadFlagsAndIniTyposAreRefusedNamingThem) {
    const auto dir = lookup::test::freshDir("lookup_eval_app_ini");
    const std::string ini = (dir / "eval.ini").string();
    const std::vector<std::string> base{"--gt", "G", "--runs", "R", "--out", "O", "--ini", ini};
    for (const auto& [text, names] : std::vector<std::pair<std::string, std::string>>{
             {"[evl]\ncoarse_exclusion_m = 3\n", ini + " [evl]: unknown section"},
             {"[eval]\ncoarse_exclusion = 3\n", ini + " [eval] coarse_exclusion: unknown key"},
             {"[eval]\nmax_gt_gap_s = soon\n", ini + " [eval] max_gt_gap_s"}}) {
        std::ofstream(ini) << text;
        EvalApp app;
        const auto r = lookup::test::runApp("lookup-eval", app, base);
        EXPECT_EQ(r.code, 1) << text;
        EXPECT_EQ(r.err.rfind("lookup-eval: " + names, 0), 0u) << r.err;
    }
    EvalApp app;
    const auto r = lookup::test::runApp("lookup-eval", app, {"--gt", "G", "--out", "O"});
    EXPECT_EQ(r.code, 1);
    EXPECT_NE(r.err.find("--runs"), std::string::npos) << r.err;
}

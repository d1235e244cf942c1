// Fault injection against lookup-localize and lookup-eval run as programs: truncated and
// byte-flipped query rawlogs, NaN/inf in every odometry field, kill -9 mid-run. Every case
// must end with exit 0 (bad records counted as skipped) or a clear one-line error, never a
// signal or a hang, and never lose the complete run at --out.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>

#include "localize_fixture.h"
#include "lookup/common/pose_files.h"

namespace fs = std::filesystem;
using namespace lookup;
using namespace lookup::localize_testing;

namespace {

constexpr double kHangS = 120;  // a 20-frame run takes a few seconds

struct Outcome {
    int code = 0;
    std::string log;
    bool hung = false;
};

Outcome localizeWithTimeout(const localize::LocalizeRequest& req, const fs::path& log) {
    const auto start = std::chrono::steady_clock::now();
    Outcome o;
    o.code = runProgram("lookup-localize", localizeArgs(req), log, 0, [&] {
        return std::chrono::steady_clock::now() - start > std::chrono::duration<double>(kHangS);
    });
    o.hung = o.code == 128 + SIGKILL;
    o.log = readText(log);
    return o;
}

std::size_t rows(const fs::path& run) {
    std::ifstream in(run / "frames.csv");
    std::size_t n = 0;
    for (std::string line; std::getline(in, line);) n += !line.empty();
    return n > 0 ? n - 1 : 0;
}

// A copy of the query rawlog (images shared) damaged by `damage(bytes)`.
std::string damagedCopy(const fs::path& dir, const std::string& name,
                        const std::function<void(std::string&)>& damage) {
    std::ifstream in(dir / "query.rawlog", std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)), {});
    damage(bytes);
    const fs::path out = dir / (name + ".rawlog");
    std::ofstream(out, std::ios::binary) << bytes;
    fs::remove_all(dir / (name + "_Images"));
    fs::create_directory_symlink(dir / "query_Images", dir / (name + "_Images"));
    return out.string();
}

// One clear line naming the rawlog: exit 2, no MRPT dump, no signal.
void expectClearError(const Outcome& o, const std::string& rawlog) {
    EXPECT_FALSE(o.hung);
    EXPECT_EQ(o.code, 2) << o.log;
    EXPECT_NE(o.log.find(fs::path(rawlog).filename().string()), std::string::npos) << o.log;
    EXPECT_EQ(o.log.find("MRPT exception"), std::string::npos) << o.log;
}

}  // namespace

TEST(Fault, TruncatedQueryRawlogsAreRefusedClearlyAndKeepTheOldRun) {
    const auto dir = lookup::test::freshDir("lookup_localize_fault_truncated");
    auto req = planarRun(dir, [](int, auto&, auto&) {});
    ASSERT_EQ(localizeWithTimeout(req, dir / "ok.log").code, 0);
    for (double share : {0.02, 0.3, 0.5, 0.77}) {
        auto cut = req;
        cut.rawlog = damagedCopy(dir, "cut", [&](std::string& b) { b.resize(b.size() * share); });
        const auto o = localizeWithTimeout(cut, dir / "cut.log");
        expectClearError(o, cut.rawlog);
        EXPECT_EQ(rows(req.out_dir), 20u) << "cut at " << share;
    }
    // Cut in the gzip trailer only: every record is there, so the run may complete.
    auto tail = req;
    tail.rawlog = damagedCopy(dir, "cut", [](std::string& b) { b.resize(b.size() - 4); });
    const auto o = localizeWithTimeout(tail, dir / "cut.log");
    if (o.code != 0) expectClearError(o, tail.rawlog);
    EXPECT_EQ(rows(req.out_dir), 20u);
}

TEST(Fault, ByteFlipsGiveAClearErrorOrFiniteFrames) {
    const auto dir = lookup::test::freshDir("lookup_localize_fault_flips");
    auto req = planarRun(dir, [](int, auto&, auto&) {});
    ASSERT_EQ(localizeWithTimeout(req, dir / "ok.log").code, 0);
    int errors = 0, ran = 0;
    for (int k = 1; k <= 12; ++k) {
        auto flipped = req;
        flipped.rawlog = damagedCopy(dir, "flip", [&](std::string& b) {
            b[b.size() * k / 13] ^= 0x5a;  // spread over the file, header to trailer
        });
        flipped.out_dir = (dir / "flip_run").string();
        const auto o = localizeWithTimeout(flipped, dir / "flip.log");
        EXPECT_FALSE(o.hung) << "flip " << k;
        EXPECT_LT(o.code, 128) << "flip " << k << ": signal\n" << o.log;
        if (o.code == 0) {
            ++ran;
            EXPECT_EQ(nonFiniteLines(fs::path(flipped.out_dir) / "frames.csv", 1), 0u);
        } else {
            ++errors;
            expectClearError(o, flipped.rawlog);
        }
    }
    EXPECT_EQ(errors + ran, 12);
    std::cout << "byte flips: " << errors << " clear errors, " << ran << " ran\n";
}

TEST(Fault, NanAndInfInEveryOdometryFieldAreSkippedNeverPoses) {
    const auto dir = lookup::test::freshDir("lookup_localize_fault_odometry");
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    // Frames 2..13: x, y, phi, vx, vy, omega, each NaN then -inf.
    auto req = planarRun(dir, [&](int i, auto&, mrpt::obs::CObservationOdometry& odo) {
        if (i < 2 || i > 13) return;
        const double bad = i < 8 ? nan : -inf;
        const int field = (i - 2) % 6;
        odo.hasVelocities = true;
        if (field == 0) odo.odometry.x(bad);
        if (field == 1) odo.odometry.y(bad);
        if (field == 2) odo.odometry.phi(bad);
        if (field == 3) odo.velocityLocal.vx = bad;
        if (field == 4) odo.velocityLocal.vy = bad;
        if (field == 5) odo.velocityLocal.omega = bad;
    });
    const auto o = localizeWithTimeout(req, dir / "odo.log");
    ASSERT_EQ(o.code, 0) << o.log;
    EXPECT_EQ(rows(req.out_dir), 20u);
    EXPECT_EQ(nonFiniteLines(fs::path(req.out_dir) / "frames.csv", 1), 0u);
    EXPECT_EQ(nonFiniteLines(fs::path(req.out_dir) / "poses.tum", 0), 0u);
    std::ifstream in(fs::path(req.out_dir) / "timing.json");
    EXPECT_EQ(nlohmann::json::parse(in).at("skipped").at("odometry_not_finite").get<int>(), 12);
    EXPECT_NE(o.log.find("record"), std::string::npos) << o.log;
}

TEST(Fault, KillNineAtAnyPointKeepsTheCompleteRun) {
    const auto dir = lookup::test::freshDir("lookup_localize_fault_kill");
    auto req = planarRun(dir, [](int, auto&, auto&) {});
    ASSERT_EQ(localizeWithTimeout(req, dir / "ok.log").code, 0);
    const fs::path partial = req.out_dir + ".partial";
    for (std::size_t after : {0u, 1u, 10u, 19u}) {
        const int code = runProgram("lookup-localize", localizeArgs(req), dir / "kill.log", 0,
                                    [&] { return fs::exists(partial) && rows(partial) >= after; });
        if (code == 0) continue;  // finished before the kill landed: also fine
        EXPECT_EQ(code, 128 + SIGKILL);
        EXPECT_EQ(rows(req.out_dir), 20u) << "killed after " << after << " frames";
        EXPECT_TRUE(fs::exists(fs::path(req.out_dir) / "timing.json"));
    }
    ASSERT_EQ(localizeWithTimeout(req, dir / "after.log").code, 0);
    EXPECT_FALSE(fs::exists(partial));
    EXPECT_EQ(rows(req.out_dir), 20u);
}

TEST(Fault, LookupCoarseRefusesTruncatedAndFlippedQueriesOnOneLine) {
    const auto dir = lookup::test::freshDir("lookup_localize_fault_coarse");
    const auto req = planarRun(dir, [](int, auto&, auto&) {});
    std::ofstream(dir / "s5.ini") << "[coarse]\nsequence_length = 5\n";
    const auto coarse = [&](const std::string& query) {
        Outcome o;
        o.code =
            runProgram("lookup-coarse",
                       {"--ref", req.rawlog, "--query", query, "--camera", "CEILING_CAM", "--ini",
                        (dir / "s5.ini").string(), "--out", (dir / "m.csv").string(), "--quiet"},
                       dir / "coarse.log");
        o.log = readText(dir / "coarse.log");
        return o;
    };
    ASSERT_EQ(coarse(req.rawlog).code, 0);
    for (const auto& [name, damage] :
         std::vector<std::pair<std::string, std::function<void(std::string&)>>>{
             {"cut", [](std::string& b) { b.resize(b.size() / 2); }},
             {"flip", [](std::string& b) { b[b.size() / 2] ^= 0x5a; }}}) {
        const auto o = coarse(damagedCopy(dir, name, damage));
        EXPECT_EQ(o.code, 2) << o.log;
        EXPECT_NE(o.log.find(name + ".rawlog: record"), std::string::npos) << o.log;
        EXPECT_EQ(std::count(o.log.begin(), o.log.end(), '\n'), 1) << o.log;
        EXPECT_FALSE(fs::exists(dir / "m.csv.tmp"));
    }
}

TEST(Fault, LookupEvalRefusesDamagedRunFilesNamingThem) {
    const auto dir = lookup::test::freshDir("lookup_localize_fault_eval");
    const auto req = planarRun(dir, [](int, auto&, auto&) {});
    ASSERT_EQ(localizeWithTimeout(req, dir / "ok.log").code, 0);
    common::PoseTrack truth;
    for (int i = 0; i < 20; ++i) {
        truth.push_back({kT0 + 0.1 * i, mrpt::poses::CPose3D(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0)});
    }
    common::writeMrptPoseFile((dir / "gt.txt").string(), truth);
    const fs::path run = dir / "damaged";
    const auto eval = [&] {
        Outcome o;
        o.code = runProgram("lookup-eval",
                            {"--gt", (dir / "gt.txt").string(), "--runs", run.string(), "--out",
                             (dir / "report").string()},
                            dir / "eval.log");
        o.log = readText(dir / "eval.log");
        return o;
    };
    const std::string csv = readText(fs::path(req.out_dir) / "frames.csv");
    const std::string timing = readText(fs::path(req.out_dir) / "timing.json");
    const std::vector<std::pair<std::string, std::string>> damages{
        {csv.substr(0, csv.size() - 30), timing},      // frames.csv cut mid-row
        {csv, timing.substr(0, timing.size() / 2)},    // timing.json cut
        {csv, std::string("\0\xff garbage", 10)},      // timing.json garbage
        {csv.substr(0, csv.find('\n') + 1), timing}};  // header only
    for (const auto& [frames, json] : damages) {
        fs::remove_all(run);
        fs::create_directories(run);
        std::ofstream(run / "frames.csv", std::ios::binary) << frames;
        std::ofstream(run / "timing.json", std::ios::binary) << json;
        const auto o = eval();
        EXPECT_EQ(o.code, 2) << o.log;
        EXPECT_NE(o.log.find(run.string()), std::string::npos) << o.log;
        EXPECT_EQ(std::count(o.log.begin(), o.log.end(), '\n'), 1) << o.log;
    }
}

TEST(Fault, LookupEvalRefusesBadGroundTruthAsBadInputNamingLine) {
    const auto dir = lookup::test::freshDir("lookup_localize_fault_eval_gt");
    const auto req = planarRun(dir, [](int, auto&, auto&) {});
    ASSERT_EQ(localizeWithTimeout(req, dir / "ok.log").code, 0);
    const fs::path gt = dir / "gt.tum";
    const std::string good = "100.0 0 0 0 0 0 0 1\n";
    // Second row bad: a word, NaN, a time past the clock's range, a row of 5 columns.
    for (const std::string bad : {"100.1 0 zero 0 0 0 0 1", "100.1 nan 0 0 0 0 0 1",
                                  "1e300 0 0 0 0 0 0 1", "100.1 0 0 0 1"}) {
        std::ofstream(gt) << good << bad << "\n";
        const int code = runProgram(
            "lookup-eval",
            {"--gt", gt.string(), "--runs", req.out_dir, "--out", (dir / "report").string()},
            dir / "eval.log");
        const std::string log = readText(dir / "eval.log");
        EXPECT_EQ(code, 2) << bad << ": " << log;
        EXPECT_NE(log.find(gt.string() + ":2: "), std::string::npos) << log;
        EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
    }
}

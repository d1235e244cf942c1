// Run folders are replaced only by complete runs, write errors are write errors, and what an
// interrupted run leaves behind is cleaned at the next start.

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <csignal>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>

#include "localize_fixture.h"
#include "lookup/common/errors.h"
#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/localize/localize_app.h"

namespace fs = std::filesystem;
using namespace lookup;
using namespace lookup::localize_testing;

namespace {

std::size_t frameRows(const fs::path& run) {
    std::ifstream in(run / "frames.csv");
    std::size_t n = 0;
    for (std::string line; std::getline(in, line);) n += !line.empty();
    return n > 0 ? n - 1 : 0;  // header
}

// `query.rawlog` cut to `share` of its bytes, its images shared: a record cut midway.
std::string truncatedCopy(const fs::path& dir, double share) {
    const fs::path cut = dir / "cut.rawlog";
    fs::copy_file(dir / "query.rawlog", cut, fs::copy_options::overwrite_existing);
    fs::resize_file(cut, std::uintmax_t(share * double(fs::file_size(cut))));
    fs::remove_all(dir / "cut_Images");
    fs::create_directory_symlink(dir / "query_Images", dir / "cut_Images");
    return cut.string();
}

}  // namespace

TEST(RunFolder, AFailedRerunKeepsTheOldRunAndItsFramesApart) {
    const auto dir = lookup::test::freshDir("lookup_localize_rerun");
    auto req = planarRun(dir, [](int, auto&, auto&) {});
    localize::runLocalization(req);
    ASSERT_EQ(frameRows(req.out_dir), 20u);
    EXPECT_FALSE(fs::exists(req.out_dir + ".partial"));

    // Refused at the start (a record cut midway through the file): nothing left behind.
    auto bad = req;
    bad.rawlog = truncatedCopy(dir, 0.5);
    EXPECT_THROW(localize::runLocalization(bad), common::RawlogError);
    EXPECT_EQ(frameRows(req.out_dir), 20u);  // the complete run is untouched
    EXPECT_TRUE(fs::exists(fs::path(req.out_dir) / "timing.json"));
    const fs::path partial = req.out_dir + ".partial";
    EXPECT_FALSE(fs::exists(partial));

    // Killed midway (kill -9 once 5 frames are written): the old run stays, the frames so far
    // stay apart in .partial, without timing.json.
    const int code = runProgram("lookup-localize", localizeArgs(req), dir / "kill.log", 0,
                                [&] { return frameRows(partial) >= 5; });
    EXPECT_EQ(code, 128 + SIGKILL) << readText(dir / "kill.log");
    EXPECT_EQ(frameRows(req.out_dir), 20u);
    EXPECT_GE(frameRows(partial), 5u);
    EXPECT_FALSE(fs::exists(partial / "timing.json"));

    // A kill between publish's two renames: only `.old` is left; the next start restores it.
    fs::rename(req.out_dir, req.out_dir + ".old");
    EXPECT_THROW(localize::runLocalization(bad), common::RawlogError);
    EXPECT_EQ(frameRows(req.out_dir), 20u);
    EXPECT_FALSE(fs::exists(req.out_dir + ".old"));

    localize::runLocalization(req);  // cleans the leftover .partial, replaces the run
    EXPECT_FALSE(fs::exists(partial));
    EXPECT_FALSE(fs::exists(req.out_dir + ".old"));
    std::ifstream in(fs::path(req.out_dir) / "timing.json");
    EXPECT_EQ(nlohmann::json::parse(in).at("frames").get<int>(), 20);

    // A folder that is not a run is never replaced.
    fs::create_directories(dir / "mine");
    std::ofstream(dir / "mine" / "notes.txt") << "keep me\n";
    req.out_dir = (dir / "mine").string();
    EXPECT_THROW(localize::runLocalization(req), common::ConfigError);
    EXPECT_TRUE(fs::exists(dir / "mine" / "notes.txt"));
}

TEST(RunFolder, AFullDiskIsAWriteErrorNamingTheFileAndKeepsTheOldRun) {
    const auto dir = lookup::test::freshDir("lookup_localize_fulldisk");
    auto req = planarRun(dir, [](int, auto&, auto&) {});
    ASSERT_EQ(runProgram("lookup-localize", localizeArgs(req), dir / "ok.log"), 0)
        << readText(dir / "ok.log");
    ASSERT_EQ(frameRows(req.out_dir), 20u);
    for (long limit : {1500L, 6000L}) {
        const int code = runProgram("lookup-localize", localizeArgs(req), dir / "full.log", limit);
        const std::string log = readText(dir / "full.log");
        EXPECT_EQ(code, 3) << log;
        EXPECT_NE(log.find("write error"), std::string::npos) << log;
        EXPECT_NE(log.find(".partial/"), std::string::npos) << log;             // names the file
        EXPECT_EQ(log.find("query.rawlog: record"), std::string::npos) << log;  // not the input
        EXPECT_EQ(frameRows(req.out_dir), 20u) << "limit " << limit;
    }
}

TEST(RunFolder, OutputFilesReportAFullDevice) {
    common::OutputFile full("/dev/full");
    full.write(std::string(100, 'x'));
    try {
        full.flush();
        FAIL() << "a write to /dev/full succeeded";
    } catch (const common::WriteError& e) {
        EXPECT_NE(std::string(e.what()).find("/dev/full"), std::string::npos) << e.what();
    }
}

TEST(RunFolder, ATruncatedResultsRawlogIsAWriteErrorNotRenamedIntoPlace) {
    const auto dir = lookup::test::freshDir("lookup_localize_rawlog_limit");
    const fs::path path = dir / "results.rawlog";
    const pid_t pid = fork();
    if (pid == 0) {
        std::signal(SIGXFSZ, SIG_IGN);
        const rlimit limit{3000, 3000};
        ::setrlimit(RLIMIT_FSIZE, &limit);
        try {
            common::RawlogWriter out(path.string());
            for (int i = 0; i < 2000; ++i) {
                mrpt::obs::CObservationOdometry odo;
                odo.sensorLabel = "ODOMETRY";
                odo.timestamp = mrpt::Clock::fromDouble(1.7e9 + i);
                odo.odometry = mrpt::poses::CPose2D(0.37 * i, std::sin(i), 0.01 * i);
                out.write(odo);
            }
            out.close();
        } catch (const common::WriteError&) {
            _exit(3);
        } catch (...) {
            _exit(2);
        }
        _exit(0);
    }
    int status = 0;
    ::waitpid(pid, &status, 0);
    ASSERT_TRUE(WIFEXITED(status));
    EXPECT_EQ(WEXITSTATUS(status), 3);
    EXPECT_FALSE(fs::exists(path));
}

TEST(RunFolder, EvalRefusesUnfinishedRunsFlagsThemOnRequestAndReportsAFullDisk) {
    const auto dir = lookup::test::freshDir("lookup_localize_eval_runs");
    auto req = planarRun(dir, [](int, auto&, auto&) {});
    localize::runLocalization(req);
    common::PoseTrack truth;
    for (int i = 0; i < 20; ++i) {
        truth.push_back({kT0 + 0.1 * i, mrpt::poses::CPose3D(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0)});
    }
    const std::string gt = (dir / "query.rawlog.GT.txt").string();
    common::writeMrptPoseFile(gt, truth);
    const auto eval = [&](const std::string& run, const fs::path& out, long limit = 0,
                          bool partial = false) {
        std::vector<std::string> args{"--gt", gt, "--runs", run, "--out", out.string()};
        if (partial) args.push_back("--partial");
        return runProgram("lookup-eval", args, dir / "eval.log", limit);
    };
    ASSERT_EQ(eval(req.out_dir, dir / "report"), 0) << readText(dir / "eval.log");

    // An aborted run: the first 6 frames and no timing.json.
    const fs::path aborted = dir / "aborted";
    fs::create_directories(aborted);
    std::ifstream in(fs::path(req.out_dir) / "frames.csv");
    std::ofstream cut(aborted / "frames.csv");
    std::string line;
    for (int k = 0; k < 7 && std::getline(in, line); ++k) cut << line << "\n";
    cut.close();
    EXPECT_EQ(eval(aborted.string(), dir / "report_aborted"), 2);
    const std::string log = readText(dir / "eval.log");
    EXPECT_NE(log.find(aborted.string() + ": not scored: no timing.json"), std::string::npos)
        << log;
    EXPECT_FALSE(fs::exists(dir / "report_aborted" / "report.json"));
    EXPECT_EQ(eval(aborted.string(), dir / "report_aborted", 0, true), 0) << log;
    EXPECT_NE(readText(dir / "report_aborted" / "report.json").find("no timing.json"),
              std::string::npos);

    // Full disk: no 0-byte report with exit 0.
    EXPECT_EQ(eval(req.out_dir, dir / "report_full", 200), 3) << readText(dir / "eval.log");
    EXPECT_NE(readText(dir / "eval.log").find("write error"), std::string::npos);
    EXPECT_FALSE(fs::exists(dir / "report_full" / "report.md"));
}

TEST(RunFolder, ProgramsDocumentTheirExitCodesAndFailOnOneLine) {
    const auto dir = lookup::test::freshDir("lookup_localize_exit_codes");
    for (const char* program :
         {"lookup-localize", "lookup-eval", "lookup-coarse", "lookup-place"}) {
        EXPECT_EQ(runProgram(program, {"--help"}, dir / "help.log"), 0) << program;
        std::string help;  // TCLAP wraps lines: compare with whitespace collapsed
        for (char c : readText(dir / "help.log")) {
            if (!std::isspace(static_cast<unsigned char>(c))) {
                help += c;
            } else if (!help.empty() && help.back() != ' ') {
                help += ' ';
            }
        }
        EXPECT_NE(help.find("Exit codes: 0 success, 1 usage or options error"), std::string::npos)
            << program << ": " << help;
        EXPECT_NE(help.find("4 internal error"), std::string::npos) << program << ": " << help;
    }
    auto req = planarRun(dir, [](int, auto&, auto&) {});
    auto args = localizeArgs(req);
    args[1] = (dir / "nodb").string();  // --db
    EXPECT_EQ(runProgram("lookup-localize", args, dir / "nodb.log"), 2);
    const std::string log = readText(dir / "nodb.log");
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 1) << log;
    EXPECT_NE(log.find("nodb"), std::string::npos) << log;
    args.insert(args.end(), {"--sampling", "nonsense", "--max-frames", "x"});
    EXPECT_EQ(runProgram("lookup-localize", args, dir / "usage.log"), 1)
        << readText(dir / "usage.log");
}

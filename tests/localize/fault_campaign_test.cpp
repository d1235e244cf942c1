// A fault campaign over the built programs: many bad inputs and faults (truncations, byte flips,
// non-finite and out-of-range fields, bad options, kill -9, writes past a file-size limit as on a
// full disk), each case classified as
//   clear error  non-zero exit 1-4 whose message names the file (or option) and no MRPT dump,
//   handled      exit 0 where the damage may be survivable, with an output that checks out
//                (or a deliberate kill -9 after which the earlier output is intact),
//   unnamed      an error that does not name the file or option given,
//   crash        a signal or an exit code outside 0-4,
//   hang         still running after kHangS,
//   silent       exit 0 on input that must be refused, or an output that does not check out,
//   lost         a complete earlier output at --out no longer intact after a failure or kill.
// The table goes to stdout and to $TMPDIR/fault_campaign.md; the test fails on any case not
// counted as a clear error or handled.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

#include "../survey/survey_fixture.h"
#include "localize_fixture.h"
#include "lookup/common/pose_files.h"
#include "lookup/database/reference_database.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using namespace lookup;
using namespace lookup::localize_testing;

namespace {

constexpr double kHangS = 120;

enum Verdict { kClear, kHandled, kUnnamed, kCrash, kHang, kSilent, kLost, kVerdicts };
const std::array<const char*, kVerdicts> kVerdictNames = {
    "clear error", "handled (exit 0)", "unnamed error", "crash",
    "hang",        "silent wrong",     "data lost"};

struct Case {
    std::string program;  ///< bin/<program>
    std::string kind;     ///< row of the table: "truncation", "byte flip", ...
    std::vector<std::string> args;
    std::string names;         ///< an error must contain this (file, option)
    bool may_succeed = false;  ///< exit 0 allowed when `output_ok`
    std::function<bool()> output_ok = [] { return true; };
    std::function<bool()> kept = {};  ///< the protected earlier output is intact
    long file_size_limit = 0;         ///< RLIMIT_FSIZE: writes beyond fail as on a full disk
    double kill_after_s = -1;         ///< >= 0: SIGKILL after this long (a crash on purpose)
    std::string env = {};             ///< NAME=VALUE set for the program
    bool stdout_full = false;         ///< stdout is /dev/full (every write fails with ENOSPC)
};

struct Tally {
    std::map<std::string, std::array<int, kVerdicts>> rows;  // "program / kind"
    std::vector<std::string> failures;
};

Verdict judge(const Case& c, int code, bool hung, const std::string& log) {
    if (hung) return kHang;
    if (c.kill_after_s >= 0 && code == 128 + SIGKILL) return !c.kept || c.kept() ? kHandled : kLost;
    if (code == 0) {
        if (!c.may_succeed && c.kill_after_s < 0) return kSilent;
        return c.output_ok() ? kHandled : kSilent;
    }
    if (code > 4) return kCrash;
    if (c.kept && !c.kept()) return kLost;
    const bool named = log.find(c.names) != std::string::npos;
    return named && log.find("MRPT exception") == std::string::npos ? kClear : kUnnamed;
}

// Runs bin/<program> with stdout and stderr into `log` (stdout into /dev/full when
// `stdout_full`), `c.env` set and `c.file_size_limit` applied; polls `stop` every 10 ms and
// kills the program when it returns true. Returns the exit code, or 128 + signal.
int runCase(const Case& c, const fs::path& log, const std::function<bool()>& stop) {
    lookup::test::ProgramRun how;
    how.log = log;
    how.env = c.env;
    how.file_size_limit = c.file_size_limit;
    how.stdout_full = c.stdout_full;
    how.kill_when = stop;
    return lookup::test::runProgram(c.program, c.args, how);
}

void run(const Case& c, const fs::path& dir, Tally& t) {
    const auto start = std::chrono::steady_clock::now();
    bool hung = false;
    const auto seconds = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    const int code = runCase(c, dir / "case.log", [&] {
        hung = seconds() > kHangS;
        return hung || (c.kill_after_s >= 0 && seconds() > c.kill_after_s);
    });
    const std::string log = lookup::test::readText(dir / "case.log");
    const Verdict v = judge(c, code, hung, log);
    ++t.rows[c.program + " | " + c.kind][v];
    if (v != kClear && v != kHandled) {
        std::string cmd = c.program;
        for (const auto& a : c.args) cmd += " " + a;
        t.failures.push_back(std::string(kVerdictNames[v]) + " (exit " + std::to_string(code) +
                             "): " + cmd + "\n    " + log.substr(0, 400));
    }
}

// A copy of `file` as `<dir>/<name><ext>` with `damage` applied to its bytes.
std::string damaged(const fs::path& file, const fs::path& dir, const std::string& name,
                    const std::function<void(std::string&)>& damage) {
    std::string bytes = lookup::test::readText(file);
    damage(bytes);
    const fs::path out = dir / (name + file.extension().string());
    std::ofstream(out, std::ios::binary) << bytes;
    return out.string();
}

std::function<void(std::string&)> cutAt(double share) {
    return [share](std::string& b) { b.resize(static_cast<std::size_t>(b.size() * share)); };
}
std::function<void(std::string&)> flipAt(double share) {
    return [share](std::string& b) { b[static_cast<std::size_t>(b.size() * share)] ^= 0x5a; };
}

// `rows` with row 2 (1-based, after the first data row) replaced by `bad`.
std::string poseFileWithRow(const fs::path& good, const fs::path& out, const std::string& bad) {
    std::istringstream in(lookup::test::readText(good));
    std::string first, line;
    while (std::getline(in, first) && (first.empty() || first[0] == '#')) {
    }
    std::ofstream(out) << first << "\n" << bad << "\n";
    return out.string();
}

// Every kind of bad row of a pose file, each in a file of its own (named bad_pose_<k>).
std::vector<std::string> badPoseFiles(const fs::path& good, const fs::path& dir, bool tum) {
    const std::string tail = tum ? " 0 0 0 1" : " 0 0 0";
    std::vector<std::string> rows = {"3000000000 0 abc 0" + tail,
                                     "3000000000 nan 0 0" + tail,
                                     "3000000000 0 inf 0" + tail,
                                     "1e300 0 0 0" + tail,
                                     "3000000000 1e200 0 0" + tail,
                                     "3000000000 0 0",
                                     std::string("\x01\xff\xfe garbage", 12)};
    if (tum) rows.push_back("3000000000 0 0 0 0 0 0 0");  // zero quaternion
    std::vector<std::string> files;
    for (std::size_t k = 0; k < rows.size(); ++k) {
        files.push_back(
            poseFileWithRow(good, dir / ("bad_pose_" + std::to_string(k) + ".txt"), rows[k]));
    }
    std::ofstream(dir / "empty_pose.txt") << "# nothing\n";
    files.push_back((dir / "empty_pose.txt").string());
    return files;
}

// An .ini file with `text`.
std::string iniFile(const fs::path& dir, const std::string& name, const std::string& text) {
    const fs::path p = dir / (name + ".ini");
    std::ofstream(p, std::ios::binary) << text;
    return p.string();
}

const std::string kBinary(
    "\x7f"
    "ELF\x02\x01\x01\0\0\0garbage",
    18);

}  // namespace

namespace {

// The inputs every case starts from: a database, a query, its complete run and report.
struct Data {
    fs::path dir;
    localize::LocalizeRequest req;
    fs::path gt;
    std::string frames, timing;  // the complete run at req.out_dir
};

bool runIntact(const Data& d) {
    return lookup::test::readText(fs::path(d.req.out_dir) / "frames.csv") == d.frames &&
           lookup::test::readText(fs::path(d.req.out_dir) / "timing.json") == d.timing;
}

// The complete run back at --out, as it was before the cases.
void restoreRun(const Data& d) {
    fs::remove_all(d.req.out_dir);
    fs::copy(d.dir / "run_complete", d.req.out_dir, fs::copy_options::recursive);
}

bool runComplete(const fs::path& run) {
    return fs::exists(run / "timing.json") && fs::exists(run / "frames.csv") &&
           nonFiniteLines(run / "frames.csv", 1) == 0;
}

// A run folder with finite frames whose poses are the complete run's, unless the log warned
// about the rawlog.
std::function<bool()> runChecksOut(const Data& d, const fs::path& run, const fs::path& rawlog) {
    return [&d, run, rawlog] {
        if (!runComplete(run)) return false;
        const std::string log = lookup::test::readText(d.dir / "case.log");
        return lookup::test::readText(run / "poses.tum") ==
                   lookup::test::readText(fs::path(d.req.out_dir) / "poses.tum") ||
               log.find(rawlog.filename().string()) != std::string::npos;
    };
}

// `args` with `flag`'s value replaced (or the flag added).
std::vector<std::string> with(std::vector<std::string> args, const std::string& flag,
                              const std::string& value) {
    const auto at = std::find(args.begin(), args.end(), flag);
    if (at != args.end() && at + 1 != args.end()) {
        *(at + 1) = value;
    } else {
        args.insert(args.end(), {flag, value});
    }
    return args;
}

using Refuse =
    std::function<void(const std::string&, std::vector<std::string>, const std::string&)>;

void localizeOptionCases(const Data& d, const Refuse& refuse) {
    const auto args = localizeArgs(d.req);
    const std::vector<std::pair<std::string, std::string>> inis = {
        {"binary", kBinary},
        {"nan", "[localizer]\nreferences_per_query = nan\n"},
        {"wrap", "[localizer]\nreferences_per_query = 4294967320\n"},
        {"word", "[localizer]\nacquisition_radius_m = far\n"},
        {"negative", "[localizer]\nacquisition_radius_m = -4\n"},
        {"unknown_key", "[localizer]\nreferences_per_querry = 3\n"},
        {"unknown_section", "[refine.matchr]\npatch_px = 40\n"}};
    for (const auto& [name, text] : inis) {
        const auto ini = iniFile(d.dir, "localize_" + name, text);
        refuse("bad --ini", with(args, "--ini", ini), ini);
    }
    const std::vector<std::array<std::string, 3>> flags = {
        {"--sampling", "bogus", "sampling"},
        {"--matcher", "bogus", "matcher"},
        {"--max-frames", "-3", "max-frames"},
        {"--repeat", "abc", "repeat"},
        {"--repeat", "0", "repeat"},
        {"--db", "/nonexistent/db", "/nonexistent/db"},
        {"--rawlog", "/nonexistent/q.rawlog", "/nonexistent/q.rawlog"},
        {"--coarse-poses", "/nonexistent/c.tum", "/nonexistent/c.tum"},
        {"--no-such-flag", "1", "no-such-flag"}};
    for (const auto& [flag, value, names] : flags) {
        refuse("bad command line", with(args, flag, value), names);
    }
}

void localizeDatabaseCases(const Data& d, const Refuse& refuse) {
    const fs::path db = d.req.db_dir;
    const std::vector<std::pair<std::string, std::function<void(std::string&)>>> damage = {
        {"refs.rawlog", flipAt(0.5)},    {"refs.rawlog", cutAt(0.5)},
        {"db.ini", flipAt(0.3)},         {"refs.tum", flipAt(0.5)},
        {"manifest.crc32", flipAt(0.6)}, {"refs_Images/ceiling_000003.pgm", flipAt(0.5)}};
    for (const auto& [file, spoil] : damage) {
        const fs::path bad_db = d.dir / "db_bad";
        fs::remove_all(bad_db);
        fs::copy(db, bad_db, fs::copy_options::recursive);
        std::string bytes = lookup::test::readText(bad_db / file);
        spoil(bytes);
        std::ofstream(bad_db / file, std::ios::binary) << bytes;
        refuse("damaged database file", with(localizeArgs(d.req), "--db", bad_db.string()),
               (bad_db / file).string());
    }
    // Values, the checksum out of the way (a hand-edited db.ini).
    for (const auto& [from, to] : std::vector<std::pair<std::string, std::string>>{
             {"fx = ", "fx = nan ; "},
             {"fy = ", "fy = -1 ; "},
             {"ceiling_height_m = ", "ceiling_height_m = inf ; "},
             {"reference_count = ", "reference_count = 1e99 ; "}}) {
        const fs::path bad_db = d.dir / "db_bad";
        fs::remove_all(bad_db);
        fs::copy(db, bad_db, fs::copy_options::recursive);
        fs::remove(bad_db / "manifest.crc32");
        std::string text = lookup::test::readText(bad_db / "db.ini");
        text.replace(text.find(from), from.size(), to);
        std::ofstream(bad_db / "db.ini") << text;
        refuse("bad value in db.ini", with(localizeArgs(d.req), "--db", bad_db.string()),
               (bad_db / "db.ini").string());
    }
}

// Queries with one non-finite or absurd odometry field in frames 3-5: skipped and counted
// (exit 0), never a NaN pose.
void odometryCases(const Data& d, Tally& t) {
    const double nan = std::numeric_limits<double>::quiet_NaN();
    const double inf = std::numeric_limits<double>::infinity();
    for (const auto& [name, bad] : std::vector<std::pair<std::string, double>>{
             {"nan_x", nan}, {"inf_phi", inf}, {"huge_y", 1e300}}) {
        const fs::path dir = d.dir / ("odo_" + name);
        fs::create_directories(dir);
        auto req = planarRun(
            dir, [&, name = name, bad = bad](int i, auto&, mrpt::obs::CObservationOdometry& o) {
                if (i < 3 || i > 5) return;
                if (name == "nan_x") o.odometry.x(bad);
                if (name == "inf_phi") o.odometry.phi(bad);
                if (name == "huge_y") o.odometry.y(bad);
            });
        Case c{"lookup-localize", "non-finite or huge odometry field", localizeArgs(req),
               req.rawlog, true};
        c.output_ok = [run = fs::path(req.out_dir)] {
            return runComplete(run) && nonFiniteLines(run / "poses.tum", 0) == 0;
        };
        run(c, d.dir, t);
    }
}

void localizeCases(const Data& d, Tally& t) {
    const Refuse refuse = [&](const std::string& kind, std::vector<std::string> args,
                              const std::string& names) {
        restoreRun(d);  // an earlier case that ran must not count against this one
        Case c{"lookup-localize", kind, std::move(args), names};
        c.kept = [&d] { return runIntact(d); };
        run(c, d.dir, t);
    };
    const auto args = localizeArgs(d.req);
    const fs::path query = d.req.rawlog;
    for (double share : {0.02, 0.1, 0.3, 0.5, 0.7, 0.9}) {
        const auto cut = damaged(query, d.dir, "q_cut", cutAt(share));
        refuse("truncated query rawlog", with(args, "--rawlog", cut), cut);
    }
    const fs::path run2 = d.dir / "run2";
    for (int k = 1; k <= 16; ++k) {
        const auto flip = damaged(query, d.dir, "q_flip", flipAt(k / 17.0));
        Case c{"lookup-localize", "byte flip in query rawlog",
               with(with(args, "--rawlog", flip), "--out", run2.string()), flip, true};
        c.output_ok = runChecksOut(d, run2, flip);
        run(c, d.dir, t);
    }
    for (const auto& bad : badPoseFiles(d.req.coarse_poses, d.dir, true)) {
        refuse("bad row in --coarse-poses", with(args, "--coarse-poses", bad), bad);
    }
    localizeDatabaseCases(d, refuse);
    localizeOptionCases(d, refuse);
    for (long limit : {300L, 4000L}) {
        restoreRun(d);
        Case c{"lookup-localize", "write past a file-size limit", args, d.req.out_dir};
        c.file_size_limit = limit;
        c.kept = [&d] { return runIntact(d); };
        run(c, d.dir, t);
    }
    // Last: these may replace the run at --out with a new complete one.
    restoreRun(d);
    Case full{"lookup-localize", "stdout on /dev/full", args, "stdout"};
    full.stdout_full = true;
    full.kept = [&d] { return runIntact(d) || runComplete(d.req.out_dir); };
    run(full, d.dir, t);
    for (double after : {0.05, 0.3, 0.8, 1.5}) {
        Case c{"lookup-localize", "kill -9 mid-run", args, "", true};
        c.kill_after_s = after;
        c.kept = [&d] { return runComplete(d.req.out_dir); };
        c.output_ok = c.kept;
        run(c, d.dir, t);
    }
}

void evalCases(const Data& d, Tally& t) {
    const fs::path report = d.dir / "report";
    const std::vector<std::string> args{"--gt",        d.gt.string(), "--runs",
                                        d.req.out_dir, "--out",       report.string()};
    const std::string good = lookup::test::readText(report / "report.md");
    const Refuse refuse = [&](const std::string& kind, std::vector<std::string> a,
                              const std::string& names) {
        Case c{"lookup-eval", kind, std::move(a), names};
        c.kept = [report, good] { return lookup::test::readText(report / "report.md") == good; };
        run(c, d.dir, t);
    };
    for (const auto& bad : badPoseFiles(d.gt, d.dir, false)) {
        refuse("bad row in --gt", with(args, "--gt", bad), bad);
    }
    const fs::path bad_run = d.dir / "run_bad";
    const std::string header = d.frames.substr(0, d.frames.find('\n') + 1);
    std::string nan_cell = d.frames;
    nan_cell.replace(nan_cell.find(',', header.size() + 1), 1, ",nan,");
    const std::vector<std::array<std::string, 3>> runs = {
        {"cut frames.csv", d.frames.substr(0, d.frames.size() - 25), d.timing},
        {"header only", header, d.timing},
        {"empty frames.csv", "", d.timing},
        {"NaN cell", nan_cell, d.timing},
        {"cut timing.json", d.frames, d.timing.substr(0, d.timing.size() / 2)},
        {"garbage timing.json", d.frames, kBinary},
        {"no timing.json", d.frames, "-"}};
    for (const auto& [name, frames, timing] : runs) {
        fs::remove_all(bad_run);
        fs::create_directories(bad_run);
        std::ofstream(bad_run / "frames.csv", std::ios::binary) << frames;
        if (timing != "-") std::ofstream(bad_run / "timing.json", std::ios::binary) << timing;
        refuse("damaged run folder", with(args, "--runs", bad_run.string()), bad_run.string());
    }
    const std::vector<std::pair<std::string, std::string>> inis = {
        {"binary", kBinary},
        {"negative", "[eval]\nmax_gt_gap_s = -1\n"},
        {"nan", "[eval]\ncoarse_exclusion_m = nan\n"},
        {"word", "[eval]\nconfident_wrong_min_error_m = abc\n"},
        {"unknown_section", "[evl]\nmax_gt_gap_s = 1\n"}};
    for (const auto& [name, text] : inis) {
        const auto ini = iniFile(d.dir, "eval_" + name, text);
        refuse("bad --ini", with(args, "--ini", ini), ini);
    }
    refuse("bad command line", {"--gt", d.gt.string(), "--out", report.string()}, "runs");
    refuse("bad command line", with(args, "--runs", "/nonexistent/run"), "/nonexistent/run");
    refuse("bad command line", with(args, "--gt", "/nonexistent/gt.txt"), "/nonexistent/gt.txt");
    for (long limit : {300L, 600L}) {  // stderr is capped too: room for the message
        Case c{"lookup-eval", "write past a file-size limit", args, report.string()};
        c.file_size_limit = limit;
        c.kept = [report, good] { return lookup::test::readText(report / "report.md") == good; };
        run(c, d.dir, t);
    }
    Case full{"lookup-eval", "stdout on /dev/full", args, "stdout"};
    full.stdout_full = true;
    run(full, d.dir, t);
}

void coarseCases(const Data& d, Tally& t) {
    const std::string ini = iniFile(d.dir, "s5", "[coarse]\nsequence_length = 5\n");
    const fs::path out = d.dir / "m.csv";
    const std::vector<std::string> args{"--ref",    d.req.rawlog,  "--query", d.req.rawlog,
                                        "--camera", "CEILING_CAM", "--ini",   ini,
                                        "--out",    out.string(),  "--quiet"};
    Case first{"lookup-coarse", "", args, ""};
    ASSERT_EQ(runCase(first, d.dir / "case.log", [] { return false; }), 0)
        << lookup::test::readText(d.dir / "case.log");
    const std::string good = lookup::test::readText(out);
    const auto kept = [out, good] { return lookup::test::readText(out) == good; };
    const auto refuse = [&](const std::string& kind, std::vector<std::string> a,
                            const std::string& names) {
        Case c{"lookup-coarse", kind, std::move(a), names};
        c.kept = kept;
        run(c, d.dir, t);
    };
    for (double share : {0.05, 0.4, 0.8}) {
        const auto cut = damaged(d.req.rawlog, d.dir, "c_cut", cutAt(share));
        refuse("truncated query rawlog", with(args, "--query", cut), cut);
    }
    for (int k = 1; k <= 4; ++k) {
        const auto flip = damaged(d.req.rawlog, d.dir, "c_flip", flipAt(k / 5.0));
        Case c{"lookup-coarse", "byte flip in query rawlog", with(args, "--query", flip), flip,
               true};
        c.output_ok = [out] { return fs::exists(out) && fs::file_size(out) > 0; };
        run(c, d.dir, t);
    }
    const auto bad_ini = iniFile(d.dir, "c_bad", "[coarse]\nsequence_length = -5\n");
    refuse("bad --ini", with(args, "--ini", bad_ini), bad_ini);
    const auto bin_ini = iniFile(d.dir, "c_bin", kBinary);
    refuse("bad --ini", with(args, "--ini", bin_ini), bin_ini);
    const auto section_ini = iniFile(d.dir, "c_section", "[coarse]\n[coarse_typo]\nx = 1\n");
    refuse("bad --ini", with(args, "--ini", section_ini), section_ini);
    refuse("bad command line", with(args, "--camera", "NO_SUCH_CAM"), "NO_SUCH_CAM");
    const auto bad_poses = badPoseFiles(d.req.coarse_poses, d.dir, true);
    for (std::size_t k = 0; k < 3; ++k) {
        refuse("bad row in --query-poses", with(args, "--query-poses", bad_poses[k]), bad_poses[k]);
    }
    Case limit{"lookup-coarse", "write past a file-size limit", args, out.string()};
    limit.file_size_limit = 300;  // stderr is capped too: room for the message
    limit.kept = kept;
    run(limit, d.dir, t);
}

// share/lookup/survey.ini with `key = value` in `[section]`.
std::string surveyIniWith(const fs::path& dir, const std::string& section, const std::string& key,
                          const std::string& value) {
    std::string text = lookup::test::readText(std::string(LOOKUP_SOURCE_SHARE_DIR) + "/survey.ini");
    const auto at = text.find("\n[" + section + "]");
    const auto end = text.find("\n[", at + 1);
    const auto line = text.find("\n" + key + " ", at);
    if (at == std::string::npos || line == std::string::npos || line > end) {
        ADD_FAILURE() << key << " not in survey.ini [" << section << "]";
    } else {
        text.replace(line + 1, text.find('\n', line + 1) - line - 1, key + " = " + value);
    }
    return iniFile(dir, "survey_" + key, text);
}

// lookup-survey --refresh of `db` from `drive` with runs it cannot use: missing, unreadable,
// of another drive; the database refreshed is never touched.
void refreshCases(const fs::path& dir, const std::string& drive, const fs::path& db,
                  const Refuse& refuse) {
    const auto runFolder = [&dir](const std::string& name, const std::string& rows) {
        const fs::path run = dir / name;
        fs::create_directories(run);
        std::ofstream(run / "frames.csv")
            << "time_s,status,reason,x,y,yaw,cov_xx,cov_xy,cov_yy,cov_tt,coarse_x,coarse_y,"
               "coarse_yaw,inlier_share,references,ms\n"
            << rows;
        std::ofstream(run / "timing.json") << "{\"frames\": 2}\n";
        return run.string();
    };
    const auto args = [&](const std::string& from, const std::string& run) {
        return std::vector<std::string>{"--refresh", from,    "--rawlogs",
                                        drive,       "--run", run,
                                        "-q",        "--out", (dir / "db_refreshed").string()};
    };
    refuse("refresh: bad run", args(db.string(), "/nonexistent/run"), "/nonexistent/run");
    refuse("refresh: bad run", args("/nonexistent/db", (dir / "run_x").string()),
           "/nonexistent/db");
    const auto garbled = runFolder("run_garbled", "1.0,refined,,abc,0,0,0,0,0,0,,,,0.5,3,1\n");
    refuse("refresh: bad run", args(db.string(), garbled), garbled);
    const auto other = runFolder("run_other",
                                 "1.0,refined,,0,0,0,1e-4,0,1e-4,1e-5,,,,0.9,3,1\n"
                                 "2.0,refined,,1,0,0,1e-4,0,1e-4,1e-5,,,,0.9,3,1\n");
    refuse("refresh: bad run", args(db.string(), other), other);
}

void surveyCases(const fs::path& dir, Tally& t) {
    const auto f = test::makeSurveyRawlog(dir.string(), "corridor", 3.0);
    const fs::path db = dir / "db_s";
    const std::vector<std::string> args{"--rawlogs", f.rawlog, "--poses",  f.ground_truth,
                                        "-q",        "--out",  db.string()};
    const auto loads = [](const fs::path& p) {
        try {
            database::ReferenceDatabase::load(p.string());
            return true;
        } catch (const std::exception&) {
            return false;
        }
    };
    Case first{"lookup-survey", "", args, ""};
    ASSERT_EQ(runCase(first, dir / "case.log", [] { return false; }), 0)
        << lookup::test::readText(dir / "case.log");
    const std::string manifest = lookup::test::readText(db / "manifest.crc32");
    const auto kept = [db, manifest] {
        return lookup::test::readText(db / "manifest.crc32") == manifest;
    };
    const Refuse refuse = [&](const std::string& kind, std::vector<std::string> a,
                              const std::string& names) {
        Case c{"lookup-survey", kind, std::move(a), names};
        c.kept = kept;
        run(c, dir, t);
    };
    refreshCases(dir, f.rawlog, db, refuse);
    fs::remove_all(dir / "s_bad_Images");
    fs::create_directory_symlink(dir / "corridor_Images", dir / "s_bad_Images");
    for (double share : {0.1, 0.5, 0.9}) {
        const auto cut = damaged(f.rawlog, dir, "s_bad", cutAt(share));
        refuse("truncated survey rawlog", with(args, "--rawlogs", cut), cut);
    }
    for (int k = 1; k <= 6; ++k) {
        const auto flip = damaged(f.rawlog, dir, "s_bad", flipAt(k / 7.0));
        Case c{"lookup-survey", "byte flip in survey rawlog",
               with(with(args, "--rawlogs", flip), "--out", (dir / "db_s2").string()), flip, true};
        c.output_ok = [&loads, dir] { return loads(dir / "db_s2"); };
        run(c, dir, t);
    }
    for (const auto& bad : badPoseFiles(f.ground_truth, dir, false)) {
        refuse("bad row in --poses", with(args, "--poses", bad), bad);
    }
    const auto bin = iniFile(dir, "survey_binary", kBinary);
    refuse("bad --ini", with(args, "--ini", bin), bin);
    const auto section =
        iniFile(dir, "survey_section",
                lookup::test::readText(std::string(LOOKUP_SOURCE_SHARE_DIR) + "/survey.ini") +
                    "\n[pose_graf]\nenabled = true\n");
    refuse("bad --ini", with(args, "--ini", section), section);
    for (const auto& [section, key, value] :
         std::vector<std::array<std::string, 3>>{{"pose_graph", "point_std_m", "nan"},
                                                 {"survey", "keyframe_spacing_m", "-1"},
                                                 {"ICP", "thresholdDist", "abc"}}) {
        const auto ini = surveyIniWith(dir, section, key, value);
        refuse("bad --ini", with(args, "--ini", ini), ini);
    }
    refuse("bad command line", with(args, "--rawlogs", "/nonexistent/a.rawlog"),
           "/nonexistent/a.rawlog");
    Case limit{"lookup-survey", "write past a file-size limit", args, db.string()};
    limit.file_size_limit = 2000;
    limit.kept = kept;
    run(limit, dir, t);
    for (const char* point : {"staging-created", "between-renames", "before-old-removed"}) {
        Case c{"lookup-survey", "kill -9 during the replacement", args, "", true};
        c.kill_after_s = kHangS;  // the program kills itself at `point`
        c.env = std::string("LOOKUP_TEST_KILL_AT=") + point;
        // Intact, or left aside for the next start to restore.
        c.kept = [&loads, db] {
            bool aside = false;
            for (const auto& e : fs::directory_iterator(db.parent_path())) {
                aside |= e.path().filename().string().rfind("db_s.old-", 0) == 0;
            }
            return loads(db) || aside;
        };
        run(c, dir, t);
        Case again{"lookup-survey", "restart after kill -9", args, "", true};
        again.output_ok = [&loads, db] { return loads(db); };
        run(again, dir, t);
    }
    Case full{"lookup-survey",
              "stdout on /dev/full",
              {"--rawlogs", f.rawlog, "--poses", f.ground_truth, "--out", db.string()},
              "stdout"};
    full.stdout_full = true;
    run(full, dir, t);
}

// lookup-train is built only with LibTorch.
void trainCases(const Data& d, Tally& t) {
    if (!fs::exists(fs::path(LOOKUP_BINARY_DIR) / "bin" / "lookup-train")) return;
    const auto bin = iniFile(d.dir, "train_binary", kBinary);
    const auto section = iniFile(d.dir, "train_section", "[fcn.trainin]\nepochs = 1\n");
    const auto model = damaged(d.req.rawlog, d.dir, "not_a_model", cutAt(0.5));
    const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
        {{"--db", "/nonexistent/db", "--train", d.req.rawlog}, "/nonexistent/db"},
        {{"--db", d.req.db_dir, "--heatmaps-only", model}, model},
        {{"--db", d.req.db_dir, "--train", d.req.rawlog, "--ini", bin}, bin},
        {{"--db", d.req.db_dir, "--train", d.req.rawlog, "--ini", section}, section},
        {{"--db", d.req.db_dir, "--train", "/nonexistent/t.rawlog"}, "/nonexistent/t.rawlog"},
        {{"--db", d.req.db_dir, "--train", d.req.rawlog, "--train-poses", "/nonexistent/p.tum"},
         "/nonexistent/p.tum"}};
    const std::string manifest = lookup::test::readText(fs::path(d.req.db_dir) / "manifest.crc32");
    for (const auto& [args, names] : cases) {
        Case c{"lookup-train", "bad input or command line", args, names};
        c.kept = [&d, manifest] {
            return lookup::test::readText(fs::path(d.req.db_dir) / "manifest.crc32") == manifest;
        };
        run(c, d.dir, t);
    }
}

void simCases(const fs::path& dir, Tally& t) {
    const std::string out = (dir / "sim").string();
    const auto bin = iniFile(dir, "sim_binary", kBinary);
    const std::vector<std::pair<std::vector<std::string>, std::string>> cases = {
        {{"--preset", "no-such-mine", "--out", out}, "no-such-mine"},
        {{"--preset", "mine-b-mini", "--seed", "abc", "--out", out}, "seed"},
        {{"--scenario", bin, "--out", out}, bin},
        {{"--scenario", "/nonexistent/s.ini", "--out", out}, "/nonexistent/s.ini"},
        {{"--preset", "mine-b-mini"}, "out"}};
    for (const auto& [args, names] : cases) {
        run(Case{"lookup-sim", "bad command line", args, names}, dir, t);
    }
}

std::string table(const Tally& t) {
    std::ostringstream md;
    md << "| program | fault | cases |";
    for (const char* v : kVerdictNames) md << " " << v << " |";
    md << "\n|---|---|---:|";
    for (int v = 0; v < kVerdicts; ++v) md << "---:|";
    md << "\n";
    std::array<int, kVerdicts> total{};
    int cases = 0;
    for (const auto& [row, counts] : t.rows) {
        const auto bar = row.find(" | ");
        int n = 0;
        for (int c : counts) n += c;
        cases += n;
        md << "| " << row.substr(0, bar) << " | " << row.substr(bar + 3) << " | " << n << " |";
        for (int v = 0; v < kVerdicts; ++v) {
            md << " " << counts[v] << " |";
            total[v] += counts[v];
        }
        md << "\n";
    }
    md << "| **all** | | **" << cases << "** |";
    for (int c : total) md << " **" << c << "** |";
    md << "\n";
    return md.str();
}

}  // namespace

TEST(FaultCampaign, EveryCaseAClearErrorOrAHandledRun) {
    Data d;
    d.dir = lookup::test::freshDir("lookup_localize_campaign");
    d.req = planarRun(d.dir, [](int, auto&, auto&) {});
    Case good{"lookup-localize", "", localizeArgs(d.req), ""};
    ASSERT_EQ(runCase(good, d.dir / "case.log", [] { return false; }), 0)
        << lookup::test::readText(d.dir / "case.log");
    fs::copy(d.req.out_dir, d.dir / "run_complete", fs::copy_options::recursive);
    d.frames = lookup::test::readText(fs::path(d.req.out_dir) / "frames.csv");
    d.timing = lookup::test::readText(fs::path(d.req.out_dir) / "timing.json");
    common::PoseTrack truth;
    for (int i = 0; i < 20; ++i) {
        truth.push_back({kT0 + 0.1 * i, mrpt::poses::CPose3D(-5 + 0.3 * i, 0.4, 0, 0.05, 0, 0)});
    }
    d.gt = d.dir / "gt.txt";
    common::writeMrptPoseFile(d.gt.string(), truth);
    Case eval{
        "lookup-eval",
        "",
        {"--gt", d.gt.string(), "--runs", d.req.out_dir, "--out", (d.dir / "report").string()},
        ""};
    ASSERT_EQ(runCase(eval, d.dir / "case.log", [] { return false; }), 0)
        << lookup::test::readText(d.dir / "case.log");

    Tally t;
    evalCases(d, t);
    coarseCases(d, t);
    localizeCases(d, t);
    odometryCases(d, t);
    trainCases(d, t);
    surveyCases(d.dir / "survey", t);
    simCases(d.dir, t);

    const std::string md = table(t);
    std::cout << md;
    for (const auto& f : t.failures) std::cout << f << "\n";
    std::ofstream(fs::temp_directory_path() / "fault_campaign.md") << md;
    EXPECT_TRUE(t.failures.empty()) << t.failures.size() << " cases neither a clear error nor "
                                    << "a handled run (listed above)";
}

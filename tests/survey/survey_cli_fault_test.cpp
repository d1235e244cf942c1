// lookup-survey as a program under bad options, damaged rawlogs and kill -9: every case must end
// with exit 1/2 and one line on stderr naming the file (and section/key), or a recovered
// database — never a signal, a hang or a database from damaged input without a word.
#include <gtest/gtest.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <regex>
#include <sstream>

#include "lookup/database/reference_database.h"
#include "lookup/test/support.h"
#include "survey_fixture.h"

namespace fs = std::filesystem;

namespace {

struct Run {
    int code = -1;    ///< exit code; >= 128: killed by a signal; 124: timed out
    std::string log;  ///< stdout and stderr together
};

// lookup-survey -q with `args` (split at spaces) and `env` ("NAME=value" or ""), killed after
// 120 s (a hang).
Run survey(const fs::path& dir, const std::string& args, const std::string& env = "") {
    std::vector<std::string> argv{"-q"};
    std::istringstream words(args);
    for (std::string w; words >> w;) argv.push_back(w);
    lookup::test::ProgramRun how;
    how.log = dir / "log.txt";
    how.env = env;
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(120);
    bool hung = false;
    how.kill_when = [&] { return hung = std::chrono::steady_clock::now() > deadline; };
    Run r;
    r.code = lookup::test::runProgram("lookup-survey", argv, how);
    if (hung) r.code = 124;
    r.log = lookup::test::readText(how.log);
    return r;
}

std::size_t lines(const std::string& s) { return std::count(s.begin(), s.end(), '\n'); }

struct Data {
    fs::path dir;
    lookup::test::Fixture f;
};

// Each test its own folder: ctest runs them as parallel processes.
const Data& data() {
    static const Data d = [] {
        Data x;
        const std::string test = testing::UnitTest::GetInstance()->current_test_info()->name();
        x.dir = fs::temp_directory_path() / ("lookup_survey_cli_fault_" + test);
        fs::remove_all(x.dir);
        x.f = lookup::test::makeSurveyRawlog(x.dir.string(), "corridor", 3.0);
        return x;
    }();
    return d;
}

std::string shareIni() { return std::string(LOOKUP_SOURCE_SHARE_DIR) + "/survey.ini"; }

// share/lookup/survey.ini with `key = value` set in `[section]` (added when absent).
std::string iniWith(const std::string& section, const std::string& key, const std::string& value) {
    std::string text = lookup::test::readText(shareIni());
    const std::regex line("\\n" + key + " *=[^\\n]*");
    const auto at = text.find("\n[" + section + "]") + 1;
    std::string head = text.substr(0, at), tail = text.substr(at);
    if (std::regex_search(tail, line)) {
        tail = std::regex_replace(tail, line, "\n" + key + " = " + value,
                                  std::regex_constants::format_first_only);
    } else {
        tail.insert(section.size() + 2, "\n" + key + " = " + value);
    }
    const auto path = data().dir / ("bad_" + section + "_" + key + ".ini");
    std::ofstream(path) << head << tail;
    return path.string();
}

}  // namespace

TEST(SurveyCliFault, BadOptionsInEverySectionAreOneLineNamingFileSectionKey) {
    const auto& d = data();
    const std::vector<std::array<std::string, 3>> cases = {
        {"survey", "keyframe_spacing_m", "abc"},
        {"survey", "mcl_particles", "4294967320"},
        {"survey", "keyframe_spacing_m", "-1"},
        {"survey", "sped_kmh", "3"},
        {"pose_graph", "point_std_m", "nan"},
        {"pose_graph", "max_iterations", "0"},
        {"pose_graph", "threads", "99999999999"},
        {"MappingApplication", "insertionLinDistance", "far"},
        {"MappingApplication_occupancyGrid_00_creationOpts", "resolution", "abc"},
        {"MappingApplication_occupancyGrid_00_insertOpts", "maxDistanceInsertion", "inf"},
        {"ICP", "thresholdDist", "abc"},
        {"ICP", "threshDist", "0.3"},
        {"ICP", "ICP_algorithm", "icpNoSuch"},
        {"PF_options", "BETA", "x"},
        {"KLD_options", "KLD_maxSampleSize", "1e999"},
        {"LikelihoodOptions", "LF_stdHit", "nan"},
    };
    for (const auto& [section, key, value] : cases) {
        const std::string ini = iniWith(section, key, value);
        const auto r = survey(d.dir, "--rawlogs " + d.f.rawlog + " --poses ground-truth --ini " +
                                         ini + " --out " + (d.dir / "db").string());
        const std::string what = section + " " + key + " = " + value;
        EXPECT_EQ(r.code, 1) << what << ": " << r.log;
        EXPECT_EQ(lines(r.log), 1u) << what << ": " << r.log;
        EXPECT_NE(r.log.find(ini + " [" + section + "]"), std::string::npos)
            << what << ": " << r.log;
        EXPECT_FALSE(fs::exists(d.dir / "db")) << what;
    }
    // Not an .ini file at all.
    std::ofstream(d.dir / "binary.ini", std::ios::binary) << std::string(
        "\x7f"
        "ELF\0\0\1",
        7);
    auto r = survey(d.dir, "--rawlogs " + d.f.rawlog + " --ini " + (d.dir / "binary.ini").string() +
                               " --out " + (d.dir / "db").string());
    EXPECT_EQ(r.code, 1) << r.log;
    EXPECT_NE(r.log.find("binary.ini: binary data"), std::string::npos) << r.log;
    r = survey(d.dir, "--no-such-flag");
    EXPECT_EQ(r.code, 1) << r.log;
    r = survey(d.dir, "--help");
    EXPECT_EQ(r.code, 0);
    EXPECT_NE(r.log.find("Exit codes: 0 success, 1 usage"), std::string::npos) << r.log;
}

TEST(SurveyCliFault, BadPoseFilesAreBadInputNamingFileAndLine) {
    const auto& d = data();
    const std::string rows = lookup::test::readText(d.f.ground_truth);
    const std::string first = rows.substr(0, rows.find('\n') + 1);
    const fs::path poses = d.dir / "poses.txt";
    // Second row bad: a word, inf, a time past the clock's range, 6 columns.
    for (const std::string bad : {"2000000000.1 0 abc 0 0 0 0", "2000000000.1 inf 0 0 0 0 0",
                                  "-1e300 0 0 0 0 0 0", "2000000000.1 0 0 0 0 0"}) {
        std::ofstream(poses) << first << bad << "\n";
        const auto r = survey(d.dir, "--rawlogs " + d.f.rawlog + " --poses " + poses.string() +
                                         " --out " + (d.dir / "dbp").string());
        EXPECT_EQ(r.code, 2) << bad << ": " << r.log;
        EXPECT_EQ(lines(r.log), 1u) << r.log;
        EXPECT_NE(r.log.find(poses.string() + ":2: "), std::string::npos) << r.log;
        EXPECT_FALSE(fs::exists(d.dir / "dbp"));
    }
}

TEST(SurveyCliFault, DamagedRawlogsRefusedNamingTheFileNeverASignal) {
    const auto& d = data();
    const std::string bytes = lookup::test::readText(d.f.rawlog);
    const fs::path bad = d.dir / "damaged.rawlog";
    // The damaged copy refers to the same external images.
    fs::remove_all(d.dir / "damaged_Images");
    fs::create_directory_symlink(d.dir / "corridor_Images", d.dir / "damaged_Images");
    fs::copy_file(d.f.ground_truth, bad.string() + ".GT.txt", fs::copy_options::overwrite_existing);
    int refused = 0, accepted = 0;
    for (int k = 0; k < 12; ++k) {
        std::string b = bytes;
        if (k < 4) {
            b.resize(b.size() * (k + 1) / 5);  // truncated
        } else {
            b[b.size() * (k - 3) / 9] ^= 0x5a;  // one byte flipped
        }
        std::ofstream(bad, std::ios::binary) << b;
        const auto r = survey(d.dir, "--rawlogs " + bad.string() + " --poses ground-truth --out " +
                                         (d.dir / "dbd").string());
        ASSERT_LT(r.code, 124) << "case " << k << ": signal or hang: " << r.log;
        if (r.code == 0) {
            ++accepted;
            continue;
        }
        ++refused;
        EXPECT_EQ(r.code, 2) << "case " << k << ": " << r.log;
        EXPECT_EQ(lines(r.log), 1u) << r.log;
        EXPECT_NE(r.log.find("damaged.rawlog: record"), std::string::npos) << r.log;
    }
    EXPECT_GE(refused, 4);  // every truncation at least
    RecordProperty("damaged_accepted", accepted);
}

TEST(SurveyCliFault, KillBetweenTheRenamesIsRecoveredAtTheNextStart) {
    const auto& d = data();
    const fs::path db = d.dir / "dbk";
    const std::string args =
        "--rawlogs " + d.f.rawlog + " --poses ground-truth --out " + db.string();
    ASSERT_EQ(survey(d.dir, args).code, 0);
    for (const char* point : {"staging-created", "between-renames", "before-old-removed"}) {
        const auto killed = survey(d.dir, args, std::string("LOOKUP_TEST_KILL_AT=") + point);
        EXPECT_EQ(killed.code, 128 + 9) << point << ": " << killed.log;
        const auto again = survey(d.dir, args);
        EXPECT_EQ(again.code, 0) << point << ": " << again.log;
        EXPECT_NE(again.log.find("interrupted lookup-survey"), std::string::npos) << again.log;
        EXPECT_NO_THROW(lookup::database::ReferenceDatabase::load(db.string())) << point;
        for (const auto& e : fs::directory_iterator(d.dir)) {
            const auto n = e.path().filename().string();
            EXPECT_EQ(n.find("dbk."), std::string::npos) << point << ": left " << n;
        }
    }
}

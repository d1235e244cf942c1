// Strict option reading (ranges, non-finite values, non-ini files, MRPT-read sections) and the
// one-line error / exit-code mapping shared by every program.
#include <gtest/gtest.h>
#include <mrpt/3rdparty/tclap/ArgException.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/core/exceptions.h>
#include <mrpt/img/TCamera.h>

#include <filesystem>
#include <fstream>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/rawlog_io.h"

namespace fs = std::filesystem;
using namespace lookup::common;

namespace {

std::string messageOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const std::exception& e) {
        return e.what();
    }
    return "";
}

std::string writeFile(const std::string& name, const std::string& text) {
    const auto path = (fs::temp_directory_path() / ("lookup_errors_" + name)).string();
    std::ofstream(path, std::ios::binary) << text;
    return path;
}

}  // namespace

TEST(StrictOptions, IntegersOutsideIntOrTheirRangeAreRefusedNamingTheRange) {
    mrpt::config::CConfigFileMemory cfg("[sampler]\ngrid_points = 4294967320\nsmall = 100000\n");
    const IniSection s(cfg, "sampler", "refiner.ini");
    std::string m = messageOf([&] { s.getInt("grid_points", 24); });
    EXPECT_EQ(m,
              "refiner.ini [sampler] grid_points: 4294967320 is out of range [-2147483648, "
              "2147483647]");
    m = messageOf([&] { s.getInt("small", 24, 4, 1024); });
    EXPECT_EQ(m, "refiner.ini [sampler] small: 100000 is out of range [4, 1024]");
    EXPECT_EQ(s.getInt("absent", 24, 4, 1024), 24);
}

TEST(StrictOptions, NonFiniteDoublesAreRefused) {
    mrpt::config::CConfigFileMemory cfg("[g]\na = nan\nb = -inf\nc = 1e999\nd = 0.5\n");
    const IniSection s(cfg, "g", "f.ini");
    for (const char* key : {"a", "b", "c"}) {
        EXPECT_NE(messageOf([&] { s.getDouble(key, 1); }).find("is not finite"), std::string::npos)
            << key;
    }
    EXPECT_DOUBLE_EQ(s.getDouble("d", 1, 0, 1), 0.5);
    EXPECT_NE(messageOf([&] { s.getDouble("d", 1, 0.6, 1); }).find("out of range"),
              std::string::npos);
}

TEST(StrictOptions, BinaryOrNonIniFilesAreRefusedNamingFileAndLine) {
    EXPECT_NE(messageOf([] {
                  loadIniFile(writeFile("bin.ini", std::string("\x7f"
                                                               "ELF\0\1",
                                                               6)));
              }).find("binary data"),
              std::string::npos);
    const auto garbage = writeFile("garbage.ini", "[survey]\nkeyframe_spacing_m = 0.25\nhello\n");
    EXPECT_EQ(messageOf([&] { loadIniFile(garbage); }),
              garbage + ":3: not a 'key = value' line: 'hello'");
    const auto nosection = writeFile("nosection.ini", "# comment\na = 1\n");
    EXPECT_NE(messageOf([&] { loadIniFile(nosection); }).find(nosection + ":2: key before"),
              std::string::npos);
    const auto empty = writeFile("empty.ini", "");
    EXPECT_NE(messageOf([&] { loadIniFile(empty); }).find("no [section]"), std::string::npos);
    const auto good = writeFile("good.ini", "; c\n// c\n[s]\nk = v # c\n@include x\n");
    const auto cfg = loadIniFile(good);
    EXPECT_EQ(configSourceName(*cfg), good);
    EXPECT_EQ(IniSection(*cfg, "s").where("k"), good + " [s] k: ");
}

// A variant file keeps only what differs from its base: every key of both, its own winning,
// through a chain of bases; a base that is missing or loops back is an error naming the file.
TEST(StrictOptions, AFileLaidOverItsBaseKeepsOnlyWhatDiffers) {
    const auto shared = writeFile("shared.ini", "[a]\nx = 1\ny = 2  // why\n[b]\nz = 3\n");
    const auto name = [](const std::string& path) { return fs::path(path).filename().string(); };
    const auto mine =
        writeFile("mine.ini", "[ini]\nbase = " + name(shared) + "\n[a]\ny = 5\n[c]\nw = 6\n");
    const auto pit = writeFile("pit.ini", "[ini]\nbase = " + name(mine) + "\n[b]\nz = 7\n");
    const auto cfg = loadIniFile(pit);
    EXPECT_EQ(cfg->read_int("a", "x", 0), 1);
    EXPECT_EQ(cfg->read_int("a", "y", 0), 5);
    EXPECT_EQ(cfg->read_int("b", "z", 0), 7);
    EXPECT_EQ(cfg->read_int("c", "w", 0), 6);
    EXPECT_FALSE(cfg->sectionExists("ini"));
    EXPECT_EQ(configSourceName(*cfg), pit + " (over " + mine + " (over " + shared + "))");

    // Installed under its base's name, a file takes its base from the share folders.
    const auto dir = fs::temp_directory_path() / "lookup_errors_etc";
    fs::create_directories(dir);
    fs::copy_file(std::string(LOOKUP_SOURCE_SHARE_DIR) + "/localize-mine-b.ini",
                  dir / "localize.ini", fs::copy_options::overwrite_existing);
    const auto installed = loadIniFile((dir / "localize.ini").string());
    EXPECT_EQ(installed->read_int("refine.matcher", "patch_px", 0), 60);
    EXPECT_DOUBLE_EQ(installed->read_double("refine.acceptance", "min_inlier_share", 0), 0.45);

    const auto missing = writeFile("missing.ini", "[ini]\nbase = nowhere.ini\n[a]\nx = 1\n");
    const std::string why = messageOf([&] { loadIniFile(missing); });
    EXPECT_NE(why.find(missing + " [ini] base: "), std::string::npos) << why;
    EXPECT_NE(why.find("nowhere.ini: no such .ini file"), std::string::npos) << why;
    const auto loop = writeFile("loop_b.ini", "[ini]\nbase = lookup_errors_loop_a.ini\n");
    writeFile("loop_a.ini", "[ini]\nbase = " + name(loop) + "\n[a]\nx = 1\n");
    EXPECT_NE(messageOf([&] { loadIniFile(loop); }).find("(a cycle)"), std::string::npos);
    const auto typo = writeFile("typo.ini", "[ini]\nbsae = shared.ini\n[a]\nx = 1\n");
    EXPECT_NE(messageOf([&] { loadIniFile(typo); }).find("[ini] bsae: unknown key"),
              std::string::npos);
}

TEST(StrictOptions, MrptReadSectionsRefuseUnknownKeysAndMalformedValues) {
    const auto check = [](const std::string& text) {
        mrpt::config::CConfigFileMemory cfg(text);
        return messageOf([&] {
            checkMrptSection(cfg, "cam", [](const mrpt::config::CConfigFileBase& c) {
                mrpt::img::TCamera cam;
                cam.loadFromConfigFile("cam", c);
            });
        });
    };
    const std::string rest = "cx = 1\ncy = 2\nfy = 50\ndist = [0 0 0 0 0]\n";
    EXPECT_EQ(check("[cam]\nresolution = [64 48]\nfx = 50\n" + rest), "");
    EXPECT_NE(
        check("[cam]\nresolution = [64 48]\nfx = abc\n" + rest).find("[cam] fx: 'abc' is not a"),
        std::string::npos);
    EXPECT_NE(check("[cam]\nresolution = [64 48]\nfx = 1\nfxx = 1\n" + rest)
                  .find("[cam] fxx: unknown key"),
              std::string::npos);
    const std::string m = check("[cam]\nresolution = [64 x]\nfx = 1\n" + rest);
    EXPECT_NE(m.find("[cam]"), std::string::npos) << m;
    EXPECT_NE(m.find("resolution"), std::string::npos) << m;
    // A key the loader requires is missing: named, not a crash.
    EXPECT_NE(check("[cam]\nfx = 1\n").find("<memory> [cam]: "), std::string::npos);
}

TEST(ErrorLine, MrptDumpReducedToItsMessageAndExitCodesByKind) {
    try {
        THROW_EXCEPTION("inner reason");
    } catch (const std::exception& e) {
        const std::string line = errorLine(e);
        EXPECT_EQ(line.find('\n'), std::string::npos) << line;
        EXPECT_NE(line.find("inner reason"), std::string::npos) << line;
        EXPECT_EQ(line.find("Call stack"), std::string::npos) << line;
        EXPECT_NE(errorText(e, true).find("Call stack"), std::string::npos);
        const std::runtime_error wrapped(std::string("f.rawlog: record 3: ") + e.what());
        EXPECT_EQ(errorLine(wrapped).rfind("f.rawlog: record 3: ", 0), 0u) << errorLine(wrapped);
        EXPECT_EQ(errorLine(wrapped).find('\n'), std::string::npos);
        EXPECT_EQ(exitCodeFor(e), kExitBadInput);
    }
    EXPECT_EQ(exitCodeFor(ConfigError("x")), kExitUsage);
    EXPECT_EQ(exitCodeFor(TCLAP::ArgException("x")), kExitUsage);
    EXPECT_EQ(exitCodeFor(WriteError("f", "full")), kExitWriteError);
    EXPECT_EQ(exitCodeFor(RawlogError("f", 1, "bad")), kExitBadInput);
    EXPECT_EQ(exitCodeFor(InternalError("bug")), kExitInternal);
    EXPECT_EQ(exitCodeFor(std::bad_alloc()), kExitInternal);
    EXPECT_EQ(errorLine(ConfigError("a\nb")), "a; b");
    const char* argv[] = {"p"};
    EXPECT_EQ(guardedMain("p", 1, argv, []() -> int { throw WriteError("out.csv", "full"); }),
              kExitWriteError);
    EXPECT_EQ(guardedMain("p", 1, argv, []() -> int { throw 42; }), kExitInternal);
}

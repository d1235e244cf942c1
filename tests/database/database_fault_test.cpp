// Faults against a database folder: damaged files (the manifest catches them, naming the
// file), malformed db.ini values, kill -9 at each step of the replacement and a full disk.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <limits>

#include "lookup/common/errors.h"
#include "lookup/database/database_writer.h"
#include "lookup/database/manifest.h"
#include "lookup/database/reference_database.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using namespace lookup::database;

namespace {

// A database of `n` references of 64x48 px of noise (so PNG and gzip cannot shrink them).
void writeDatabase(const fs::path& out, int n) {
    DatabaseWriter w(out.string());
    const mrpt::img::TCamera cam = lookup::test::pinholeCamera(64, 48, 50);
    for (int i = 0; i < n; ++i) {
        ReferenceInput in;
        in.traverse = "a";
        in.ceiling = mrpt::obs::CObservationImage::Create();
        in.ceiling->sensorLabel = "CEILING_CAM";
        in.ceiling->timestamp = mrpt::Clock::fromDouble(100.0 + i);
        in.ceiling->cameraParams = cam;
        in.ceiling->image.resize(64, 48, mrpt::img::CH_GRAY);
        for (int v = 0; v < 48; ++v)
            for (int u = 0; u < 64; ++u) {
                *in.ceiling->image(u, v) =
                    uint8_t((u * 7919 + v * 104729 + i * 31) * 2654435761u >> 24);
            }
        in.vehicle_pose = mrpt::poses::CPose3D(i * 0.5, 0, 0, 0, 0, 0);
        in.vehicle_cov.setIdentity();
        w.add(in);
    }
    DatabaseInfo info;
    info.ceiling_camera = cam;
    info.ceiling_height_m = 4;
    w.commit(info);
}

std::string loadError(const fs::path& db) {
    try {
        ReferenceDatabase::load(db.string());
    } catch (const DatabaseError& e) {
        return e.what();
    }
    return "";
}

void flipByte(const fs::path& file, std::size_t offset) {
    std::fstream f(file, std::ios::in | std::ios::out | std::ios::binary);
    f.seekg(static_cast<std::streamoff>(offset));
    char c = 0;
    f.get(c);
    f.seekp(static_cast<std::streamoff>(offset));
    f.put(static_cast<char>(c ^ 0x10));
}

// Runs `body` in a forked child; returns its wait status.
int inChild(const std::function<int()>& body) {
    const pid_t pid = fork();
    if (pid == 0) {
        int code = 5;
        try {
            code = body();
        } catch (const lookup::common::WriteError&) {
            code = 3;
        } catch (...) {
            code = 6;
        }
        _exit(code);
    }
    int status = 0;
    waitpid(pid, &status, 0);
    return status;
}

int leftovers(const fs::path& dir) {
    int n = 0;
    for (const auto& e : fs::directory_iterator(dir)) {
        const auto name = e.path().filename().string();
        n += name.find(".tmp-") != std::string::npos || name.find(".old-") != std::string::npos;
    }
    return n;
}

}  // namespace

TEST(DatabaseFault, FlippedByteInAnyFileRefusedNamingIt) {
    const auto dir = lookup::test::freshDir("lookup_database_fault_flip");
    writeDatabase(dir / "db", 4);
    ASSERT_EQ(loadError(dir / "db"), "");
    for (const std::string rel :
         {"refs.rawlog", "refs_Images/ceiling_000002.pgm", "db.ini", "refs.tum"}) {
        writeDatabase(dir / "db", 4);
        const fs::path file = dir / "db" / rel;
        flipByte(file, fs::file_size(file) / 2);
        const std::string m = loadError(dir / "db");
        EXPECT_NE(m.find(file.string() + ": damaged"), std::string::npos) << rel << ": " << m;
    }
    // Truncated: named too.
    writeDatabase(dir / "db", 4);
    fs::resize_file(dir / "db" / "refs.rawlog", fs::file_size(dir / "db" / "refs.rawlog") - 9);
    EXPECT_NE(loadError(dir / "db").find("refs.rawlog: damaged"), std::string::npos);
    // lookup-train's rewrite of [heatmaps] keeps the database valid.
    writeDatabase(dir / "db", 4);
    fs::create_directory(dir / "db" / "h1");
    { std::ofstream(dir / "db" / "db.ini", std::ios::app) << "\n[heatmaps]\ndirectory = h1\n"; }
    EXPECT_EQ(loadError(dir / "db"), "");
}

// Heat maps as lookup-train leaves them: a folder with a manifest of its own, listed in db.ini.
TEST(DatabaseFault, DamagedOrMissingHeatMapsNamed) {
    const auto dir = lookup::test::freshDir("lookup_database_fault_heatmaps");
    const fs::path db = dir / "db";
    const fs::path heat = db / "heatmaps_001";
    const auto withHeatMaps = [&](const std::string& listed) {
        writeDatabase(db, 3);
        fs::create_directory(heat);
        for (int i = 0; i < 3; ++i) {
            std::ofstream(heat / ("heat_00000" + std::to_string(i) + ".png"), std::ios::binary)
                << std::string(200, char('a' + i));
        }
        writeManifest(heat.string());
        std::ofstream(db / "db.ini", std::ios::app)
            << "\n[heatmaps]\ndirectory = " << listed << "\n";
    };
    withHeatMaps("heatmaps_001");
    ASSERT_EQ(loadError(db), "");
    flipByte(heat / "heat_000001.png", 100);
    std::string m = loadError(db);
    EXPECT_NE(m.find((heat / "heat_000001.png").string() + ": damaged"), std::string::npos) << m;
    withHeatMaps("heatmaps_001");
    fs::remove(heat / "heat_000002.png");
    m = loadError(db);
    EXPECT_NE(m.find((heat / "heat_000002.png").string() + ": missing"), std::string::npos) << m;
    withHeatMaps("heatmaps_009");
    m = loadError(db);
    EXPECT_NE(
        m.find("db.ini [heatmaps] directory: " + (db / "heatmaps_009").string() + " is missing"),
        std::string::npos)
        << m;
    withHeatMaps("../elsewhere");
    EXPECT_NE(loadError(db).find("is not a folder inside the database"), std::string::npos);
}

TEST(DatabaseFault, MalformedDbIniValuesNamed) {
    const auto dir = lookup::test::freshDir("lookup_database_fault_dbini");
    const auto rewrite = [&](const std::string& from, const std::string& to) {
        writeDatabase(dir / "db", 2);
        fs::remove(dir / "db" / kManifest);  // the values, not the checksum, are under test
        std::ifstream in(dir / "db" / "db.ini");
        std::string text((std::istreambuf_iterator<char>(in)), {});
        const auto at = text.find(from);
        if (at == std::string::npos) return std::string("'" + from + "' not in db.ini");
        text.replace(at, from.size(), to);
        std::ofstream(dir / "db" / "db.ini") << text;
        return loadError(dir / "db");
    };
    std::string m = rewrite("fx = 50", "fx = abc");
    EXPECT_NE(m.find("db.ini [ceiling_camera] fx: 'abc"), std::string::npos) << m;
    EXPECT_NE(m.find("is not a finite number"), std::string::npos) << m;
    m = rewrite("fx = 50", "fx = -50");
    EXPECT_NE(m.find("db.ini [ceiling_camera] fx: focal lengths"), std::string::npos) << m;
    m = rewrite("fy = 50", "fy = nan");
    EXPECT_NE(m.find("[ceiling_camera] fy"), std::string::npos) << m;
    m = rewrite("reference_count = 2", "reference_count = 4294967298");
    EXPECT_NE(m.find("[database] reference_count: 4294967298 is out of range"), std::string::npos)
        << m;
    m = rewrite("[ceiling_camera]", "\x01\x02garbage line");
    EXPECT_NE(m.find("db.ini:"), std::string::npos) << m;
}

TEST(DatabaseFault, KillAtEveryStepOfTheReplacementLosesNothing) {
    const auto dir = lookup::test::freshDir("lookup_database_fault_kill");
    const fs::path db = dir / "db";
    for (const char* point : {"staging-created", "between-renames", "before-old-removed"}) {
        fs::remove_all(db);
        writeDatabase(db, 3);
        const int status = inChild([&] {
            setenv("LOOKUP_TEST_KILL_AT", point, 1);
            writeDatabase(db, 5);
            return 0;
        });
        ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGKILL) << point;
        const bool between = std::string(point) == "between-renames";
        EXPECT_EQ(leftovers(dir), between ? 2 : 1) << point;  // staging and/or old
        if (between) {
            // No database at the target, and the error says where it is.
            EXPECT_NE(loadError(db).find(".old-"), std::string::npos) << loadError(db);
        }
        const auto done = recoverInterrupted(db.string());
        EXPECT_FALSE(done.empty()) << point;
        EXPECT_EQ(leftovers(dir), 0) << point;
        ASSERT_EQ(loadError(db), "") << point;
        const std::size_t expected = std::string(point) == "before-old-removed" ? 5 : 3;
        EXPECT_EQ(ReferenceDatabase::load(db.string()).size(), expected) << point;
    }
    // A running writer's staging folder is not touched.
    DatabaseWriter live(db.string());
    EXPECT_TRUE(recoverInterrupted(db.string()).empty());
    EXPECT_TRUE(fs::is_directory(live.stagingDir()));
}

TEST(DatabaseFault, FullDiskIsAWriteErrorAndKeepsTheOldDatabase) {
    const auto dir = lookup::test::freshDir("lookup_database_fault_full");
    const fs::path db = dir / "db";
    writeDatabase(dir / "probe", 120);
    const auto image = fs::file_size(dir / "probe" / "refs_Images" / "ceiling_000000.pgm");
    const auto rawlog = fs::file_size(dir / "probe" / "refs.rawlog");
    ASSERT_GT(rawlog, 2 * image);
    fs::remove_all(dir / "probe");
    writeDatabase(db, 3);
    // The first image fails, or the rawlog half-way.
    for (const rlim_t limit : {rlim_t(image / 2), rlim_t(rawlog / 2)}) {
        const int status = inChild([&] {
            signal(SIGXFSZ, SIG_IGN);
            const rlimit r{limit, limit};
            setrlimit(RLIMIT_FSIZE, &r);
            writeDatabase(db, 120);
            return 0;
        });
        ASSERT_TRUE(WIFEXITED(status)) << limit;
        EXPECT_EQ(WEXITSTATUS(status), 3) << "file size limit " << limit;
        EXPECT_EQ(leftovers(dir), 0) << limit;
        ASSERT_EQ(loadError(db), "") << limit;
        EXPECT_EQ(ReferenceDatabase::load(db.string()).size(), 3u) << limit;
    }
}

TEST(DatabaseFault, NonFinitePoseNeverStored) {
    const auto dir = lookup::test::freshDir("lookup_database_fault_nanpose");
    DatabaseWriter w((dir / "db").string());
    ReferenceInput in;
    in.ceiling = mrpt::obs::CObservationImage::Create();
    in.ceiling->image.resize(8, 8, mrpt::img::CH_GRAY);
    in.vehicle_cov.setIdentity();
    in.vehicle_pose = mrpt::poses::CPose3D(1, std::nan(""), 0, 0, 0, 0);
    EXPECT_THROW(w.add(in), DatabaseError);
    in.vehicle_pose = mrpt::poses::CPose3D();
    in.vehicle_cov(1, 1) = std::numeric_limits<double>::infinity();
    EXPECT_THROW(w.add(in), DatabaseError);
    EXPECT_EQ(w.size(), 0u);
}

// A changed ceiling through the whole pipeline (lookup-sim -> survey with laser-derived
// references -> localise -> lookup-survey --refresh -> localise -> evaluate): a first drive over
// new shotcrete and mesh refreshes the database, and a second drive the same day, along another
// line, refines more of its frames, more accurately, than against the surveyed database alone.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "lookup/suite/suite.h"

namespace fs = std::filesystem;
using namespace lookup::suite;

namespace {

// The changed ceiling and the other vehicle's camera, on traverses 3 and 4.
std::string changedDay(bool refresh) {
    std::ostringstream s;
    s << "scenario.traverse_count = 5\n"
      << "traverse_3.roles = " << (refresh ? "query,refresh" : "query") << "\n"
      << "traverse_4.name = second-drive\ntraverse_4.roles = query\n"
      << "traverse_4.lateral_offset_m = 0.6\ntraverse_4.speed_kmh = 25\n";
    for (const char* t : {"traverse_3", "traverse_4"}) {
        s << t << ".ceiling_camera.pose_x_m = 0.8\n"
          << t << ".ceiling_camera.pose_z_m = 2.8\n"
          << t << ".world.mesh_fraction = 0.5\n"
          << t << ".world.shotcrete_fraction = 0.4\n"
          << t << ".world.pipe_offset_m = 1.2\n"
          << t << ".world.light_spacing_m = 0\n";
    }
    return s.str();
}

const lookup::eval::MethodResult& secondDrive(const JobResult& job) {
    for (const auto& r : job.rows) {
        if (r.traverse == "second-drive" && r.method != "coarse") return r;
    }
    throw std::runtime_error(job.condition + ": no second-drive row");
}

}  // namespace

TEST(RefreshPipeline, ASecondDriveOverAChangedCeilingGainsFromTheRefreshedDatabase) {
    const fs::path dir = fs::temp_directory_path() / "lookup_refresh_pipeline";
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "refresh.ini") << "[suite]\nname = refresh\nseeds = 2\n"
                                       << "localize_ini = localize-mine-b.ini\n\n"
                                       << "[condition.surveyed-only]\npreset = mine-b-mini\n"
                                       << changedDay(false) << "\n"
                                       << "[condition.refreshed]\npreset = mine-b-mini\n"
                                       << changedDay(true);
    auto suite = SuiteOptions::fromFile((dir / "refresh.ini").string(), {LOOKUP_SOURCE_SHARE_DIR});
    suite.threads_per_job = 1;
    std::ostringstream log;
    const auto results = runSuite(suite, (dir / "out").string(), 2, log);
    ASSERT_EQ(results.size(), 2u) << log.str();
    for (const auto& r : results) ASSERT_TRUE(r.ok) << r.condition << ": " << r.reason;
    const auto& before = secondDrive(results[0]);
    const auto& after = secondDrive(results[1]);
    EXPECT_TRUE(fs::is_directory(dir / "out" / "jobs" / "refreshed" / "seed-2" / "db-zigzag"));
    EXPECT_GE(after.acceptance_share, before.acceptance_share + 0.05);
    EXPECT_LT(after.error.p95_m, before.error.p95_m);
    EXPECT_LT(after.error.mean_m, 0.08);
    EXPECT_EQ(before.confident_wrong, 0u);
    EXPECT_EQ(after.confident_wrong, 0u);
}

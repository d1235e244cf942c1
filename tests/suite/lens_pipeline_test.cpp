// Lens distortion and another camera through the whole pipeline (lookup-sim -> survey with
// laser-derived references and its own ceiling height -> localise -> evaluate) on a 30 m mine:
// a strong barrel lens and a fisheye on every traverse, and a query camera with a 10 % longer
// focal length and a barrel lens the survey's camera does not have. Each must refine about as
// many frames as the pinhole mine, about as accurately.
#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "lookup/suite/suite.h"

namespace fs = std::filesystem;
using namespace lookup::suite;

TEST(LensPipeline, BarrelFisheyeAndAnotherQueryCameraRefineLikeAPinholeMine) {
    const fs::path dir = fs::temp_directory_path() / "lookup_lens_pipeline";
    fs::remove_all(dir);
    fs::create_directories(dir);
    std::ofstream(dir / "lens.ini") << R"([suite]
name = lens
seeds = 6
localize_ini = localize-mine-b.ini
max_frames = 60

[condition.ideal]
preset = mine-b-mini
world.length_m = 30

[condition.barrel]
preset = mine-b-mini
world.length_m = 30
ceiling_camera.distortion = plumb_bob
ceiling_camera.dist_k1 = -0.40
ceiling_camera.dist_k2 = 0.12
ceiling_camera.dist_p1 = 0.0005
ceiling_camera.dist_p2 = -0.0005

[condition.fisheye]
preset = mine-b-mini
world.length_m = 30
ceiling_camera.distortion = kannala_brandt
ceiling_camera.hfov_deg = 140
ceiling_camera.dist_k1 = 0.01
ceiling_camera.dist_k2 = -0.005
ceiling_camera.dist_k3 = 0.002
ceiling_camera.dist_k4 = -0.001

[condition.other-query-camera]
preset = mine-b-mini
world.length_m = 30
traverse_3.ceiling_camera.hfov_deg = 89.55
traverse_3.ceiling_camera.distortion = plumb_bob
traverse_3.ceiling_camera.dist_k1 = -0.30
traverse_3.ceiling_camera.dist_k2 = 0.09
)";
    auto suite = SuiteOptions::fromFile((dir / "lens.ini").string(), {LOOKUP_SOURCE_SHARE_DIR});
    suite.threads_per_job = 1;
    std::ostringstream log;
    const auto results = runSuite(suite, (dir / "out").string(), 2, log);
    ASSERT_EQ(results.size(), 4u) << log.str();
    for (const auto& r : results) ASSERT_TRUE(r.ok) << r.condition << ": " << r.reason;
    const auto s = summarizeConditions(suite, results);
    ASSERT_EQ(s.size(), 4u);
    const auto& ideal = s[0];
    ASSERT_EQ(ideal.runs, 1u);
    ASSERT_GT(ideal.refined_share, 0.3);
    for (std::size_t i = 1; i < s.size(); ++i) {
        SCOPED_TRACE(s[i].condition);
        EXPECT_EQ(s[i].runs, 1u);
        EXPECT_GE(s[i].refined_share, ideal.refined_share - 0.10);
        EXPECT_LE(s[i].mean_m, std::max(1.5 * ideal.mean_m, ideal.mean_m + 0.02));
        EXPECT_EQ(s[i].confident_wrong, 0u);
    }
}

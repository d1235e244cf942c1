#include <gtest/gtest.h>

#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <filesystem>

#include "../common/round_trip.h"
#include "lookup/coarse/options.h"
#include "lookup/common/config.h"
#include "lookup/localize/localizer_options.h"
#include "lookup/refine/options.h"
#include "lookup/test/support.h"

using namespace lookup;

namespace {
const std::string kShare = LOOKUP_SOURCE_SHARE_DIR;
}

// The per-mine files lookup-localize --ini reads must load strictly (a typo in a key is an
// error, not a silent default) and carry the values they document: the shared settings from
// their base, localize.ini, and their own matcher sizes; the calibrated suite's vehicles add
// only their clocks to them.
TEST(LocalizeIni, PerMineFilesLoadStrictly) {
    for (const auto& [file, search, patch] :
         {std::tuple{"localize-mine-a.ini", 40, 40}, std::tuple{"localize-mine-b.ini", 70, 60},
          std::tuple{"suites/calibrated/localize-mine-a-real.ini", 40, 40},
          std::tuple{"suites/calibrated/localize-mine-b-real.ini", 70, 60},
          std::tuple{"suites/calibrated/localize-mine-b-offsets.ini", 70, 60}}) {
        const auto ini = common::loadIniFile(kShare + "/" + file);
        localize::LocalizerOptions lo;
        ASSERT_NO_THROW(lo.loadFromConfigFile(*ini, "localizer")) << file;
        EXPECT_NO_THROW(lo.check()) << file;
        refine::RefinerOptions ro;
        ASSERT_NO_THROW(ro.loadFromConfigFile(*ini, "refine")) << file;
        EXPECT_NO_THROW(ro.check()) << file;
        EXPECT_EQ(ro.matcher.search_range_px, search) << file;
        EXPECT_EQ(ro.matcher.patch_px, patch) << file;
        EXPECT_DOUBLE_EQ(ro.acceptance.min_inlier_share, 0.45) << file;
        EXPECT_DOUBLE_EQ(ro.acceptance.min_inlier_share_tracked, 0.3) << file;
        EXPECT_LT(ro.estimator.tilt_sigma_deg, 1.0) << file;
        EXPECT_DOUBLE_EQ(ro.matcher.max_contrast_gain, 64.0) << file;
        EXPECT_EQ(ini->sectionExists("time_offsets"), std::string(file).find("suites/") == 0)
            << file;
    }
}

TEST(LocalizeIni, AcquisitionKeysRoundTripAndAreChecked) {
    localize::LocalizerOptions o;
    o.acquisition_ambiguity_margin = 0.25;
    o.acquisition_ambiguity_distance_m = 2.5;
    o.coarse_while_tracking = false;
    mrpt::config::CConfigFileMemory mem;
    o.saveToConfigFile(mem, "localizer");
    localize::LocalizerOptions back;
    back.loadFromConfigFile(mem, "localizer");
    EXPECT_DOUBLE_EQ(back.acquisition_ambiguity_margin, 0.25);
    EXPECT_DOUBLE_EQ(back.acquisition_ambiguity_distance_m, 2.5);
    EXPECT_FALSE(back.coarse_while_tracking);

    back.acquisition_ambiguity_margin = 1.5;
    try {
        back.check();
        FAIL() << "a margin of 1.5 was accepted";
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("acquisition_ambiguity_margin"), std::string::npos)
            << e.what();
    }
}

// A slip bound at or under the gate would leave no step the ceiling could take.
TEST(LocalizeIni, TheCeilingOdometrysSlipBoundsAreChecked) {
    localize::LocalizerOptions o;
    o.ceiling_odometry_max_slip = o.ceiling_odometry_min_slip;
    try {
        o.check();
        FAIL() << "a max slip equal to the min slip was accepted";
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("ceiling_odometry_max_slip"), std::string::npos)
            << e.what();
    }
    o.ceiling_odometry_max_slip = 0.5;
    EXPECT_NO_THROW(o.check());
}

TEST(LocalizeIni, TheLensToleranceStaysUnderWhatCountsAsDirt) {
    localize::LocalizerOptions o;
    o.lens.dirty_transmission = 0.9;
    o.lens.tolerance = 0.1;  // nothing could be found dirty
    try {
        o.check();
        FAIL() << "a tolerance that hides every blotch was accepted";
    } catch (const common::ConfigError& e) {
        EXPECT_NE(std::string(e.what()).find("lens_tolerance"), std::string::npos) << e.what();
    }
    o.lens.tolerance = 0.05;
    EXPECT_NO_THROW(o.check());
}

TEST(LocalizeIni, CoarseModeIsOneOfItsNames) {
    mrpt::config::CConfigFileMemory mem;
    mem.write("localizer", "coarse", "ceiling");
    localize::LocalizerOptions o;
    o.loadFromConfigFile(mem, "localizer");
    EXPECT_EQ(o.coarse, localize::CoarseMode::Ceiling);
    mem.write("localizer", "coarse", "forward");
    try {
        o.loadFromConfigFile(mem, "localizer");
        FAIL() << "coarse = forward was accepted";
    } catch (const common::ConfigError& e) {
        const std::string what = e.what();
        EXPECT_NE(what.find("coarse"), std::string::npos) << what;
        EXPECT_NE(what.find("sequence"), std::string::npos) << what;  // the names allowed
    }
}

// MRPT's TCLAP reports a parse error by returning false, not by exiting: every app must stop
// with a non-zero status on an unknown flag instead of running with half-parsed options.
TEST(AppCommandLines, UnknownFlagFailsAndHelpSucceeds) {
    const auto log = lookup::test::freshDir("options_app_command_lines") / "log.txt";
    for (const char* app :
         {"lookup-localize", "lookup-eval", "lookup-sim", "lookup-survey", "lookup-coarse"}) {
        EXPECT_NE(lookup::test::runProgram(app, {"--no-such-flag"}, log), 0) << app;
        EXPECT_EQ(lookup::test::runProgram(app, {"--help"}, log), 0) << app;
    }
}

// Save then load gives the same options, for every struct lookup-localize reads.
TEST(LocalizeIni, EveryOptionsStructRoundTrips) {
    localize::LocalizerOptions lo;
    lo.coarse = localize::CoarseMode::Ceiling;
    lo.use_tracking = false;
    lo.max_latency_s = 1.0 / 3.0;
    lo.image_cache_capacity = 77;
    options_testing::expectRoundTrip(lo, "localizer");
    refine::RefinerOptions ro = refine::RefinerOptions::mineB();
    ro.sampler.mode = refine::SamplingMode::HeatMap;
    ro.matcher.subpixel = refine::SubpixelMethod::Parabola;
    ro.matcher.use_simd = false;
    ro.homography.ransac_confidence = 0.9;
    ro.estimator.pixel_sigma_px = 0.1;
    ro.acceptance.max_offset_m = 2.5;
    ro.correspondence.method = refine::CorrespondenceMethod::Ecc;
    ro.correspondence.ecc_epsilon = 3e-7;
    options_testing::expectRoundTrip(ro, "refine");
    coarse::CoarseOptions co;
    co.camera_label = "FRONT";
    co.use_odometry = false;
    co.velocity_max = 2.75;
    options_testing::expectRoundTrip(co, "coarse");
}

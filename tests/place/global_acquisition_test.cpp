#include <mrpt/obs/CObservationOdometry.h>

#include <nlohmann/json.hpp>

#include "lookup/localize/localize_app.h"
#include "lookup/localize/localizer.h"
#include "place_fixture.h"

namespace lookup::place_testing {
namespace {

using localize::FrameStatus;
using mrpt::poses::CPose3D;

/// A localiser on the fixture's database with its place index and no forward camera.
struct CeilingOnly {
    database::ReferenceDatabase db;
    place::PlaceIndex index;
    std::unique_ptr<localize::Localizer> localizer;
    double t = localize_testing::kT0;

    explicit CeilingOnly(const fs::path& dir, int check_every = 10)
        : db(database::ReferenceDatabase::load((dir / "db").string())),
          index(place::PlaceIndex::load((dir / "db" / place::kPlaceIndexFile).string(), db,
                                        place::PlaceIndexOptions())) {
        localize::LocalizerOptions o;
        o.coarse = localize::CoarseMode::Ceiling;
        o.place_check_every = check_every;
        refine::RefinerOptions r;
        r.sampler.mode = refine::SamplingMode::Grid;
        localizer = std::make_unique<localize::Localizer>(db, o, r, nullptr, false);
        localizer->setPlaceIndex(&index);
    }
    /// Odometry, then the ceiling frame, at `vehicle`; the frame's result.
    localize::FrameResult drive(const localize_testing::Scene& scene, const CPose3D& vehicle) {
        t += 0.1;
        auto odo = mrpt::obs::CObservationOdometry::Create();
        odo->sensorLabel = "ODOMETRY";
        odo->timestamp = mrpt::Clock::fromDouble(t - 0.001);
        odo->odometry = mrpt::poses::CPose2D(vehicle.x(), vehicle.y(), vehicle.yaw());
        localizer->process(odo);
        return *localizer->process(scene.image(vehicle, t));
    }
};

double errorOf(const localize::FrameResult& f, const CPose3D& truth) {
    return std::hypot(f.pose.mean.x() - truth.x(), f.pose.mean.y() - truth.y());
}

TEST(GlobalAcquisition, FirstFixWithinThreeFramesFromAColdStartAnywhereInEitherDirection) {
    const auto dir = lookup::test::freshDir("lookup_localize_global_cold_starts");
    const auto scene = sceneWithDatabase(dir);
    CeilingOnly run(dir);
    int starts = 0, fixed = 0;
    for (double x0 : {-6.0, -2.5, 1.0, 4.5}) {
        for (double yaw : {0.1, M_PI - 0.1}) {
            run.localizer->restart();  // a kidnapping: nothing is known of the last place
            ++starts;
            for (int k = 0; k < 3; ++k) {
                const CPose3D vehicle(x0 + 0.3 * k * std::cos(yaw), 0.25, 0, yaw, 0, 0);
                const auto f = run.drive(scene, vehicle);
                if (f.status != FrameStatus::Refined) continue;
                EXPECT_LT(errorOf(f, vehicle), 0.05) << "start x " << x0 << " yaw " << yaw;
                ++fixed;
                break;
            }
        }
    }
    EXPECT_EQ(fixed, starts);
}

TEST(GlobalAcquisition, ARepeatingCeilingIsAmbiguousNeverAConfidentPlace) {
    const auto dir = lookup::test::freshDir("lookup_localize_global_periodic");
    const auto scene = sceneWithDatabase(dir, 4.0);
    CeilingOnly run(dir);
    int ambiguous = 0;
    for (int k = 0; k < 12; ++k) {
        const CPose3D vehicle(-3 + 0.3 * k, 0.2, 0, 0.05, 0, 0);
        const auto f = run.drive(scene, vehicle);
        ambiguous += f.status == FrameStatus::Ambiguous;
        EXPECT_FALSE(f.has_pose && errorOf(f, vehicle) > 0.5) << "frame " << k << " " << f.reason;
    }
    EXPECT_GT(ambiguous, 6);
}

TEST(GlobalAcquisition, ATrackOnAnAliasedPlaceIsDroppedByTheCheck) {
    const auto dir = lookup::test::freshDir("lookup_localize_global_track_check");
    const auto scene = sceneWithDatabase(dir, 4.0);
    CeilingOnly run(dir, /*check_every=*/1);
    // Started one period off: the ceiling confirms the wrong place exactly.
    run.localizer->setInitialPose(run.t, mrpt::poses::CPose2D(-3 + 4.0, 0.2, 0.05));
    bool dropped = false;
    for (int k = 0; k < 3 && !dropped; ++k) {
        const auto f = run.drive(scene, CPose3D(-3 + 0.3 * k, 0.2, 0, 0.05, 0, 0));
        dropped = f.status == FrameStatus::Ambiguous && !f.has_pose;
    }
    EXPECT_TRUE(dropped);
}

TEST(GlobalAcquisition, KidnappingsAlongTheRouteAreCountedAndFixedFromTheCeilingAlone) {
    const auto dir = lookup::test::freshDir("lookup_localize_global_kidnap");
    auto req = localize_testing::planarRun(dir, [](int, auto&, auto&) {});
    const auto db = database::ReferenceDatabase::load(req.db_dir);
    place::PlaceIndex::build(db, place::PlaceIndexOptions())
        .save(req.db_dir + "/" + place::kPlaceIndexFile);
    req.coarse_poses.clear();  // no forward camera, no coarse file: the ceiling alone
    std::ofstream((dir / "ceiling.ini").string()) << "[localizer]\ncoarse = ceiling\n";
    req.ini_file = (dir / "ceiling.ini").string();
    req.kidnap_every = 5;
    localize::runLocalization(req);
    const auto timing = nlohmann::json::parse(std::ifstream(dir / "run" / "timing.json"));
    const auto& cold = timing.at("cold_starts");
    EXPECT_EQ(cold.at("count").get<int>(), 4);
    EXPECT_EQ(cold.at("fixed_within_3_frames").get<int>(), 4) << cold.dump();
}

TEST(GlobalAcquisition, CeilingOnlyRunsRefuseADatabaseWithoutItsIndex) {
    const auto dir = lookup::test::freshDir("lookup_localize_global_no_index");
    auto req = localize_testing::planarRun(dir, [](int, auto&, auto&) {});
    req.coarse_poses.clear();
    std::ofstream((dir / "ceiling.ini").string()) << "[localizer]\ncoarse = ceiling\n";
    req.ini_file = (dir / "ceiling.ini").string();
    try {
        localize::runLocalization(req);
        ADD_FAILURE() << "ran without a place index";
    } catch (const std::exception& e) {
        EXPECT_NE(std::string(e.what()).find("place_index.bin: no place index"), std::string::npos)
            << e.what();
    }
    EXPECT_FALSE(fs::exists(dir / "run" / "frames.csv"));
}

}  // namespace
}  // namespace lookup::place_testing

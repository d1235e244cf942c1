#pragma once
// A synthetic database with its place index, and queries anywhere along it at any heading.

#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "../localize/localize_fixture.h"
#include "lookup/database/reference_database.h"
#include "lookup/place/place_index.h"

namespace lookup::place_testing {
using localize_testing::fs::path;
namespace fs = std::filesystem;

/// The fixture's database (65 references along y = 0 from x = -8) and its index in
/// `dir`/db; with `period_m` > 0 the ceiling repeats along x with that period.
inline localize_testing::Scene sceneWithDatabase(const fs::path& dir, double period_m = 0) {
    localize_testing::Scene scene;
    if (period_m > 0) {
        auto& c = scene.ceiling;
        const int period_px = static_cast<int>(std::lround(period_m / c.metres_per_px));
        for (int x = period_px; x < c.texture.cols; ++x) {
            c.texture.col(x % period_px).copyTo(c.texture.col(x));
        }
    }
    localize_testing::writeDatabase(scene, (dir / "db").string(), {{"survey", 65, 100.0}});
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    place::PlaceIndex::build(db, place::PlaceIndexOptions())
        .save((dir / "db" / place::kPlaceIndexFile).string());
    return scene;
}

}  // namespace lookup::place_testing

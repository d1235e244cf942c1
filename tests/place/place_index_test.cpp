#include <zlib.h>

#include <cstring>
#include <fstream>
#include <functional>

#include "lookup/place/place_pose.h"
#include "place_fixture.h"

namespace lookup::place_testing {
namespace {

using mrpt::poses::CPose3D;

cv::Mat grey(const mrpt::obs::CObservationImage& obs) {
    return obs.image.asCvMat<cv::Mat>(mrpt::img::SHALLOW_COPY);
}

struct Located {
    bool found = false;
    double error_m = 1e9, yaw_error_deg = 1e9;
};

// The index's best place for the vehicle's ceiling view, as the camera saw it (`seen` changes
// the image, e.g. its light; identity when empty), with the whole scene on `grade` (the
// references' poses and the vehicle's moved onto it, the images as they are).
Located locate(const place::PlaceIndex& index, const database::ReferenceDatabase& db,
               const localize_testing::Scene& scene, const CPose3D& vehicle,
               const std::function<cv::Mat(const cv::Mat&)>& seen = {}, const CPose3D& grade = {}) {
    const auto obs = scene.image(vehicle, 0);
    const auto candidates = index.query(seen ? seen(grey(*obs)) : grey(*obs), nullptr,
                                        place::expectedPixelScale(db, {scene.camera, scene.mount}));
    Located out;
    if (candidates.empty()) return out;
    const auto& c = candidates.front();
    const auto& ref = db.reference(c.reference);
    const auto pose = place::vehiclePose(
        c, db.info().ceiling_camera, grade + ref.vehicle_pose, ref.ceiling_camera_mount,
        {scene.camera, scene.mount}, db.info().ceiling_height_m, index.options().max_scale_change);
    if (!pose) return out;
    const mrpt::poses::CPose2D truth(grade + vehicle);
    out.found = true;
    out.error_m = std::hypot(pose->x() - truth.x(), pose->y() - truth.y());
    out.yaw_error_deg = std::abs(mrpt::RAD2DEG(mrpt::math::wrapToPi(pose->phi() - truth.phi())));
    return out;
}

// Of the vehicle poses every metre from x = -7 to 7 m at headings 0, 90 and 180 deg (kTried),
// how many the index places within 0.15 m from the image as `seen` changes it.
constexpr int kTried = 15 * 3;
int placedRight(const place::PlaceIndex& index, const database::ReferenceDatabase& db,
                const localize_testing::Scene& scene,
                const std::function<cv::Mat(const cv::Mat&)>& seen) {
    int right = 0;
    for (double x = -7; x <= 7; x += 1.0) {
        for (double yaw_deg : {0.0, 90.0, 180.0}) {
            const CPose3D vehicle(x, 0.2, 0, mrpt::DEG2RAD(yaw_deg), 0, 0);
            const auto r = locate(index, db, scene, vehicle, seen);
            if (r.found && r.error_m < 0.15) ++right;
        }
    }
    return right;
}

TEST(PlaceIndex, FindsThePlaceAnywhereAtAnyHeadingFromOneImage) {
    const auto dir = lookup::test::freshDir("lookup_localize_place_any_heading");
    const auto scene = sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const auto index = place::PlaceIndex::load((dir / "db" / place::kPlaceIndexFile).string(), db,
                                               place::PlaceIndexOptions());
    EXPECT_LT(index.indexedReferences(), db.size());  // thinned along the traverse
    int right = 0, tried = 0;
    for (double x = -7; x <= 7; x += 1.75) {
        for (double yaw_deg : {0.0, 35.0, 90.0, 180.0, -120.0}) {
            const CPose3D vehicle(x, 0.3, 0, mrpt::DEG2RAD(yaw_deg), 0, 0);
            const auto r = locate(index, db, scene, vehicle);
            ++tried;
            // Features only: the SAD refinement takes it to centimetres.
            if (r.found && r.error_m < 0.15 && r.yaw_error_deg < 2) ++right;
        }
    }
    EXPECT_GE(right, tried * 95 / 100) << right << " of " << tried;
}

TEST(PlaceIndex, AQueryCameraAtAnotherHeightIsPlacedThroughItsMount) {
    // Mounted 1.1 m higher than the survey's, the camera has the ceiling 2.4 m away instead of
    // 3.5 m and sees it 1.46 times larger in pixels: the query is detected at the references'
    // scale, and a candidate is judged by the two views' sizes in metres on the ceiling.
    const auto dir = lookup::test::freshDir("lookup_localize_place_other_height");
    const auto survey = sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const auto index = place::PlaceIndex::load((dir / "db" / place::kPlaceIndexFile).string(), db,
                                               place::PlaceIndexOptions());
    localize_testing::Scene higher = survey;
    higher.mount = CPose3D(0, 0, 2.6, 0, 0, 0);
    int right = 0, tried = 0, misplaced = 0;
    for (double x = -7; x <= 7; x += 1.75) {
        for (double yaw_deg : {0.0, 90.0, 180.0}) {
            const CPose3D vehicle(x, 0.3, 0, mrpt::DEG2RAD(yaw_deg), 0, 0);
            const auto r = locate(index, db, higher, vehicle);
            ++tried;
            if (r.found && r.error_m < 0.15 && r.yaw_error_deg < 2) ++right;
            // The same images with the survey's mount reported: no height explains the scale.
            const place::QueryCamera misreported{higher.camera, survey.mount};
            misplaced += static_cast<int>(
                place::placeQuery(index, db, misreported, grey(*higher.image(vehicle, 0))).size());
        }
    }
    EXPECT_GE(right, tried * 90 / 100) << right << " of " << tried;
    EXPECT_EQ(misplaced, 0);
}

// The query under other light: the tunnel lamps off, only the vehicle's cone lighting the
// middle of the view, a darker exposure.
cv::Mat underOtherLight(const cv::Mat& image) {
    cv::Mat out(image.size(), CV_8UC1);
    const double cx = 0.5 * image.cols, cy = 0.5 * image.rows;
    for (int v = 0; v < image.rows; ++v) {
        for (int u = 0; u < image.cols; ++u) {
            const double r2 = ((u - cx) * (u - cx) + (v - cy) * (v - cy)) / (cx * cx);
            const double light = 0.12 + 0.5 * std::exp(-1.5 * r2);
            out.at<uchar>(v, u) = cv::saturate_cast<uchar>(image.at<uchar>(v, u) * light);
        }
    }
    return out;
}

TEST(PlaceIndex, AReferenceOnAGradePlacesTheVehicleOnItsFloor) {
    // The database's scene moved as a whole 5 m down onto an 8 deg grade (3-D surveyed
    // references down a decline, the ceiling following the floor): the same images, so the
    // same places, moved likewise. Taken as the horizontal plane z = h of the map, the ceiling
    // lay 5 m further from the references than it is.
    const auto dir = lookup::test::freshDir("lookup_localize_place_grade");
    const auto scene = sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const auto index = place::PlaceIndex::load((dir / "db" / place::kPlaceIndexFile).string(), db,
                                               place::PlaceIndexOptions());
    const CPose3D grade(3.0, -2.0, -5.0, 0.4, mrpt::DEG2RAD(8.0), mrpt::DEG2RAD(0.5));
    int right = 0, tried = 0;
    for (double x = -6; x <= 6; x += 3.0) {
        for (double yaw_deg : {0.0, 180.0}) {
            const CPose3D vehicle(x, 0.3, 0, mrpt::DEG2RAD(yaw_deg), 0, 0);
            const auto r = locate(index, db, scene, vehicle, {}, grade);
            ++tried;
            if (r.found && r.error_m < 0.15 && r.yaw_error_deg < 2) ++right;
        }
    }
    EXPECT_GE(right, tried * 9 / 10) << right << " of " << tried;
}

TEST(PlaceIndex, FindsThePlaceUnderOtherLightOnTheIlluminationFreeImage) {
    const auto dir = lookup::test::freshDir("lookup_localize_place_other_light");
    const auto scene = sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    place::PlaceIndexOptions raw;
    raw.illumination_sigma_px = 0;
    const auto on_texture = place::PlaceIndex::build(db, place::PlaceIndexOptions());
    const auto on_raw = place::PlaceIndex::build(db, raw);
    const int right = placedRight(on_texture, db, scene, underOtherLight);
    const int right_raw = placedRight(on_raw, db, scene, underOtherLight);
    EXPECT_GE(right, kTried * 9 / 10) << right << " of " << kTried;
    EXPECT_GT(right, right_raw) << "raw image: " << right_raw << " of " << kTried;
}

// The query from a camera under a lamp 16 times dimmer: a sixteenth of the light, the same
// read noise.
cv::Mat underADimLamp(const cv::Mat& image) {
    cv::Mat light, noise(image.size(), CV_32F), out;
    image.convertTo(light, CV_32F, 1.0 / 16);
    cv::RNG(7).fill(noise, cv::RNG::NORMAL, 0, 1.2);
    cv::Mat(light + noise).convertTo(out, CV_8U);
    return out;
}

TEST(PlaceIndex, FindsThePlaceInADimNoisyImageSmoothedBeforeDetection) {
    const auto dir = lookup::test::freshDir("lookup_localize_place_dim");
    const auto scene = sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    place::PlaceIndexOptions unsmoothed;
    unsmoothed.noisy_texture_to_noise = 0;
    const auto smoothed = place::PlaceIndex::build(db, place::PlaceIndexOptions());
    const auto as_before = place::PlaceIndex::build(db, unsmoothed);
    const int right = placedRight(smoothed, db, scene, underADimLamp);
    const int right_before = placedRight(as_before, db, scene, underADimLamp);
    EXPECT_GE(right, kTried * 9 / 10) << right << " of " << kTried;
    EXPECT_GT(right, right_before) << "unsmoothed: " << right_before << " of " << kTried;
}

TEST(PlaceIndex, NoCandidateOnAnImageWithoutTexture) {
    const auto dir = lookup::test::freshDir("lookup_localize_place_flat");
    sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const auto index = place::PlaceIndex::load((dir / "db" / place::kPlaceIndexFile).string(), db,
                                               place::PlaceIndexOptions());
    cv::Mat flat(240, 320, CV_8UC1, cv::Scalar(128));
    cv::RNG(3).fill(flat, cv::RNG::NORMAL, 128, 2);  // sensor noise on a uniform ceiling
    EXPECT_TRUE(index.query(flat).empty());
}

std::string errorOf(const std::string& file, const database::ReferenceDatabase& db) {
    try {
        place::PlaceIndex::load(file, db, place::PlaceIndexOptions());
    } catch (const place::PlaceIndexError& e) {
        return e.what();
    }
    return "";
}

TEST(PlaceIndex, DamagedForeignOrMissingIndexFilesAreRefusedNamingTheFile) {
    const auto dir = lookup::test::freshDir("lookup_localize_place_bad_files");
    sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const std::string good = (dir / "db" / place::kPlaceIndexFile).string();
    std::ifstream in(good, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    const auto writeCopy = [&](const std::string& name, const std::string& content) {
        const std::string p = (dir / name).string();
        std::ofstream(p, std::ios::binary) << content;
        return p;
    };
    const std::string truncated = writeCopy("truncated.bin", bytes.substr(0, bytes.size() / 2));
    std::string flipped_bytes = bytes;
    flipped_bytes[flipped_bytes.size() / 3] ^= 0x20;
    const std::string flipped = writeCopy("flipped.bin", flipped_bytes);
    const std::string garbage = writeCopy("garbage.bin", "not an index at all");
    for (const auto& [file, why] : {std::pair{truncated, "CRC"},
                                    {flipped, "CRC"},
                                    {garbage, "not a LookUP place index"},
                                    {(dir / "missing.bin").string(), "cannot open"}}) {
        const std::string e = errorOf(file, db);
        EXPECT_NE(e.find(file), std::string::npos) << e;
        EXPECT_NE(e.find(why), std::string::npos) << e;
    }
    // Another database (the same ceiling, surveyed 0.1 m to the side).
    localize_testing::Scene scene;
    localize_testing::writeDatabase(scene, (dir / "other").string(),
                                    {{"survey", 65, 100.0, 0, 0.1}});
    const auto other = database::ReferenceDatabase::load((dir / "other").string());
    const std::string e = errorOf(good, other);
    EXPECT_NE(e.find("another database"), std::string::npos) << e;
}

// `bytes` of an index file with its format version replaced and its CRC-32 made right again.
std::string withFormatVersion(std::string bytes, std::uint32_t version) {
    std::memcpy(&bytes[8], &version, sizeof version);  // after the 8-byte magic
    const std::size_t payload = bytes.size() - 4;
    const auto crc = static_cast<std::uint32_t>(
        crc32(0L, reinterpret_cast<const Bytef*>(bytes.data()), static_cast<uInt>(payload)));
    std::memcpy(&bytes[payload], &crc, sizeof crc);
    return bytes;
}

TEST(PlaceIndex, AnIndexOfAnEarlierFormatIsQueriedAsItWasBuilt) {
    const auto dir = lookup::test::freshDir("lookup_localize_place_format");
    sceneWithDatabase(dir);
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    const std::string file = (dir / "db" / place::kPlaceIndexFile).string();
    std::ifstream in(file, std::ios::binary);
    const std::string bytes((std::istreambuf_iterator<char>(in)), {});
    const auto load = [&](std::uint32_t version) {
        const std::string copy = (dir / ("v" + std::to_string(version) + ".bin")).string();
        std::ofstream(copy, std::ios::binary) << withFormatVersion(bytes, version);
        return place::PlaceIndex::load(copy, db, place::PlaceIndexOptions());
    };
    // Format 2 detected every image without smoothing a noisy one: its queries must too.
    EXPECT_EQ(load(2).options().noisy_texture_to_noise, 0.0);
    EXPECT_GT(load(3).options().noisy_texture_to_noise, 0.0);
    EXPECT_EQ(load(1).options().illumination_sigma_px, 0.0);
    try {
        load(4);
        ADD_FAILURE() << "a newer format was read";
    } catch (const place::PlaceIndexError& e) {
        EXPECT_NE(std::string(e.what()).find("format version 4"), std::string::npos) << e.what();
    }
}

TEST(PlaceIndex, BuildingTheIndexLeavesTheReferencesUntouched) {
    const auto dir = lookup::test::freshDir("lookup_localize_place_untouched");
    localize_testing::Scene scene;
    localize_testing::writeDatabase(scene, (dir / "db").string(), {{"survey", 20, 100.0}});
    const auto before = fs::last_write_time(dir / "db" / "refs.rawlog");
    const auto db = database::ReferenceDatabase::load((dir / "db").string());
    place::PlaceIndex::build(db, place::PlaceIndexOptions())
        .save((dir / "db" / place::kPlaceIndexFile).string());
    EXPECT_EQ(fs::last_write_time(dir / "db" / "refs.rawlog"), before);
    // The database still verifies (its manifest does not list the index).
    EXPECT_NO_THROW(database::ReferenceDatabase::load((dir / "db").string()));
}

}  // namespace
}  // namespace lookup::place_testing

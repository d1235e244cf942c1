// Every reference keeps its own ceiling-camera intrinsics (another camera, another vehicle);
// databases written before that (version 0 of CObservationLookupReference) still load, their
// references taking db.ini's [ceiling_camera].
#include <gtest/gtest.h>
#include <mrpt/io/CFileOutputStream.h>
#include <mrpt/io/CMemoryStream.h>
#include <mrpt/serialization/CArchive.h>

#include <filesystem>
#include <limits>

#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"
#include "lookup/database/manifest.h"
#include "lookup/database/reference_database.h"
#include "lookup/obs/observation_lookup_reference.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using namespace lookup::database;

namespace {

mrpt::img::TCamera camera(double f, bool barrel) {
    mrpt::img::TCamera c;
    c.ncols = 16;
    c.nrows = 12;
    c.setIntrinsicParamsFromValues(f, f, 7.5, 5.5);
    if (barrel) {
        c.setDistortionPlumbBob(-0.3, 0.09, 0.0005, -0.0005);
    } else {
        c.setDistortionPlumbBob(0, 0, 0, 0);
        c.distortion = mrpt::img::DistortionModel::none;
    }
    return c;
}

ReferenceInput input(int i, const mrpt::img::TCamera& cam) {
    ReferenceInput in;
    in.traverse = "a";
    in.ceiling = mrpt::obs::CObservationImage::Create();
    in.ceiling->sensorLabel = "CEILING_CAM";
    in.ceiling->timestamp = mrpt::Clock::fromDouble(100.0 + i);
    in.ceiling->cameraPose = mrpt::poses::CPose3D(0.5, 0, 2, 0, 0, 0);
    in.ceiling->cameraParams = cam;
    in.ceiling->image.resize(16, 12, mrpt::img::CH_GRAY);
    in.ceiling->image.filledRectangle(0, 0, 15, 11, mrpt::img::TColor(i, i, i));
    in.vehicle_pose = mrpt::poses::CPose3D(i, 0, 0, 0, 0, 0);
    in.vehicle_cov.setIdentity();
    return in;
}

// References 0-2 from an ideal camera, 3-5 from another vehicle's barrel lens.
void writeTwoCameras(const fs::path& out) {
    DatabaseWriter w(out.string());
    for (int i = 0; i < 6; ++i) w.add(input(i, camera(i < 3 ? 20.0 : 22.0, i >= 3)));
    DatabaseInfo info;
    info.name = "two cameras";
    info.ceiling_camera = camera(20.0, false);
    info.ceiling_height_m = 4.5;
    w.commit(info);
}

// The bytes of `record` as version 0 wrote them: without the trailing has_ceiling_camera and
// ceiling_camera (version 1) nor source and superseded_by (version 2), version byte 0 (MRPT:
// name-length byte, class name, version, data, end flag).
std::vector<uint8_t> versionZeroBytes(const lookup::obs::CObservationLookupReference& record) {
    const auto bytes = [](const auto& write) {
        mrpt::io::CMemoryStream m;
        auto a = mrpt::serialization::archiveFrom(m);
        write(a);
        const auto* p = static_cast<const uint8_t*>(m.getRawBufferData());
        return std::vector<uint8_t>(p, p + m.getTotalBytesCount());
    };
    auto all = bytes([&](auto& a) { a << record; });
    const auto tail = bytes([&](auto& a) {
        a << record.has_ceiling_camera << record.ceiling_camera << record.source
          << record.superseded_by;
    });
    const std::size_t name_length = all.at(0) & 0x7F;
    EXPECT_EQ(all.at(1 + name_length), 2) << "version byte not where expected";
    all.at(1 + name_length) = 0;
    all.erase(all.end() - 1 - std::ptrdiff_t(tail.size()), all.end() - 1);
    return all;
}

// Rewrites refs.rawlog with every LOOKUP_REF record in version 0 (uncompressed: MRPT's gz
// reader reads plain files too) and the manifest over the new file.
void downgradeToVersionZero(const fs::path& db) {
    const std::string path = (db / kRefsRawlog).string();
    std::vector<std::vector<uint8_t>> records;
    {
        lookup::common::RawlogReader reader(path);
        mrpt::obs::CObservation::Ptr o;
        while (reader.next(o)) {
            mrpt::io::CMemoryStream m;
            auto a = mrpt::serialization::archiveFrom(m);
            if (auto rec = std::dynamic_pointer_cast<lookup::obs::CObservationLookupReference>(o)) {
                rec->has_ceiling_camera = false;
                rec->ceiling_camera = mrpt::img::TCamera();
                records.push_back(versionZeroBytes(*rec));
                continue;
            }
            a << *o;
            const auto* p = static_cast<const uint8_t*>(m.getRawBufferData());
            records.emplace_back(p, p + m.getTotalBytesCount());
        }
    }
    mrpt::io::CFileOutputStream f(path);
    for (const auto& r : records) f.Write(r.data(), r.size());
    f.close();
    writeManifest(db.string());
}

}  // namespace

TEST(ReferenceCamera, EachReferenceKeepsItsOwnIntrinsicsAndDistortion) {
    const auto dir = lookup::test::freshDir("lookup_refcam_own");
    writeTwoCameras(dir / "db");
    const auto db = ReferenceDatabase::load((dir / "db").string());
    ASSERT_EQ(db.size(), 6u);
    for (std::size_t i = 0; i < 6; ++i) {
        const auto& c = db.reference(i).ceiling_camera;
        EXPECT_DOUBLE_EQ(c.fx(), i < 3 ? 20.0 : 22.0) << i;
        EXPECT_EQ(c.distortion == mrpt::img::DistortionModel::plumb_bob, i >= 3) << i;
        EXPECT_DOUBLE_EQ(c.k1(), i < 3 ? 0.0 : -0.3) << i;
        EXPECT_EQ(c.ncols, 16u);
    }
    EXPECT_DOUBLE_EQ(db.info().ceiling_camera.fx(), 20.0);
}

TEST(ReferenceCamera, AFinerCameraIsStoredAveragedDownWithItsIntrinsics) {
    const auto dir = lookup::test::freshDir("lookup_refcam_capped");
    // A 16x12 camera stored at most 8 px wide: half the size, focal length and principal point
    // (pixel centres: (7.5 + 0.5) / 2 - 0.5 = 3.5), the distortion as it was; the pixels are
    // the 2x2 means.
    mrpt::img::TCamera cam = camera(20.0, true);
    ReferenceInput in = input(0, cam);
    for (int y = 0; y < 12; ++y)
        for (int x = 0; x < 16; ++x) in.ceiling->image.setPixel(x, y, (x % 2) * 200);
    {
        DatabaseWriter w((dir / "db").string(), 8);
        w.add(in);
        DatabaseInfo info;
        info.name = "capped";
        info.ceiling_camera = cam;
        info.ceiling_height_m = 4.5;
        w.commit(info);
    }
    const auto db = ReferenceDatabase::load((dir / "db").string());
    ASSERT_EQ(db.size(), 1u);
    for (const auto& c : {db.reference(0).ceiling_camera, db.info().ceiling_camera}) {
        EXPECT_EQ(c.ncols, 8u);
        EXPECT_EQ(c.nrows, 6u);
        EXPECT_NEAR(c.fx(), 10.0, 1e-4);
        EXPECT_NEAR(c.fy(), 10.0, 1e-4);
        EXPECT_NEAR(c.cx(), 3.5, 1e-4);
        EXPECT_NEAR(c.cy(), 2.5, 1e-4);
        EXPECT_DOUBLE_EQ(c.k1(), -0.3);
    }
    const cv::Mat stored = db.ceilingImage(0);
    ASSERT_EQ(stored.cols, 8);
    ASSERT_EQ(stored.rows, 6);
    for (int y = 0; y < 6; ++y)
        for (int x = 0; x < 8; ++x) EXPECT_EQ(int(stored.at<uint8_t>(y, x)), 100) << x << "," << y;
    // Without a limit the image is stored as recorded.
    {
        DatabaseWriter w((dir / "as-recorded").string());
        w.add(in);
        DatabaseInfo info;
        info.ceiling_camera = cam;
        info.ceiling_height_m = 4.5;
        w.commit(info);
    }
    const auto full = ReferenceDatabase::load((dir / "as-recorded").string());
    EXPECT_EQ(full.ceilingImage(0).cols, 16);
    EXPECT_DOUBLE_EQ(full.info().ceiling_camera.fx(), 20.0);
}

TEST(ReferenceCamera, VersionZeroRecordsTakeTheDatabaseCamera) {
    const auto dir = lookup::test::freshDir("lookup_refcam_v0");
    writeTwoCameras(dir / "db");
    downgradeToVersionZero(dir / "db");
    const auto db = ReferenceDatabase::load((dir / "db").string());
    ASSERT_EQ(db.size(), 6u);
    for (std::size_t i = 0; i < 6; ++i) {
        const auto& c = db.reference(i).ceiling_camera;
        EXPECT_DOUBLE_EQ(c.fx(), 20.0) << i;
        EXPECT_DOUBLE_EQ(c.k1(), 0.0) << i;
        EXPECT_NEAR(db.reference(i).vehicle_pose.x(), double(i), 1e-12);
    }
}

TEST(ReferenceCamera, BadIntrinsicsAreRefusedNamingTheReference) {
    const auto dir = lookup::test::freshDir("lookup_refcam_bad");
    DatabaseWriter w((dir / "db").string());
    w.add(input(0, camera(20.0, false)));
    auto nan_dist = camera(20.0, true);
    nan_dist.dist[1] = std::numeric_limits<double>::quiet_NaN();
    auto unknown = camera(20.0, false);
    unknown.distortion = static_cast<mrpt::img::DistortionModel>(7);
    for (const auto& [cam, expected] :
         {std::pair{nan_dist, "dist[1]"}, std::pair{unknown, "not one MRPT knows"}}) {
        try {
            w.add(input(1, cam));
            ADD_FAILURE() << "accepted " << expected;
        } catch (const DatabaseError& e) {
            const std::string m = e.what();
            EXPECT_NE(m.find("reference 1"), std::string::npos) << m;
            EXPECT_NE(m.find(expected), std::string::npos) << m;
        }
    }
}

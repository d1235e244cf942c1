#include <gtest/gtest.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/obs/CObservationOdometry.h>

#include <filesystem>
#include <fstream>

#include "lookup/common/rawlog_io.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;
using lookup::common::RawlogError;
using lookup::common::RawlogReader;
using lookup::common::RawlogWriter;

namespace {

void writeSample(const std::string& path) {
    RawlogWriter w(path);
    for (int i = 0; i < 3; ++i) {
        mrpt::obs::CObservationImage img;
        img.sensorLabel = "CEILING_CAM";
        img.timestamp = mrpt::Clock::fromDouble(100.0 + i);
        img.image.resize(8, 6, mrpt::img::CH_GRAY);
        img.image.filledRectangle(0, 0, 7, 5, mrpt::img::TColor(10 * i, 10 * i, 10 * i));
        w.writeWithExternalImage(img, "CEILING_CAM_" + std::to_string(i) + ".png");
        mrpt::obs::CObservationOdometry odo;
        odo.sensorLabel = "ODOMETRY";
        odo.timestamp = img.timestamp;
        odo.odometry = mrpt::poses::CPose2D(i, 0, 0);
        w.write(odo);
    }
    w.close();
}
}  // namespace

TEST(Rawlog, RoundTripWithExternalImagesFromAbsolutePath) {
    const auto dir = lookup::test::freshDir("lookup_common_roundtrip");
    const std::string path = fs::absolute(dir / "traverse.rawlog").string();
    writeSample(path);
    ASSERT_TRUE(fs::exists(dir / "traverse_Images" / "CEILING_CAM_2.png"));
    ASSERT_FALSE(fs::exists(path + ".tmp"));

    RawlogReader r(path);
    mrpt::obs::CObservation::Ptr obs;
    int images = 0, odometry = 0;
    while (r.next(obs)) {
        if (auto img = std::dynamic_pointer_cast<mrpt::obs::CObservationImage>(obs)) {
            EXPECT_EQ(img->image.getWidth(), 8u);  // loads the external file
            EXPECT_EQ(*img->image.ptr<uint8_t>(3, 3), 10 * images);
            ++images;
        } else if (std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(obs)) {
            ++odometry;
        }
    }
    EXPECT_EQ(images, 3);
    EXPECT_EQ(odometry, 3);
}

TEST(Rawlog, MissingFileAndTruncatedDataNameTheFile) {
    EXPECT_THROW(RawlogReader("/nonexistent/x.rawlog"), RawlogError);

    const auto dir = lookup::test::freshDir("lookup_common_truncated");
    const std::string path = (dir / "t.rawlog").string();
    writeSample(path);
    // Re-write uncompressed and cut in the middle of a record.
    std::string bytes;
    {
        mrpt::io::CFileGZInputStream in(path);
        std::vector<char> buf(1 << 16);
        size_t n;
        while ((n = in.Read(buf.data(), buf.size())) > 0) bytes.append(buf.data(), n);
    }
    const std::string cut = (dir / "cut.rawlog").string();
    std::ofstream(cut, std::ios::binary)
        .write(bytes.data(), bytes.size() - 5);  // inside the last record
    RawlogReader r(cut);
    mrpt::obs::CObservation::Ptr obs;
    try {
        while (r.next(obs)) {
        }
        FAIL() << "truncated rawlog read without error";
    } catch (const RawlogError& e) {
        const std::string msg = e.what();
        EXPECT_NE(msg.find("cut.rawlog"), std::string::npos) << msg;
        EXPECT_NE(msg.find("record"), std::string::npos) << msg;
    }
}

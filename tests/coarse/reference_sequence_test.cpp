#include "lookup/coarse/reference_sequence.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "lookup/common/rawlog_io.h"
#include "lookup/test/support.h"
#include "route_rawlog.h"

namespace fs = std::filesystem;

namespace lookup::coarse {
namespace {

using testing::SyntheticRoute;

TEST(Descriptor, InvariantToIlluminationButNotToPlace) {
    SyntheticRoute route(10, 10, 3);
    const CoarseOptions o;
    const auto a = computeDescriptor(route.image(2, 0.0), o);
    const auto a_dark = computeDescriptor(route.image(2, 0.0, 0.5, 30.0), o);
    const auto b = computeDescriptor(route.image(5, 0.0), o);
    ASSERT_EQ(a.size(), 64u * 48u);
    EXPECT_LT(descriptorDifference(a, a_dark), 1.5);  // patch normalisation removes g*I+b
    EXPECT_GT(descriptorDifference(a, b), 10.0);      // another place differs
    // Thumbnails of larger images: the same place at 4x resolution still matches.
    cv::Mat big;
    cv::resize(route.image(2, 0.0).asCvMatRef(), big, cv::Size(256, 192), 0, 0, cv::INTER_CUBIC);
    EXPECT_LT(
        descriptorDifference(a, computeDescriptor(mrpt::img::CImage(big, mrpt::img::DEEP_COPY), o)),
        4.0);
    EXPECT_THROW(computeDescriptor(mrpt::img::CImage(), o), std::invalid_argument);
    EXPECT_THROW(descriptorDifference(a, Descriptor(3)), std::invalid_argument);
}

TEST(ReferenceDescriptors, SaveLoadRoundTripAndBrokenFiles) {
    SyntheticRoute route(30, 3, 4);
    const CoarseOptions o;
    ReferenceDescriptors refs(o);
    refs.setImageSize(64, 48);
    for (int i = 0; i < 30; ++i) {
        refs.add(100.0 + 0.5 * i, computeDescriptor(route.image(i, 3.0), o),
                 mrpt::poses::CPose3D(2.0 * i, 1.0, 0.0, 0.1 * i, 0, 0));
    }
    EXPECT_DOUBLE_EQ(refs.arcLength(29), 58.0);
    EXPECT_EQ(refs.nearestInTime(105.1), 10u);
    EXPECT_EQ(refs.nearestInSpace(mrpt::poses::CPose3D(41, 1, 0, 0, 0, 0)), 20u);

    const auto dir = lookup::test::freshDir("lookup_coarse_descriptors");
    const std::string path = (dir / "forward.coarse").string();
    refs.saveDescriptors(path);
    EXPECT_FALSE(fs::exists(path + ".tmp"));
    const auto back = ReferenceDescriptors::loadDescriptors(path);
    ASSERT_EQ(back.size(), refs.size());
    ASSERT_TRUE(back.hasPoses());
    EXPECT_EQ(back.imageWidth(), 64);
    EXPECT_EQ(back.imageHeight(), 48);
    for (std::size_t i = 0; i < refs.size(); ++i) {
        EXPECT_EQ(back.time(i), refs.time(i));
        EXPECT_EQ(back.descriptor(i), refs.descriptor(i));
        EXPECT_NEAR(back.pose(i).yaw(), refs.pose(i).yaw(), 1e-12);
        EXPECT_NEAR(back.pose(i).x(), refs.pose(i).x(), 1e-12);
    }

    // Truncated, foreign and missing files: errors name the file.
    std::string bytes;
    {
        std::ifstream in(path, std::ios::binary);
        bytes.assign(std::istreambuf_iterator<char>(in), {});
    }
    const std::string cut = (dir / "cut.coarse").string();
    std::ofstream(cut, std::ios::binary).write(bytes.data(), bytes.size() / 2);
    const std::string foreign = (dir / "foreign.coarse").string();
    std::ofstream(foreign) << "hello world, not descriptors";
    for (const auto& p : {cut, foreign, (dir / "missing.coarse").string()}) {
        try {
            ReferenceDescriptors::loadDescriptors(p);
            ADD_FAILURE() << p << " accepted";
        } catch (const DescriptorFileError& e) {
            EXPECT_NE(std::string(e.what()).find(p), std::string::npos) << e.what();
        }
    }
    // Inconsistent input to add().
    EXPECT_THROW(refs.add(99.0, refs.descriptor(0), refs.pose(0)), std::invalid_argument);
    EXPECT_THROW(refs.add(200.0, refs.descriptor(0)), std::invalid_argument);
    EXPECT_THROW(refs.add(200.0, Descriptor(5), refs.pose(0)), std::invalid_argument);
}

TEST(BuildReferenceSequence, FromRawlogWithPosesAndBadInput) {
    SyntheticRoute route(40, 3, 9);
    const auto dir = lookup::test::freshDir("lookup_coarse_build");
    const std::string rawlog = fs::absolute(dir / "ref.rawlog").string();
    const std::string gt = (dir / "ref.rawlog.GT.txt").string();
    testing::writeRouteRawlog(rawlog, route, testing::positionsFrom(0, 1, 25), 50.0, "FORWARD_CAM",
                              2.0, gt);
    const CoarseOptions o;
    const auto track = common::readPoseFile(gt);
    const auto refs = buildReferenceSequence(rawlog, o, &track);
    ASSERT_EQ(refs.size(), 25u);
    EXPECT_EQ(refs.imageWidth(), 64);
    EXPECT_DOUBLE_EQ(refs.time(3), 53.0);
    EXPECT_NEAR(refs.pose(7).x(), 7.0, 1e-9);
    EXPECT_LT(descriptorDifference(refs.descriptor(4), computeDescriptor(route.image(4, 0.0), o)),
              4.0);

    // Absent label: the message lists what is there.
    CoarseOptions other = o;
    other.camera_label = "REAR_CAM";
    try {
        buildReferenceSequence(rawlog, other);
        ADD_FAILURE() << "absent label accepted";
    } catch (const common::RawlogError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("REAR_CAM"), std::string::npos) << m;
        EXPECT_NE(m.find("FORWARD_CAM (mrpt::obs::CObservationImage)"), std::string::npos) << m;
        EXPECT_NE(m.find("ODOMETRY"), std::string::npos) << m;
        EXPECT_NE(m.find(rawlog), std::string::npos) << m;
    }

    // Images of different sizes in one rawlog: the record is named.
    const std::string mixed = (dir / "mixed.rawlog").string();
    {
        common::RawlogWriter w(mixed);
        for (int i = 0; i < 3; ++i) {
            mrpt::obs::CObservationImage img;
            img.sensorLabel = "FORWARD_CAM";
            img.timestamp = mrpt::Clock::fromDouble(i);
            img.image = route.image(i, 1.0);
            if (i == 2) img.image = img.image.scaleHalf(mrpt::img::IMG_INTERP_AREA);
            w.writeWithExternalImage(img, "f" + std::to_string(i) + ".png");
        }
        w.close();
    }
    try {
        buildReferenceSequence(mixed, o);
        ADD_FAILURE() << "mixed sizes accepted";
    } catch (const common::RawlogError& e) {
        const std::string m = e.what();
        EXPECT_NE(m.find("32x24"), std::string::npos) << m;
        EXPECT_NE(m.find("64x48"), std::string::npos) << m;
    }
    // A pose track that does not cover the images.
    common::PoseTrack short_track(track.begin(), track.begin() + 5);
    EXPECT_THROW(buildReferenceSequence(rawlog, o, &short_track), common::RawlogError);
}

}  // namespace
}  // namespace lookup::coarse

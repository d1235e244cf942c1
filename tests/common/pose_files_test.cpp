#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "lookup/common/config.h"
#include "lookup/common/pose_files.h"

namespace fs = std::filesystem;
using namespace lookup::common;

TEST(PoseFiles, MrptAndTumRoundTripToTheSamePoses) {
    PoseTrack track;
    for (int i = 0; i < 5; ++i) {
        track.push_back({1000.0 + i, mrpt::poses::CPose3D(i, 2 * i, 0.1, 0.3 * i, 0.01, -0.02)});
    }
    const auto dir = fs::temp_directory_path();
    const std::string gt = (dir / "lookup_pf.GT.txt").string();
    const std::string tum = (dir / "lookup_pf.tum").string();
    writeMrptPoseFile(gt, track);
    writeTumPoseFile(tum, track);
    for (const auto& path : {gt, tum}) {
        const auto back = readPoseFile(path);
        ASSERT_EQ(back.size(), track.size());
        for (size_t i = 0; i < track.size(); ++i) {
            EXPECT_NEAR(back[i].time_s, track[i].time_s, 1e-6);
            EXPECT_NEAR((back[i].pose - track[i].pose).translation().norm(), 0, 1e-5) << path;
            EXPECT_NEAR(back[i].pose.yaw(), track[i].pose.yaw(), 1e-6) << path;
        }
    }
}

TEST(PoseFiles, InterpolatesBetweenSamplesAndRefusesGaps) {
    PoseTrack track{{0.0, mrpt::poses::CPose3D(0, 0, 0, 0, 0, 0)},
                    {1.0, mrpt::poses::CPose3D(2, 0, 0, 0, 0, 0)},
                    {10.0, mrpt::poses::CPose3D(3, 0, 0, 0, 0, 0)}};
    auto interp = makeInterpolator(track, 2.0);
    mrpt::poses::CPose3D out;
    bool valid = false;
    interp.interpolate(mrpt::Clock::fromDouble(0.25), out, valid);
    ASSERT_TRUE(valid);
    EXPECT_NEAR(out.x(), 0.5, 1e-6);
    interp.interpolate(mrpt::Clock::fromDouble(5.0), out, valid);
    EXPECT_FALSE(valid);
}

TEST(PoseFiles, MalformedRowNamesFileAndLine) {
    const std::string path = (fs::temp_directory_path() / "lookup_bad.tum").string();
    std::ofstream(path) << "# header\n1 0 0 0 0 0 0 1\n2 0 0 zero 0 0 0 1\n";
    try {
        readPoseFile(path);
        FAIL();
    } catch (const PoseFileError& e) {
        EXPECT_NE(std::string(e.what()).find("lookup_bad.tum:3"), std::string::npos) << e.what();
    }
}

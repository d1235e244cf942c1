#include "lookup/coarse/coarse_source.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>

#include "lookup/common/config.h"
#include "lookup/test/support.h"

namespace fs = std::filesystem;

namespace lookup::coarse {
namespace {

std::shared_ptr<ReferenceDescriptors> posedReferences() {
    const CoarseOptions o;
    auto refs = std::make_shared<ReferenceDescriptors>(o);
    for (int i = 0; i < 10; ++i) {
        refs->add(500.0 + i, Descriptor(64 * 48, static_cast<std::uint8_t>(i)),
                  mrpt::poses::CPose3D(3.0 * i, 0, 0, 0, 0, 0));
    }
    return refs;
}

TEST(MatchFileSource, NearestRowWithinGapAndBadRows) {
    const auto dir = lookup::test::freshDir("lookup_coarse_matchfile");
    const std::string path = (dir / "matches.txt").string();
    std::ofstream(path) << "# query reference\n10.0 503.0\n\n11.0 504.2\n12.0 505.0\n";
    MatchFileSource src(path, 0.3, posedReferences());
    CoarseQuery q;
    q.time_s = 11.1;
    auto r = src.locate(q);
    EXPECT_EQ(r.status, CoarseStatus::External);
    EXPECT_TRUE(r.usable());
    EXPECT_DOUBLE_EQ(r.reference_time_s, 504.2);
    EXPECT_EQ(r.reference_index, 4u);  // nearest reference in time to 504.2
    ASSERT_TRUE(r.coarse_pose.has_value());
    EXPECT_DOUBLE_EQ(r.coarse_pose->x(), 12.0);
    q.time_s = 13.0;  // 1 s from the last row: beyond the gap
    r = src.locate(q);
    EXPECT_EQ(r.status, CoarseStatus::Lost);
    EXPECT_FALSE(r.reason.empty());
    EXPECT_EQ(r.query_index, 1u);

    const std::string bad = (dir / "bad.txt").string();
    std::ofstream(bad) << "10.0 503.0\n11.0 abc\n";
    try {
        MatchFileSource s(bad, 0.3);
        ADD_FAILURE();
    } catch (const DescriptorFileError& e) {
        EXPECT_NE(std::string(e.what()).find(bad + ":2"), std::string::npos) << e.what();
    }
    EXPECT_THROW(MatchFileSource((dir / "none.txt").string(), 0.3), DescriptorFileError);
}

TEST(PoseFileSource, InterpolatesAndFindsTheNearestReference) {
    const auto dir = lookup::test::freshDir("lookup_coarse_posefile");
    const std::string path = (dir / "coarse.tum").string();
    common::PoseTrack track = {{20.0, mrpt::poses::CPose3D(0, 0, 0, 0, 0, 0)},
                               {22.0, mrpt::poses::CPose3D(20, 0, 0, 0, 0, 0)}};
    common::writeTumPoseFile(path, track);
    PoseFileSource src(path, 5.0, posedReferences());
    CoarseQuery q;
    q.time_s = 21.2;  // x = 12
    auto r = src.locate(q);
    ASSERT_EQ(r.status, CoarseStatus::External);
    ASSERT_TRUE(r.coarse_pose.has_value());
    EXPECT_NEAR(r.coarse_pose->x(), 12.0, 1e-3);
    EXPECT_EQ(r.reference_index, 4u);
    EXPECT_DOUBLE_EQ(r.reference_time_s, 504.0);
    q.time_s = 30.0;
    EXPECT_EQ(src.locate(q).status, CoarseStatus::Lost);
    EXPECT_THROW(PoseFileSource((dir / "none.tum").string(), 1.0), std::exception);
}

}  // namespace
}  // namespace lookup::coarse

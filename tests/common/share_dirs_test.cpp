#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "lookup/common/share_dirs.h"

namespace fs = std::filesystem;
using lookup::common::executableDirectory;
using lookup::common::findShareFile;
using lookup::common::shareDirectories;

TEST(ShareDirs, BesideTheBinaryComesBeforeTheSourceTree) {
    const std::string exe_dir = executableDirectory();
    ASSERT_FALSE(exe_dir.empty());
    EXPECT_TRUE(fs::exists(fs::path(exe_dir) / "common_test"));
    const auto dirs = shareDirectories();
    ASSERT_GE(dirs.size(), 2u);
    EXPECT_EQ(dirs[0], (fs::path(exe_dir) / ".." / "share" / "lookup").lexically_normal().string());
    EXPECT_EQ(dirs[1], fs::path(LOOKUP_SOURCE_SHARE_DIR).lexically_normal().string());
}

TEST(ShareDirs, FindsSourceTreeFilesAndNothingForUnknownNames) {
    // The build tree has no bin/../share/lookup/refiner.ini, so the source tree's is found.
    const std::string beside = shareDirectories()[0] + "/refiner.ini";
    if (fs::exists(beside)) GTEST_SKIP() << beside << " exists";
    EXPECT_EQ(fs::path(findShareFile("refiner.ini")),
              fs::path(LOOKUP_SOURCE_SHARE_DIR).lexically_normal() / "refiner.ini");
    EXPECT_EQ(findShareFile("no-such-file-in-share.ini"), "");
}

TEST(ShareDirs, FindsAFileBesideTheBinary) {
    const fs::path beside_dir = shareDirectories()[0];
    const bool made_share = !fs::exists(beside_dir.parent_path());
    const bool made_lookup = !fs::exists(beside_dir);
    fs::create_directories(beside_dir);
    const fs::path probe = beside_dir / ("share_dirs_probe_" + std::to_string(getpid()) + ".ini");
    std::ofstream(probe) << "# probe\n";
    const std::string found = findShareFile(probe.filename().string());
    fs::remove(probe);
    if (made_lookup) fs::remove(beside_dir);
    if (made_share) fs::remove(beside_dir.parent_path());
    EXPECT_EQ(fs::path(found), probe);
}

#include "lookup/common/share_dirs.h"

#include <algorithm>
#include <filesystem>
#include <system_error>

namespace fs = std::filesystem;

namespace lookup::common {

std::string executableDirectory() {
    std::error_code ec;
    const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
    if (ec || exe.empty()) return "";
    return exe.parent_path().string();
}

std::vector<std::string> shareDirectories() {
    std::vector<std::string> dirs;
    auto add = [&dirs](const fs::path& p) {
        const std::string s = p.lexically_normal().string();
        if (!s.empty() && std::find(dirs.begin(), dirs.end(), s) == dirs.end()) dirs.push_back(s);
    };
    const std::string exe_dir = executableDirectory();
    if (!exe_dir.empty()) add(fs::path(exe_dir) / LOOKUP_SHARE_DIR_FROM_BIN);
    add(LOOKUP_SOURCE_SHARE_DIR);
    add(LOOKUP_INSTALL_SHARE_DIR);
    return dirs;
}

std::string findShareFile(const std::string& relative) {
    for (const auto& dir : shareDirectories()) {
        const fs::path p = fs::path(dir) / relative;
        std::error_code ec;
        if (fs::exists(p, ec)) return p.string();
    }
    return "";
}

}  // namespace lookup::common

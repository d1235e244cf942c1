#pragma once
// What the tests of every stage share (target lookup_test_support): temporary folders, whole
// files as text, running a built program, and an App run as its program would run it.

#include <mrpt/img/TCamera.h>

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "lookup/common/app.h"

namespace lookup::test {

/// An empty folder `<temporary folder>/<name>` (removed first with what it held). ctest sets
/// TMPDIR to the build tree's test-tmp, so two build trees never share one.
std::filesystem::path freshDir(const std::string& name);

/// The whole file (bytes as they are); "" when it cannot be read.
std::string readText(const std::filesystem::path& path);

/// An ideal pinhole camera of `width` x `height` px, focal length `f` px, centred.
inline mrpt::img::TCamera pinholeCamera(unsigned width, unsigned height, double f) {
    mrpt::img::TCamera cam;
    cam.ncols = width;
    cam.nrows = height;
    cam.fx(f);
    cam.fy(f);
    cam.cx(width / 2.0);
    cam.cy(height / 2.0);
    return cam;
}

/// bin/<name> of the build tree the tests belong to.
std::string programPath(const std::string& name);

struct ProgramRun {
    std::filesystem::path log;  ///< stdout and stderr of the program
    std::string env;            ///< "NAME=value" set for the program only; "" = none
    /// > 0: every file the program writes is capped there (RLIMIT_FSIZE, SIGXFSZ ignored:
    /// writes beyond fail with EFBIG, as on a full disk).
    long file_size_limit = 0;
    bool stdout_full = false;  ///< stdout into /dev/full (a lost stdout)
    /// Polled every 10 ms while the program runs; true kills it with SIGKILL.
    std::function<bool()> kill_when;
};

/// Runs program bin/<name> with `args` as `how` says. Returns its exit code, or 128 + signal.
int runProgram(const std::string& name, const std::vector<std::string>& args,
               const ProgramRun& how);
/// The same with stdout and stderr into `log`, files capped at `file_size_limit` (> 0) and
/// `kill_when` polled.
int runProgram(const std::string& name, const std::vector<std::string>& args,
               const std::filesystem::path& log, long file_size_limit = 0,
               const std::function<bool()>& kill_when = {});

/// What an App printed and returned.
struct AppRun {
    int code = -1;
    std::string out, err;
};

/// common::runApp(program, app, ...) with `args` after the program name, stdout and stderr
/// captured (both C and C++ streams).
AppRun runApp(const char* program, common::App& app, const std::vector<std::string>& args);

}  // namespace lookup::test

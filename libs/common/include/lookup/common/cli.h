#pragma once
// Command-line helpers shared by the apps.

#include <string>

namespace lookup::common {

/// Exit code after MRPT's TCLAP CmdLine::parse() returned false: it returns false both after
/// printing --help / --version (success) and after printing a parse error (failure), and does
/// not exit by itself, so a program that ignores the result runs on with half-parsed flags.
/// 0 when --help, -h or --version was asked for, else `error_code`.
inline int parseFailureExitCode(int argc, const char* const* argv, int error_code = 1) {
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--help" || a == "-h" || a == "--version") return 0;
    }
    return error_code;
}

}  // namespace lookup::common

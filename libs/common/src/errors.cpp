#include "lookup/common/errors.h"

#include <mrpt/3rdparty/tclap/ArgException.h>
#include <mrpt/core/exceptions.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <iostream>
#include <new>
#include <sstream>

#include "lookup/common/config.h"

namespace lookup::common {
namespace {

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r\n");
    if (b == std::string::npos) return {};
    return s.substr(b, s.find_last_not_of(" \t\r\n") - b + 1);
}

// MRPT's dump: "==== MRPT exception ====\nMessage: ...\nLocation: ...\nCall stack ...".
constexpr const char* kMrptDumpMark = "==== MRPT exception ====";

std::string withoutDump(const std::string& text) {
    const auto mark = text.find(kMrptDumpMark);
    if (mark == std::string::npos) return text;
    std::string line = trim(text.substr(0, mark));
    const auto msg = text.find("Message:", mark);
    if (msg != std::string::npos) {
        const auto from = msg + std::string("Message:").size();
        const auto end = text.find('\n', from);
        const std::string m = trim(text.substr(from, end == std::string::npos ? end : end - from));
        line += (line.empty() ? "" : " ") + m;
    }
    return line;
}

}  // namespace

WriteError::WriteError(const std::string& file, const std::string& reason)
    : std::runtime_error(file + ": write error: " + reason) {}

std::string errorLine(const std::exception& e) {
    std::stringstream in(withoutDump(e.what()));
    std::string out;
    for (std::string line; std::getline(in, line);) {
        line = trim(line);
        if (!line.empty()) out += (out.empty() ? "" : "; ") + line;
    }
    return out.empty() ? std::string("unknown error") : out;
}

std::string errorText(const std::exception& e, bool verbose) {
    return verbose ? std::string(e.what()) : errorLine(e);
}

int exitCodeFor(const std::exception& e) {
    if (dynamic_cast<const ConfigError*>(&e) || dynamic_cast<const TCLAP::ArgException*>(&e)) {
        return kExitUsage;
    }
    if (dynamic_cast<const WriteError*>(&e)) return kExitWriteError;
    if (dynamic_cast<const InternalError*>(&e) || dynamic_cast<const std::bad_alloc*>(&e)) {
        return kExitInternal;
    }
    return kExitBadInput;
}

bool verboseRequested(int argc, const char* const* argv) {
    for (int i = 1; i < argc; ++i) {
        const std::string a = argv[i];
        if (a == "--verbose" || a == "-v") return true;
    }
    return false;
}

int checkedStdout(const char* program, int code) {
    std::cout.flush();
    const bool failed = !std::cout || std::fflush(stdout) != 0 || std::ferror(stdout);
    if (!failed) return code;
    const int err = errno;
    std::cerr << program << ": stdout: write error"
              << (err != 0 ? std::string(": ") + std::strerror(err) : std::string()) << std::endl;
    return code == kExitOk ? kExitWriteError : code;
}

int guardedMain(const char* program, int argc, const char* const* argv,
                const std::function<int()>& body) {
    const bool verbose = verboseRequested(argc, argv);
    try {
        return checkedStdout(program, body());
    } catch (const std::exception& e) {
        std::cerr << program << ": " << errorText(e, verbose) << std::endl;
        return exitCodeFor(e);
    } catch (...) {
        std::cerr << program << ": internal error: unknown exception" << std::endl;
        return kExitInternal;
    }
}

}  // namespace lookup::common

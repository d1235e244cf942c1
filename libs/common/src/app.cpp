#include "lookup/common/app.h"

#include <iostream>
#include <vector>

#include "lookup/common/cli.h"
#include "lookup/common/errors.h"

namespace lookup::common {

bool App::parseCommandLine(TCLAP::CmdLine& cmd, int argc, const char* const* argv) {
    OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    std::vector<const char*> args(argv, argv + argc);
    const bool parsed = cmd.parse(argc, args.data());
    cmd.setOutput(nullptr);
    if (!parsed) exit_code_ = parseFailureExitCode(argc, argv, kExitUsage);
    return parsed;
}

bool App::refuse(const char* program, const std::exception& e, bool verbose) {
    std::cerr << program << ": " << errorText(e, verbose) << std::endl;
    exit_code_ = exitCodeFor(e);
    return false;
}

int runApp(const char* program, App& app, int argc, const char* const* argv) {
    return guardedMain(program, argc, argv, [&] {
        if (!app.initialize(argc, argv)) return app.exitCode();
        return app.run();
    });
}

}  // namespace lookup::common

#pragma once
// Command-line helpers shared by the apps.

#include <mrpt/3rdparty/tclap/CmdLine.h>

#include <iostream>
#include <list>
#include <string>

namespace lookup::common {

/// TCLAP's parse errors on one line, "<program>: <option>: <reason>", the required options
/// that are missing named, instead of TCLAP's "PARSE ERROR" and its usage block. Usage:
/// `OneLineOutput out; cmd.setOutput(&out);` (out must outlive cmd's parse()).
class OneLineOutput : public TCLAP::StdOutput {
  public:
    void failure(TCLAP::CmdLineInterface& cmd, TCLAP::ArgException& e) override {
        std::string program = cmd.getProgramName();
        program = program.substr(program.find_last_of('/') + 1);
        std::string id = e.argId();
        if (id.rfind("Argument: ", 0) == 0) id = id.substr(10);
        if (id.size() > 2 && id.front() == '(' && id.back() == ')')
            id = id.substr(1, id.size() - 2);
        std::string missing;  // only once parsing got to the end
        const bool at_end = e.error().find("required arguments missing") != std::string::npos;
        for (TCLAP::Arg* a : at_end ? cmd.getArgList() : std::list<TCLAP::Arg*>{}) {
            if (a->isRequired() && !a->isSet()) {
                missing += (missing.empty() ? "" : ", ") + std::string("--") + a->getName();
            }
        }
        std::cerr << program << ": " << (id.empty() || id == " " ? std::string() : id + ": ")
                  << e.error() << (missing.empty() ? std::string() : " (missing: " + missing + ")")
                  << " (--help lists the options)" << std::endl;
    }
};

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

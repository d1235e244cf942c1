#pragma once
// The one shape of every LookUP program: an App class in its stage's library (so tests run
// it) and a main of a few lines, `return runApp("lookup-x", app, argc, argv);`. As MRPT's
// apps: initialize() parses the command line and the options, run() does the work.

#include <exception>

namespace TCLAP {
class CmdLine;
}

namespace lookup::common {

class App {
  public:
    virtual ~App() = default;
    /// Parses the command line (and the --ini file). False when the program should exit at
    /// once with exitCode(): 0 after --help / --version, else the error was printed on stderr
    /// as one line naming the flag, or the file, section and key.
    virtual bool initialize(int argc, const char* const* argv) = 0;
    /// Does the work; returns the process exit code (common::kExit* unless the program's
    /// --help says otherwise), also kept in exitCode().
    virtual int run() = 0;
    int exitCode() const { return exit_code_; }

  protected:
    /// cmd.parse with one-line errors (common::OneLineOutput); false with exitCode() set when
    /// TCLAP printed the help, the version or an error.
    bool parseCommandLine(TCLAP::CmdLine& cmd, int argc, const char* const* argv);
    /// For initialize(): prints "<program>: <error>" on stderr, keeps its exit code, false.
    bool refuse(const char* program, const std::exception& e, bool verbose = false);

    int exit_code_ = 0;
};

/// A program's main: initialize() then run(), inside guardedMain (an escaping exception is
/// one line on stderr and its exit code; a lost stdout turns success into a write error).
int runApp(const char* program, App& app, int argc, const char* const* argv);

}  // namespace lookup::common

#pragma once
// What every program does with an error: one line on stderr naming the file, record or
// section/key and the reason (MRPT's stack dump only with --verbose), and an exit code from
// one table shared by all programs.

#include <functional>
#include <stdexcept>
#include <string>

namespace lookup::common {

/// Exit codes of every LookUP program (process exit statuses, so plain ints).
inline constexpr int kExitOk = 0;          ///< success
inline constexpr int kExitUsage = 1;       ///< bad command line or options (.ini)
inline constexpr int kExitBadInput = 2;    ///< bad input data (rawlog, image, pose file, database)
inline constexpr int kExitWriteError = 3;  ///< an output could not be written (full disk, ...)
inline constexpr int kExitInternal = 4;    ///< internal error (a bug, out of memory)

/// The exit-code table for --help texts.
inline constexpr const char* kExitCodesHelp =
    "Exit codes: 0 success, 1 usage or options error, 2 bad input data, 3 write/output "
    "error, 4 internal error.";

/// An output that could not be written or renamed into place: the message names the file.
class WriteError : public std::runtime_error {
  public:
    WriteError(const std::string& file, const std::string& reason);
};

/// A broken internal contract (a bug rather than bad input).
class InternalError : public std::logic_error {
  public:
    using std::logic_error::logic_error;
};

/// The message of `e` on one line: for MRPT exceptions the text before the dump plus its
/// "Message:" line (no call stack); other multi-line messages are joined with "; ".
std::string errorLine(const std::exception& e);
/// errorLine(e), or with `verbose` the full text including MRPT's call stack.
std::string errorText(const std::exception& e, bool verbose);
/// The exit code for `e`: ConfigError and TCLAP errors 1, WriteError 3, InternalError and
/// std::bad_alloc 4, anything else (rawlog, database, image, pose file errors) 2.
int exitCodeFor(const std::exception& e);

/// True when argv holds --verbose (or -v).
bool verboseRequested(int argc, const char* const* argv);

/// Flushes stdout; when anything written to it was lost (a closed pipe, /dev/full) prints
/// "<program>: stdout: write error" on stderr and turns a success `code` into kExitWriteError.
int checkedStdout(const char* program, int code);

/// Runs `body` and turns any exception into "<program>: <errorText>" on stderr and its exit
/// code; a non-std exception is an internal error. Returns body's own code otherwise, passed
/// through checkedStdout.
int guardedMain(const char* program, int argc, const char* const* argv,
                const std::function<int()>& body);

}  // namespace lookup::common

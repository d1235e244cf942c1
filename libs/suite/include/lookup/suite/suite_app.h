#pragma once
// lookup-suite's command line over runSuite (a thin main calls common::runApp).
//
//   lookup-suite --suite FILE.ini --out DIR [--seeds 1-5] [-j N]

#include <string>
#include <vector>

#include "lookup/common/app.h"
#include "lookup/suite/suite.h"

namespace lookup::suite {

class SuiteApp : public common::App {
  public:
    /// `share_dirs`: where bare file names and presets are looked up (source tree, install).
    explicit SuiteApp(std::vector<std::string> share_dirs) : share_dirs_(std::move(share_dirs)) {}

    /// Parses the command line and the suite file. Returns false (after printing help or the
    /// error to stderr) when the program should exit; `exitCode()` then tells how.
    bool initialize(int argc, const char* const* argv) override;
    /// Runs every job, prints one line per finished job and the table. Exit code: 0 when every
    /// job ran, 2 when some failed (their rows say why), 3 when the report cannot be written.
    int run() override;

    const SuiteOptions& options() const { return options_; }
    const std::vector<JobResult>& results() const { return results_; }

  private:
    std::vector<std::string> share_dirs_;
    SuiteOptions options_;
    std::string out_dir_;
    int parallel_ = 1;
    std::vector<JobResult> results_;
};

}  // namespace lookup::suite

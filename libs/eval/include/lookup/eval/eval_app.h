#pragma once
// lookup-eval, the program: accuracy of localisation runs against ground truth, per traverse
// and method (a thin main calls common::runApp).
//   lookup-eval --gt Q1.rawlog.GT.txt[,Q2...] --runs RUN1[,RUN2...] --out REPORT_DIR [--ini F]
//               [--map MAP.gridmap.gz] [--partial] [--verbose]

#include <string>
#include <vector>

#include "lookup/common/app.h"
#include "lookup/eval/evaluator.h"

namespace lookup::eval {

/// Parses the command line and the [eval] section of --ini; run() scores the runs, writes the
/// report folder and prints report.md on stdout. Runs that did not finish are refused unless
/// --partial; errors of the run escape run() for common::runApp to report.
class EvalApp : public common::App {
  public:
    bool initialize(int argc, const char* const* argv) override;
    int run() override;

    const EvalOptions& options() const { return options_; }

  private:
    std::vector<std::string> gt_files_, run_dirs_;
    std::string out_dir_, map_file_;
    bool partial_ = false;
    EvalOptions options_;
};

}  // namespace lookup::eval

#include "lookup/suite/suite_app.h"

#include <mrpt/3rdparty/tclap/CmdLine.h>

#include <fstream>
#include <iostream>
#include <thread>
#include <vector>

#include "lookup/common/cli.h"

namespace lookup::suite {

bool SuiteApp::initialize(int argc, const char* const* argv) {
    TCLAP::CmdLine cmd(
        "lookup-suite: generate -> survey -> localise -> evaluate over conditions x seeds, one "
        "table (suite.md, suite.json). Exit codes: 0 every job ran, 1 bad arguments or suite "
        "file, 2 some jobs failed (their rows say why), 3 the report could not be written.",
        ' ', "0.1");
    lookup::common::OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    TCLAP::ValueArg<std::string> suite("s", "suite", "suite .ini file", true, "", "FILE.ini", cmd);
    TCLAP::ValueArg<std::string> out("o", "out", "output folder", true, "", "DIR", cmd);
    TCLAP::ValueArg<std::string> seeds("", "seeds", "overrides the suite's seeds, e.g. 6-10", false,
                                       "", "LIST", cmd);
    TCLAP::ValueArg<int> jobs("j", "jobs", "jobs run side by side", false, 1, "N", cmd);
    try {
        std::vector<const char*> args(argv, argv + argc);
        if (!cmd.parse(argc, args.data())) {
            exit_code_ = common::parseFailureExitCode(argc, argv);
            return false;
        }
        if (jobs.getValue() < 1) throw std::invalid_argument("--jobs must be >= 1");
        options_ = SuiteOptions::fromFile(suite.getValue(), share_dirs_);
        if (seeds.isSet()) options_.seeds = parseSeeds(seeds.getValue());
    } catch (const std::exception& e) {
        std::cerr << "lookup-suite: " << e.what() << "\n";
        exit_code_ = 1;
        return false;
    }
    out_dir_ = out.getValue();
    parallel_ = jobs.getValue();
    const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
    options_.threads_per_job = std::max(1, static_cast<int>(cores) / parallel_);
    return true;
}

int SuiteApp::run() {
    std::cout << "lookup-suite: " << options_.conditions.size() << " conditions x "
              << options_.seeds.size() << " seeds, " << parallel_ << " at a time, into " << out_dir_
              << std::endl;
    try {
        results_ = runSuite(options_, out_dir_, parallel_, std::cout);
    } catch (const std::exception& e) {
        std::cerr << "lookup-suite: " << e.what() << "\n";
        return exit_code_ = 3;
    }
    std::ifstream table(out_dir_ + "/suite.md");
    std::cout << "\n" << table.rdbuf() << "\n";
    bool all_ok = true;
    for (const auto& r : results_) all_ok = all_ok && r.ok;
    return exit_code_ = all_ok ? 0 : 2;
}

}  // namespace lookup::suite

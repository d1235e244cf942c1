// lookup-eval: accuracy of localisation runs against ground truth, per traverse and method.
//   lookup-eval --gt Q1.rawlog.GT.txt[,Q2...] --runs RUN1[,RUN2...] --out REPORT_DIR [--ini F]
//               [--map MAP.gridmap.gz] [--partial] [--verbose]

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/system/string_utils.h>

#include <fstream>
#include <iostream>

#include "lookup/common/cli.h"
#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"
#include "lookup/eval/evaluator.h"

namespace {

int run(int argc, char** argv) {
    TCLAP::CmdLine cmd(std::string("lookup-eval: localisation error against ground truth. "
                                   "Runs that did not finish (no timing.json), whose frame "
                                   "count differs from timing.json's, without frames or "
                                   "with non-finite values are refused unless --partial. ") +
                           lookup::common::kExitCodesHelp,
                       ' ', "0.1");
    lookup::common::OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    TCLAP::ValueArg<std::string> gt_arg("", "gt", "ground-truth file(s), comma separated", true, "",
                                        "GT.txt[,...]", cmd);
    TCLAP::ValueArg<std::string> runs_arg("", "runs", "lookup-localize output folder(s)", true, "",
                                          "DIR[,...]", cmd);
    TCLAP::ValueArg<std::string> out_arg("", "out", "report folder", true, "", "DIR", cmd);
    TCLAP::ValueArg<std::string> ini_arg("", "ini", "options ([eval] section)", false, "", "FILE",
                                         cmd);
    TCLAP::ValueArg<std::string> map_arg(
        "", "map", "occupancy grid drawn under the trajectory pictures (the dataset's map)", false,
        "", "MAP.gridmap.gz", cmd);
    TCLAP::SwitchArg partial("", "partial",
                             "score such runs anyway, named in the report's flagged column", cmd);
    TCLAP::SwitchArg verbose("", "verbose", "on errors, print MRPT's full exception dump", cmd);
    if (!cmd.parse(argc, argv)) return lookup::common::parseFailureExitCode(argc, argv);

    lookup::eval::EvalOptions options;
    if (!ini_arg.getValue().empty()) {
        const auto cfg = lookup::common::loadIniFile(ini_arg.getValue());
        lookup::common::rejectUnknownSections(*cfg, {"eval"});
        lookup::common::loadAndCheck(options, *cfg, "eval");
    }
    std::vector<std::string> gt_files, run_dirs;
    mrpt::system::tokenize(gt_arg.getValue(), ",", gt_files);
    mrpt::system::tokenize(runs_arg.getValue(), ",", run_dirs);

    std::vector<lookup::eval::GroundTruth> truths;
    for (const auto& f : gt_files) truths.push_back(lookup::eval::loadGroundTruth(f));
    std::vector<lookup::eval::Run> runs;
    for (const auto& d : run_dirs) {
        runs.push_back(lookup::eval::loadRun(d));
        const std::string problem = lookup::eval::runProblem(runs.back());
        if (problem.empty()) continue;
        if (!partial.getValue()) {
            throw std::runtime_error(d + ": not scored: " + problem +
                                     " (--partial scores it, flagged)");
        }
        std::cerr << "lookup-eval: warning: " << d << ": " << problem << ": scored, flagged\n";
        runs.back().flagged = problem;
    }

    auto report = lookup::eval::evaluate(truths, runs, options);
    if (!map_arg.getValue().empty()) {
        report.map_walls = lookup::eval::loadMapWalls(map_arg.getValue());
    }
    lookup::eval::writeReport(report, out_arg.getValue());
    std::ifstream md(out_arg.getValue() + "/report.md");
    std::cout << md.rdbuf() << std::flush;
    if (!std::cout) throw lookup::common::WriteError("stdout", "cannot write the report");
    return 0;
}

}  // namespace

int main(int argc, char** argv) {
    return lookup::common::guardedMain("lookup-eval", argc, argv, [&] { return run(argc, argv); });
}

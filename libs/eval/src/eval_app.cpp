#include "lookup/eval/eval_app.h"

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/system/string_utils.h>

#include <fstream>
#include <iostream>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"

namespace lookup::eval {

bool EvalApp::initialize(int argc, const char* const* argv) {
    TCLAP::CmdLine cmd(std::string("lookup-eval: localisation error against ground truth. "
                                   "Runs that did not finish (no timing.json), whose frame "
                                   "count differs from timing.json's, without frames or "
                                   "with non-finite values are refused unless --partial. ") +
                           common::kExitCodesHelp,
                       ' ', "0.1");
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
    if (!parseCommandLine(cmd, argc, argv)) return false;
    try {
        if (!ini_arg.getValue().empty()) {
            const auto cfg = common::loadIniFile(ini_arg.getValue());
            common::rejectUnknownSections(*cfg, {"eval"});
            common::loadAndCheck(options_, *cfg, "eval");
        }
    } catch (const std::exception& e) {
        return refuse("lookup-eval", e, verbose.getValue());
    }
    mrpt::system::tokenize(gt_arg.getValue(), ",", gt_files_);
    mrpt::system::tokenize(runs_arg.getValue(), ",", run_dirs_);
    out_dir_ = out_arg.getValue();
    map_file_ = map_arg.getValue();
    partial_ = partial.getValue();
    return true;
}

int EvalApp::run() {
    std::vector<GroundTruth> truths;
    for (const auto& f : gt_files_) truths.push_back(loadGroundTruth(f));
    std::vector<Run> runs;
    for (const auto& d : run_dirs_) {
        runs.push_back(loadRun(d));
        const std::string problem = runProblem(runs.back());
        if (problem.empty()) continue;
        if (!partial_) {
            throw std::runtime_error(d + ": not scored: " + problem +
                                     " (--partial scores it, flagged)");
        }
        std::cerr << "lookup-eval: warning: " << d << ": " << problem << ": scored, flagged\n";
        runs.back().flagged = problem;
    }

    auto report = evaluate(truths, runs, options_);
    if (!map_file_.empty()) report.map_walls = loadMapWalls(map_file_);
    writeReport(report, out_dir_);
    std::ifstream md(out_dir_ + "/report.md");
    std::cout << md.rdbuf() << std::flush;
    if (!std::cout) throw common::WriteError("stdout", "cannot write the report");
    return exit_code_ = common::kExitOk;
}

}  // namespace lookup::eval

// lookup-eval: accuracy of localisation runs against ground truth, per traverse and method.
//   lookup-eval --gt Q1.rawlog.GT.txt[,Q2...] --runs RUN1[,RUN2...] --out REPORT_DIR [--ini F]

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/core/exceptions.h>
#include <mrpt/system/string_utils.h>

#include <fstream>
#include <iostream>

#include "lookup/common/cli.h"
#include "lookup/eval/evaluator.h"

int main(int argc, char** argv) {
    try {
        TCLAP::CmdLine cmd("lookup-eval: localisation error against ground truth", ' ', "0.1");
        TCLAP::ValueArg<std::string> gt_arg("", "gt", "ground-truth file(s), comma separated", true,
                                            "", "GT.txt[,...]", cmd);
        TCLAP::ValueArg<std::string> runs_arg("", "runs", "lookup-localize output folder(s)", true,
                                              "", "DIR[,...]", cmd);
        TCLAP::ValueArg<std::string> out_arg("", "out", "report folder", true, "", "DIR", cmd);
        TCLAP::ValueArg<std::string> ini_arg("", "ini", "options ([eval] section)", false, "",
                                             "FILE", cmd);
        if (!cmd.parse(argc, argv)) return lookup::common::parseFailureExitCode(argc, argv);

        lookup::eval::EvalOptions options;
        if (!ini_arg.getValue().empty()) {
            mrpt::config::CConfigFile cfg(ini_arg.getValue());
            options.loadFromConfigFile(cfg, "eval");
        }
        std::vector<std::string> gt_files, run_dirs;
        mrpt::system::tokenize(gt_arg.getValue(), ",", gt_files);
        mrpt::system::tokenize(runs_arg.getValue(), ",", run_dirs);

        std::vector<lookup::eval::GroundTruth> truths;
        for (const auto& f : gt_files) truths.push_back(lookup::eval::loadGroundTruth(f));
        std::vector<lookup::eval::Run> runs;
        for (const auto& d : run_dirs) runs.push_back(lookup::eval::loadRun(d));

        const auto report = lookup::eval::evaluate(truths, runs, options);
        lookup::eval::writeReport(report, out_arg.getValue());
        std::ifstream md(out_arg.getValue() + "/report.md");
        std::cout << md.rdbuf();
        return 0;
    } catch (const TCLAP::ArgException& e) {
        std::cerr << "lookup-eval: " << e.error() << " (" << e.argId() << ")\n";
    } catch (const std::exception& e) {
        std::cerr << "lookup-eval: " << mrpt::exception_to_str(e) << "\n";
    }
    return 1;
}

// lookup-sim: generates a synthetic mine dataset (docs/dataset-format.md, docs/sim.md).
//   lookup-sim --preset mine-b-mini --out /tmp/mine-b-mini [--seed N]
//   lookup-sim --scenario my.ini --out DIR

#include <lookup/common/config.h>
#include <lookup/sim/simulator.h>
#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/system/progress.h>

#include <unistd.h>
#include <cstdio>
#include <iostream>
#include <string>
#include <vector>

#include "lookup/common/cli.h"
#include "lookup/common/errors.h"
#include "lookup/common/share_dirs.h"

namespace {

// share/lookup/scenarios of every share folder, best first (lookup/common/share_dirs.h).
std::vector<std::string> scenarioDirectories() {
    std::vector<std::string> dirs;
    for (const auto& d : lookup::common::shareDirectories()) dirs.push_back(d + "/scenarios");
    return dirs;
}

}  // namespace

namespace {

int run(int argc, char** argv) {
    TCLAP::CmdLine cmd(std::string("lookup-sim: synthetic underground mine with ground truth "
                                   "(MRPT rawlogs). ") +
                           lookup::common::kExitCodesHelp,
                       ' ', "0.1");
    lookup::common::OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    TCLAP::ValueArg<std::string> preset(
        "p", "preset",
        "built-in scenario: mine-a, mine-b, mine-a-mini, mine-b-mini, mine-a-real, mine-b-real, "
        "mine-a-real-mini, mine-b-real-mini, lhd-cycle-mini, mine-b-decline-mini",
        false, "", "NAME", cmd);
    TCLAP::ValueArg<std::string> scenario("s", "scenario", "scenario .ini file", false, "",
                                          "FILE.ini", cmd);
    TCLAP::ValueArg<std::string> out("o", "out", "output dataset folder", true, "", "DIR", cmd);
    TCLAP::ValueArg<uint64_t> seed("", "seed", "overrides the scenario's seed", false, 0, "N", cmd);
    TCLAP::ValueArg<int> threads("j", "threads", "render threads (0: all cores)", false, -1, "N",
                                 cmd);
    TCLAP::SwitchArg quiet("q", "quiet", "no progress bar", cmd);
    TCLAP::SwitchArg verbose("v", "verbose", "full error texts (MRPT call stacks)", cmd);
    if (!cmd.parse(argc, argv)) return lookup::common::parseFailureExitCode(argc, argv);
    if (preset.isSet() == scenario.isSet()) {
        throw lookup::common::ConfigError(
            "give exactly one of --preset NAME or --scenario FILE.ini");
    }
    {
        const std::string path =
            scenario.isSet() ? scenario.getValue()
                             : lookup::sim::findPreset(preset.getValue(), scenarioDirectories());
        lookup::sim::ScenarioOptions options = lookup::sim::ScenarioOptions::fromFile(path);
        if (seed.isSet()) options.seed = seed.getValue();
        if (threads.isSet()) options.threads = threads.getValue();
        lookup::sim::Simulator sim(options);
        std::cout << "lookup-sim: " << options.name << " from " << path << ", seed " << options.seed
                  << ", route " << sim.world().routeLength() << " m, " << options.traverses.size()
                  << " traverses\n";
        const bool bar = !quiet.isSet() && isatty(fileno(stderr));
        auto progress = [bar](const std::string& name, double f) {
            if (!bar) return;
            std::fprintf(stderr, "\r%-10s %s %5.1f%%", name.c_str(),
                         mrpt::system::progress(f, 40).c_str(), 100 * f);
            if (f >= 1.0) std::fprintf(stderr, "\n");
            std::fflush(stderr);
        };
        const auto result = sim.run(out.getValue(), progress);
        if (result.status != lookup::sim::SimulationResult::Status::Ok) {
            // The simulator's failures are the outputs it could not write.
            std::cerr << "lookup-sim: FAILED: " << result.reason << std::endl;
            return int(lookup::common::kExitWriteError);
        }
        std::cout << lookup::sim::formatSummary(result) << std::flush;
        if (!std::cout) throw lookup::common::WriteError("stdout", "cannot write the summary");
        return int(lookup::common::kExitOk);
    }
}

}  // namespace

int main(int argc, char** argv) {
    return lookup::common::guardedMain("lookup-sim", argc, argv, [&] { return run(argc, argv); });
}

#include "lookup/sim/sim_app.h"

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/system/progress.h>
#include <unistd.h>

#include <cstdio>
#include <iostream>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/share_dirs.h"

namespace lookup::sim {
namespace {

std::vector<std::string> scenarioDirectories() {
    std::vector<std::string> dirs;
    for (const auto& d : common::shareDirectories()) dirs.push_back(d + "/scenarios");
    return dirs;
}

void drawProgress(const std::string& name, double f) {
    std::fprintf(stderr, "\r%-10s %s %5.1f%%", name.c_str(), mrpt::system::progress(f, 40).c_str(),
                 100 * f);
    if (f >= 1.0) std::fprintf(stderr, "\n");
    std::fflush(stderr);
}

}  // namespace

SimApp::SimApp() : scenario_dirs_(scenarioDirectories()) {}

bool SimApp::initialize(int argc, const char* const* argv) {
    TCLAP::CmdLine cmd(std::string("lookup-sim: synthetic underground mine with ground truth "
                                   "(MRPT rawlogs). ") +
                           common::kExitCodesHelp,
                       ' ', "0.1");
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
    if (!parseCommandLine(cmd, argc, argv)) return false;
    try {
        if (preset.isSet() == scenario.isSet()) {
            throw common::ConfigError("give exactly one of --preset NAME or --scenario FILE.ini");
        }
        scenario_file_ =
            scenario.isSet() ? scenario.getValue() : findPreset(preset.getValue(), scenario_dirs_);
        options_ = ScenarioOptions::fromFile(scenario_file_);
    } catch (const std::exception& e) {
        return refuse("lookup-sim", e, verbose.getValue());
    }
    if (seed.isSet()) options_.seed = seed.getValue();
    if (threads.isSet()) options_.threads = threads.getValue();
    out_dir_ = out.getValue();
    progress_bar_ = !quiet.isSet() && isatty(fileno(stderr));
    return true;
}

int SimApp::run() {
    Simulator sim(options_);
    std::cout << "lookup-sim: " << options_.name << " from " << scenario_file_ << ", seed "
              << options_.seed << ", route " << sim.world().routeLength() << " m, "
              << options_.traverses.size() << " traverses\n";
    for (const auto& w : sim.warnings()) std::cerr << "lookup-sim: warning: " << w << "\n";
    result_ = sim.run(out_dir_, progress_bar_ ? Simulator::Progress(drawProgress) : nullptr);
    if (result_.status != SimulationResult::Status::Ok) {
        // The simulator's failures are the outputs it could not write.
        std::cerr << "lookup-sim: FAILED: " << result_.reason << std::endl;
        return exit_code_ = common::kExitWriteError;
    }
    std::cout << formatSummary(result_) << std::flush;
    if (!std::cout) throw common::WriteError("stdout", "cannot write the summary");
    return exit_code_ = common::kExitOk;
}

}  // namespace lookup::sim

#pragma once
// lookup-sim, the program: generates a synthetic mine dataset (docs/dataset-format.md,
// docs/sim.md); a thin main calls common::runApp.
//   lookup-sim --preset mine-b-mini --out /tmp/mine-b-mini [--seed N]
//   lookup-sim --scenario my.ini --out DIR

#include <string>
#include <vector>

#include "lookup/common/app.h"
#include "lookup/sim/scenario.h"
#include "lookup/sim/simulator.h"

namespace lookup::sim {

/// Parses the command line and reads the scenario (a preset or --scenario FILE.ini, whose
/// unknown sections and keys are refused naming the file); run() writes the dataset and prints
/// its summary. Exit code 3 when an output could not be written.
class SimApp : public common::App {
  public:
    /// Presets are looked up in share/lookup/scenarios of every share folder, best first.
    SimApp();
    explicit SimApp(std::vector<std::string> scenario_dirs)
        : scenario_dirs_(std::move(scenario_dirs)) {}

    bool initialize(int argc, const char* const* argv) override;
    int run() override;

    const ScenarioOptions& options() const { return options_; }
    const SimulationResult& result() const { return result_; }

  private:
    std::vector<std::string> scenario_dirs_;
    std::string scenario_file_, out_dir_;
    bool progress_bar_ = false;
    ScenarioOptions options_;
    SimulationResult result_;
};

}  // namespace lookup::sim

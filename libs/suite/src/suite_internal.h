#pragma once
// Pieces shared by the suite's sources, not part of its interface.

#include <nlohmann/json.hpp>

#include <cstdint>
#include <string>

#include "lookup/sim/scenario.h"
#include "lookup/suite/suite.h"

namespace lookup::suite {

/// The condition's preset with its overrides applied and checked, for one seed.
sim::ScenarioOptions scenarioFor(const Condition& condition, std::uint64_t seed,
                                 const std::string& suite_source, int threads);

nlohmann::json toJson(const JobResult& job);
JobResult jobFromJson(const nlohmann::json& j);

}  // namespace lookup::suite

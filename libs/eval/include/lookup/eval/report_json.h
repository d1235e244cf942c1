#pragma once
// One (traverse, method) row as report.json writes it: the same keys wherever a row is written
// or read back (lookup-eval's report, lookup-suite's per-job results).

#include <nlohmann/json.hpp>

#include "lookup/eval/evaluator.h"

namespace lookup::eval {

nlohmann::json toJson(const MethodResult& row);

/// The row written by toJson(); throws nlohmann::json::exception for a missing key or a value
/// of the wrong type.
MethodResult methodResultFromJson(const nlohmann::json& j);

}  // namespace lookup::eval

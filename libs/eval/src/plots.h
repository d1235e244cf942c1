#pragma once
// gnuplot helpers shared by the report's charts (internal to libs/eval).

#include <string>

#include "lookup/eval/evaluator.h"

namespace lookup::eval::detail {

/// True when gnuplot is on the PATH.
bool haveGnuplot();
/// Runs the script `gp` (its output files named inside it), retrying with the plain png
/// terminal when pngcairo is missing; false with `warning` set when it fails.
bool runGnuplot(const std::string& gp, const std::string& out_dir, std::string& warning);
/// The per-run trajectory and per-traverse error-along-the-route pictures; false with
/// `warning` set when gnuplot fails on one (the others are still drawn).
bool plotRunPictures(const Report& r, const std::string& out_dir, std::string& warning);
/// A file-name-safe form of a traverse or method name.
std::string fileStem(const std::string& name);

}  // namespace lookup::eval::detail

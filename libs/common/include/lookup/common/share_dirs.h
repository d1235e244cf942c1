#pragma once
// Where the programs find their data files (share/lookup: .ini presets, scenarios, sensors):
// beside the running binary first, so an installed or relocated tree uses its own files, then
// the source tree the program was built from, then the configured install prefix.

#include <string>
#include <vector>

namespace lookup::common {

/// The folder holding the running executable (from /proc/self/exe); empty when unknown.
std::string executableDirectory();

/// Candidate share/lookup folders, best first, without duplicates:
/// `<executable dir>/<bin-to-share path>` (normally `../share/lookup`), the source tree's
/// share/lookup, the install prefix's share/lookup. Folders need not exist.
std::vector<std::string> shareDirectories();

/// `relative` (e.g. "survey.ini", "scenarios") under the first of shareDirectories() where it
/// exists; empty when none holds it.
std::string findShareFile(const std::string& relative);

}  // namespace lookup::common

#pragma once
// Integrity of a database folder: lookup-survey records the CRC-32 and size of every file it
// writes in `manifest.crc32`; ReferenceDatabase::load() verifies them, so a damaged file (a
// flipped byte, a truncated copy) is refused naming the file instead of changing poses
// silently. db.ini is covered without its [heatmaps] section, which lookup-train rewrites;
// heat maps written later are not covered.
//
// Format, one line per file: `<crc32, 8 hex digits> <size in bytes> <path relative to the
// folder>`; lines starting with '#' are comments.

#include <string>

namespace lookup::database {

inline constexpr const char* kManifest = "manifest.crc32";

/// Writes `<dir>/manifest.crc32` over every regular file under `dir` (common::WriteError on
/// failure).
void writeManifest(const std::string& dir);

/// Verifies `<dir>/manifest.crc32`: DatabaseError naming the file when one is missing, of
/// another size or another checksum, or when the manifest itself is malformed. Returns false
/// (and checks nothing) when the folder has no manifest (databases of older versions).
bool verifyManifest(const std::string& dir);

}  // namespace lookup::database

#pragma once
// Integrity of a database folder: lookup-survey records the CRC-32 and size of every file it
// writes in `manifest.crc32`; ReferenceDatabase::load() verifies them, so a damaged file (a
// flipped byte, a truncated copy) is refused naming the file instead of changing poses
// silently. db.ini is covered without its [heatmaps] section, which lookup-train rewrites;
// lookup-train gives each heat-map folder it writes a manifest of its own, verified on load
// when db.ini lists that folder.
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

/// Checks the heat-map folder `heatmaps_dir` (db.ini [heatmaps] directory, relative to the
/// database folder `db_dir`): DatabaseError when it is not a folder inside the database, or
/// when its manifest finds a damaged file. Nothing to check when `heatmaps_dir` is empty.
void verifyHeatMaps(const std::string& db_dir, const std::string& heatmaps_dir);

}  // namespace lookup::database

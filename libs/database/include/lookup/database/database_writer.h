#pragma once
// Builds a reference database folder atomically: everything is written into a staging folder
// `<out>.tmp-<pid>-XXXXXX` beside the target, synced to disk, checked by loading it, and
// swapped in by commit(): the old database is renamed to `<out>.old-<pid>-XXXXXX`, the new one
// renamed onto `<out>`, the old one removed. A writer destroyed without commit() (an
// exception, a failed survey) removes its staging folder, and an existing database at `<out>`
// stays untouched until the new one is complete. A process killed on the way leaves folders
// that recoverInterrupted() restores or removes at the next start. Write failures (a full
// disk) throw common::WriteError naming the file.

#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/obs/CObservationImage.h>

#include <memory>
#include <string>
#include <vector>

#include "lookup/common/rawlog_io.h"
#include "lookup/database/reference.h"

namespace lookup::database {

/// What the survey hands over for one reference.
struct ReferenceInput {
    std::string traverse;
    /// Ceiling image (external file or in memory) with cameraParams and cameraPose.
    mrpt::obs::CObservationImage::Ptr ceiling;
    /// Forward image nearest in time (may be null).
    mrpt::obs::CObservationImage::Ptr forward;
    mrpt::poses::CPose3D vehicle_pose;          ///< at the ceiling image time, map frame
    mrpt::math::CMatrixDouble33 vehicle_cov;    ///< (x, y, yaw)
    mrpt::poses::CPose3D forward_vehicle_pose;  ///< at the forward image time, map frame
    double sharpness = 0;
    double mean_intensity = 0;
    double travelled_m = 0;
    std::string source = "survey";  ///< Reference::source
    std::string superseded_by;      ///< Reference::superseded_by
};

/// Restores or removes what interrupted writers of `out_dir` left beside it (only those of
/// processes no longer running): when `out_dir` is missing but an `.old-` folder exists (a kill
/// between the two renames of commit()), the old database is renamed back; stale `.tmp-`
/// (staging) and `.old-` folders are removed. Returns one line per action, for the user.
std::vector<std::string> recoverInterrupted(const std::string& out_dir);

/// Test seam: when the environment variable LOOKUP_TEST_KILL_AT equals `point`, the process
/// kills itself with SIGKILL there (points: "staging-created", "between-renames",
/// "before-old-removed"), so tests can interrupt a survey at an exact step.
void testKillPoint(const char* point);

class DatabaseWriter {
  public:
    /// Creates the staging folder beside `out_dir`. Throws DatabaseError if impossible. Ceiling
    /// images wider than `ceiling_max_width_px` (> 0) are stored averaged down to that width,
    /// their intrinsics (and DatabaseInfo::ceiling_camera at commit) scaled with them.
    explicit DatabaseWriter(const std::string& out_dir, int ceiling_max_width_px = 0);
    ~DatabaseWriter();
    DatabaseWriter(const DatabaseWriter&) = delete;
    DatabaseWriter& operator=(const DatabaseWriter&) = delete;

    /// Appends one reference (its images stored as 8-bit grey PGM in refs_Images/); returns its
    /// id.
    uint32_t add(const ReferenceInput& in);
    /// Stores the map as map.gridmap.gz and map.png.
    void setMap(const mrpt::maps::COccupancyGridMap2D& map);
    /// Writes a text file (e.g. the report) into the staging folder.
    void writeTextFile(const std::string& name, const std::string& content);

    /// Writes refs.tum, db.ini and the checksum manifest, closes refs.rawlog, syncs and loads
    /// the staging folder and renames it onto `out_dir`, replacing an older database there.
    /// Throws common::WriteError (naming the file) on failure; the old database is then kept.
    void commit(DatabaseInfo info);

    const std::string& stagingDir() const { return staging_; }
    std::size_t size() const { return references_.size(); }

  private:
    void writeRecord(const mrpt::obs::CObservation& obs);
    void verifyStaged() const;
    void swapIntoPlace();

    std::string out_dir_;
    std::string staging_;
    int ceiling_max_width_px_ = 0;
    std::unique_ptr<common::RawlogWriter> rawlog_;
    std::vector<Reference> references_;
    bool has_map_ = false;
    bool committed_ = false;
};

}  // namespace lookup::database

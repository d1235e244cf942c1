#pragma once
// What the localiser keeps between runs (docs/run-format.md, "Persisted fix", "The camera
// clock carried between runs"): the last trusted fix, so that a localiser restarted where the
// vehicle stopped (power cycle, crash) starts from it; the ceiling camera's time offset as the
// vehicle's drives estimated it. Files are replaced atomically (a temporary beside it, fsync,
// rename): a power cut leaves the previous content or the new one, never half a file.

#include <mrpt/poses/CPosePDFGaussian.h>

#include <condition_variable>
#include <mutex>
#include <optional>
#include <string>
#include <thread>

#include "lookup/localize/localizer.h"

namespace lookup::database {
class ReferenceDatabase;
}

namespace lookup::localize {

struct SavedFix {
    double time_s = 0;        ///< time stamp of the frame that was refined
    double saved_unix_s = 0;  ///< when the file was written (UNIX time)
    mrpt::poses::CPosePDFGaussian pose;
    std::string db_dir;       ///< database path, for the log (moving a database keeps its fixes)
    std::string db_identity;  ///< databaseIdentity() of the database the fix was made on
};

/// What identifies a database's content: MD5 of db.ini and refs.tum, and the reference count.
std::string databaseIdentity(const database::ReferenceDatabase& db);

/// Writes `fix` to `path` atomically. Throws std::runtime_error naming the path and the reason.
void writeFixFile(const std::string& path, const SavedFix& fix);

/// Reads a fix written by writeFixFile. Returns nullopt, with `why_not` set to a one-line
/// reason naming the file, when it is missing, corrupt or from another database than
/// `db_identity`.
std::optional<SavedFix> readFixFile(const std::string& path, const std::string& db_identity,
                                    std::string& why_not);

/// The ceiling camera's offset against the odometry as the vehicle's runs left it.
struct SavedCameraClock {
    std::string camera;  ///< the ceiling camera's sensor label
    CameraClock::Estimate estimate;
    double saved_unix_s = 0;
};

/// Writes `clock` to `path` atomically. Throws common::WriteError naming the path and reason.
void writeCameraClockFile(const std::string& path, const SavedCameraClock& clock);

/// Reads a file written by writeCameraClockFile. Returns nullopt, with `why_not` set to a
/// one-line reason naming the file, when it is missing, corrupt, not finite, or of another
/// camera than `camera`.
std::optional<SavedCameraClock> readCameraClockFile(const std::string& path,
                                                    const std::string& camera,
                                                    std::string& why_not);

/// Keeps the last refined fix of a run and writes it every `interval_s` while it changes, on
/// a thread of its own (an fsync must not delay a frame), and at flush(). A failing write is
/// logged once and retried; it never stops a run.
class FixPersister {
  public:
    FixPersister(std::string path, double interval_s, std::string db_dir, std::string db_identity);
    ~FixPersister();  ///< flush()
    /// Notes a frame; refined frames become the fix to persist.
    void update(const FrameResult& frame);
    /// Stops the writer thread and writes the fix now if it changed (at shutdown). Idempotent.
    void flush();
    std::size_t writes() const;

  private:
    void writerLoop();
    void writeLocked(std::unique_lock<std::mutex>& lock);
    std::string path_;
    double interval_s_;
    mutable std::mutex mutex_;
    std::condition_variable wake_;
    SavedFix fix_;
    bool dirty_ = false, error_logged_ = false, stopping_ = false;
    std::size_t writes_ = 0;
    std::thread writer_;
};

}  // namespace lookup::localize

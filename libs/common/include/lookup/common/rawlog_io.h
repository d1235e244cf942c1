#pragma once
// Rawlog reading and writing shared by every tool. Reading accepts both MRPT rawlog formats
// (actions/sensory-frames and observations-only) and resolves external images to absolute
// paths, which sidesteps the MRPT 2.5.8 `detectImagesDirectory` bug with absolute rawlog
// paths and lets several rawlogs be open at once (CImage's path base is a global).

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CObservation.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/poses/CPose2D.h>
#include <mrpt/serialization/CArchive.h>

#include <cstddef>
#include <cstdio>
#include <deque>
#include <exception>
#include <memory>
#include <stdexcept>
#include <string>

namespace lookup::common {

/// A rawlog that cannot be read: the message names the file, the record index and the reason.
class RawlogError : public std::runtime_error {
  public:
    RawlogError(const std::string& file, std::size_t record, const std::string& reason);
    RawlogError(const std::string& file, const std::string& reason);
    /// A message that names file and record already (e.g. another RawlogError's, extended).
    explicit RawlogError(const std::string& message) : std::runtime_error(message) {}
};

/// A text output file whose every write is checked: a failed write, flush, fsync or close
/// (full disk, file size limit, I/O error) throws WriteError naming the file.
class OutputFile {
  public:
    /// Opens (truncates) `path`; throws WriteError when it cannot.
    explicit OutputFile(std::string path);
    ~OutputFile();
    OutputFile(const OutputFile&) = delete;
    OutputFile& operator=(const OutputFile&) = delete;

    void write(const std::string& text);
    /// printf-style; throws WriteError on failure.
    void printf(const char* format, ...) __attribute__((format(printf, 2, 3)));
    /// Hands what was written to the kernel (a killed program keeps it).
    void flush();
    /// Flushes, fsyncs and closes (the data is on the device when this returns).
    void close();
    const std::string& path() const { return path_; }

  private:
    [[noreturn]] void fail(const char* what) const;
    std::string path_;
    std::FILE* file_ = nullptr;
};

/// Writes `content` to `<path>.tmp`, fsyncs it and renames it over `path`: readers see the old
/// file or the complete new one, never a part. Throws WriteError naming the file.
void writeFileAtomically(const std::string& path, const std::string& content);

/// fsync of a written file, before it is renamed into place. Throws WriteError.
void syncFile(const std::string& path);

/// fsync of a folder, so renames and new files in it survive a power cut. Throws WriteError.
void syncDirectory(const std::string& dir);

/// `<dir>/<stem>_Images` for `<dir>/<stem>.rawlog`: where external images live.
std::string imagesDirectoryFor(const std::string& rawlog_path);

/// Streams the observations of a rawlog in file order.
///
/// Sensory frames are flattened into their observations. Odometry actions
/// (CActionRobotMovement2D) of the actions/sensory-frames format become CObservationOdometry
/// records, labelled "ODOMETRY", carrying the accumulated odometry pose, so callers see one
/// kind of record whatever the format.
class RawlogReader {
  public:
    /// Opens `path`; throws RawlogError if it does not exist or cannot be opened.
    explicit RawlogReader(const std::string& path);

    /// Reads the next observation into `obs`; false at the end of the file. Throws RawlogError
    /// (file, record, reason) on corrupt or truncated data.
    bool next(mrpt::obs::CObservation::Ptr& obs);

    /// Index of the rawlog entry the last observation came from (0-based, as RawLogViewer).
    std::size_t recordIndex() const { return record_index_; }
    const std::string& path() const { return path_; }
    const std::string& imagesDirectory() const { return images_dir_; }

  private:
    void resolveImagePaths(mrpt::obs::CObservation& obs) const;

    std::string path_;
    std::string images_dir_;
    mrpt::io::CFileGZInputStream file_;
    std::unique_ptr<mrpt::serialization::CArchive> archive_;
    std::deque<mrpt::obs::CObservation::Ptr> pending_;
    std::size_t next_entry_ = 0;
    std::size_t record_index_ = 0;
    mrpt::poses::CPose2D odometry_;
};

/// Writes an observations-only rawlog (gz-compressed, as MRPT's own tools write them) whose
/// images are stored as external PNG files in `<stem>_Images/`. The file is written to
/// `<path>.tmp` and renamed by close(), so an interrupted run never leaves a truncated rawlog
/// under the final name.
class RawlogWriter {
  public:
    explicit RawlogWriter(const std::string& rawlog_path, int compress_level = 1);
    ~RawlogWriter();
    RawlogWriter(const RawlogWriter&) = delete;
    RawlogWriter& operator=(const RawlogWriter&) = delete;

    /// Stores `obs.image` as `<stem>_Images/<file_name>` (PNG unless the name says otherwise)
    /// and writes the observation referring to it. An image that is already external is
    /// loaded and re-saved, so the output folder is self-contained.
    void writeWithExternalImage(mrpt::obs::CObservationImage& obs, const std::string& file_name);

    /// Writes any observation as it is (images embedded, if any). Throws WriteError.
    void write(const mrpt::obs::CObservation& obs);

    /// Flushes, closes, reads the file back (a full disk can cut the compressed stream on
    /// close, unreported by zlib), fsyncs and renames into place. Called by the destructor
    /// if not called before, unless the writer is destroyed by an exception: then the
    /// unfinished file stays as `<path>.tmp`. A WriteError (e.g. a full disk) propagates from
    /// here but not from the destructor (which leaves the .tmp file).
    void close();

    std::size_t recordsWritten() const { return records_; }
    const std::string& imagesDirectory() const { return images_dir_; }

  private:
    /// Throws WriteError unless `tmp` reads back as exactly `records` records.
    static void verifyWritten(const std::string& tmp, std::size_t records);

    std::string path_;
    std::string images_dir_;
    mrpt::io::CFileGZOutputStream file_;
    std::unique_ptr<mrpt::serialization::CArchive> archive_;
    std::size_t records_ = 0;
    bool closed_ = false;
    int exceptions_at_open_ = std::uncaught_exceptions();
};

}  // namespace lookup::common

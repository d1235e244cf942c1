#include "lookup/common/rawlog_io.h"

#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/system/filesystem.h>

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstdarg>
#include <cstdio>
#include <cstring>
#include <exception>
#include <filesystem>

#include "lookup/common/errors.h"

namespace lookup::common {
namespace fs = std::filesystem;

RawlogError::RawlogError(const std::string& file, std::size_t record, const std::string& reason)
    : std::runtime_error(file + ": record " + std::to_string(record) + ": " + reason) {}

RawlogError::RawlogError(const std::string& file, const std::string& reason)
    : std::runtime_error(file + ": " + reason) {}

OutputFile::OutputFile(std::string path) : path_(std::move(path)) {
    file_ = std::fopen(path_.c_str(), "w");
    if (file_ == nullptr) fail("cannot open for writing");
}

OutputFile::~OutputFile() {
    if (file_ != nullptr) std::fclose(file_);
}

void OutputFile::fail(const char* what) const {
    throw WriteError(path_, std::string(what) + ": " + std::strerror(errno));
}

void OutputFile::write(const std::string& text) {
    if (std::fwrite(text.data(), 1, text.size(), file_) != text.size()) fail("cannot write");
}

void OutputFile::printf(const char* format, ...) {
    std::va_list args;
    va_start(args, format);
    const int n = std::vfprintf(file_, format, args);
    va_end(args);
    if (n < 0 || std::ferror(file_)) fail("cannot write");
}

void OutputFile::flush() {
    if (std::fflush(file_) != 0 || std::ferror(file_)) fail("cannot write");
}

void OutputFile::close() {
    if (file_ == nullptr) return;
    flush();
    if (::fsync(fileno(file_)) != 0) fail("cannot sync");
    std::FILE* f = std::exchange(file_, nullptr);
    if (std::fclose(f) != 0) fail("cannot close");
}

void writeFileAtomically(const std::string& path, const std::string& content) {
    const std::string tmp = path + ".tmp";
    {
        OutputFile out(tmp);
        out.write(content);
        out.close();
    }
    std::error_code ec;
    fs::rename(tmp, path, ec);
    if (ec) throw WriteError(path, "cannot rename " + tmp + " into place: " + ec.message());
    syncDirectory(fs::absolute(path).parent_path().string());
}

void syncFile(const std::string& path) {
    const int fd = ::open(path.c_str(), O_RDONLY);
    if (fd < 0 || ::fsync(fd) != 0) {
        const int err = errno;
        if (fd >= 0) ::close(fd);
        throw WriteError(path, std::string("cannot sync: ") + std::strerror(err));
    }
    ::close(fd);
}

void syncDirectory(const std::string& dir) {
    const int fd = ::open(dir.c_str(), O_RDONLY | O_DIRECTORY);
    if (fd < 0) throw WriteError(dir, std::string("cannot open folder: ") + std::strerror(errno));
    const int rc = ::fsync(fd);
    const int err = errno;
    ::close(fd);
    // Some file systems cannot sync folders (EINVAL): nothing more to be had there.
    if (rc != 0 && err != EINVAL) {
        throw WriteError(dir, std::string("cannot sync folder: ") + std::strerror(err));
    }
}

std::string imagesDirectoryFor(const std::string& rawlog_path) {
    const fs::path p = fs::absolute(rawlog_path);
    return (p.parent_path() / (p.stem().string() + "_Images")).string();
}

RawlogReader::RawlogReader(const std::string& path) : path_(path) {
    if (!fs::is_regular_file(path)) throw RawlogError(path, "no such rawlog file");
    std::string error;
    if (!file_.open(path, error)) throw RawlogError(path, "cannot open: " + error);
    archive_ =
        std::make_unique<mrpt::serialization::CArchiveStreamBase<mrpt::io::CFileGZInputStream>>(
            file_);
    images_dir_ = imagesDirectoryFor(path);
    if (!fs::is_directory(images_dir_)) {
        // MRPT's other convention: a sibling folder named "Images".
        const auto alt = fs::absolute(path).parent_path() / "Images";
        if (fs::is_directory(alt)) images_dir_ = alt.string();
    }
}

void RawlogReader::resolveImagePaths(mrpt::obs::CObservation& obs) const {
    auto* img_obs = dynamic_cast<mrpt::obs::CObservationImage*>(&obs);
    if (img_obs == nullptr || !img_obs->image.isExternallyStored()) return;
    const std::string name = img_obs->image.getExternalStorageFile();
    if (!name.empty() && name.front() != '/') {
        img_obs->image.setExternalStorage(images_dir_ + "/" + name);
    }
}

bool RawlogReader::next(mrpt::obs::CObservation::Ptr& obs) {
    while (pending_.empty()) {
        const std::size_t entry = next_entry_;
        const uint64_t position_before = file_.getPosition();
        mrpt::serialization::CSerializable::Ptr object;
        try {
            object = archive_->ReadObject();
        } catch (const mrpt::serialization::CExceptionEOF&) {
            // Nothing consumed at the end of the file: a clean end between records. Nothing
            // consumed before it: the compressed stream is damaged. Otherwise a record was cut.
            if (file_.getPosition() == position_before) {
                if (file_.checkEOF()) return false;
                throw RawlogError(path_, entry,
                                  "unreadable from here: damaged compressed data (byte flip?)");
            }
            throw RawlogError(path_, entry, "truncated record (unexpected end of file)");
        } catch (const std::exception& e) {
            throw RawlogError(path_, entry, std::string("corrupt record: ") + e.what());
        }
        ++next_entry_;
        record_index_ = entry;
        if (auto single = std::dynamic_pointer_cast<mrpt::obs::CObservation>(object)) {
            pending_.push_back(single);
        } else if (auto frame = std::dynamic_pointer_cast<mrpt::obs::CSensoryFrame>(object)) {
            for (const auto& o : *frame) pending_.push_back(o);
        } else if (auto actions = std::dynamic_pointer_cast<mrpt::obs::CActionCollection>(object)) {
            if (auto move = actions->getBestMovementEstimation(); move) {
                odometry_ = odometry_ + move->rawOdometryIncrementReading;
                auto odo = mrpt::obs::CObservationOdometry::Create();
                odo->sensorLabel = "ODOMETRY";
                odo->timestamp = move->timestamp;
                odo->odometry = odometry_;
                pending_.push_back(odo);
            }
        } else {
            throw RawlogError(path_, entry,
                              std::string("unexpected object of class ") +
                                  (object ? object->GetRuntimeClass()->className : "null"));
        }
    }
    obs = pending_.front();
    pending_.pop_front();
    if (!obs) throw RawlogError(path_, record_index_, "null observation");
    resolveImagePaths(*obs);
    return true;
}

RawlogWriter::RawlogWriter(const std::string& rawlog_path, int compress_level)
    : path_(rawlog_path), images_dir_(imagesDirectoryFor(rawlog_path)) {
    std::error_code ec;
    fs::create_directories(images_dir_, ec);
    if (ec) throw RawlogError(rawlog_path, "cannot create " + images_dir_ + ": " + ec.message());
    std::string error;
    if (!file_.open(path_ + ".tmp", compress_level, error)) {
        throw RawlogError(rawlog_path, "cannot open for writing: " + error);
    }
    archive_ =
        std::make_unique<mrpt::serialization::CArchiveStreamBase<mrpt::io::CFileGZOutputStream>>(
            file_);
}

RawlogWriter::~RawlogWriter() {
    if (closed_) return;
    try {
        if (std::uncaught_exceptions() == exceptions_at_open_) {
            close();
            return;
        }
        // Destroyed by an exception: the rawlog is unfinished and must not be renamed into
        // place; it stays as .tmp.
        archive_.reset();
        file_.close();
    } catch (...) {
        // Destructors must not throw; the .tmp file is left behind for inspection.
    }
}

void RawlogWriter::writeWithExternalImage(mrpt::obs::CObservationImage& obs,
                                          const std::string& file_name) {
    const std::string full = images_dir_ + "/" + file_name;
    if (!obs.image.saveToFile(full)) {
        throw WriteError(
            full, "cannot write image (record " + std::to_string(records_) + " of " + path_ + ")");
    }
    obs.image.setExternalStorage(file_name);
    write(obs);
    // The in-memory observation now refers to a relative name; make it usable again.
    obs.image.setExternalStorage(full);
}

void RawlogWriter::write(const mrpt::obs::CObservation& obs) {
    try {
        (*archive_) << obs;
    } catch (const std::exception& e) {
        throw WriteError(path_ + ".tmp",
                         "record " + std::to_string(records_) + ": " + errorLine(e));
    }
    ++records_;
}

void RawlogWriter::close() {
    if (closed_) return;
    closed_ = true;
    archive_.reset();
    file_.close();
    const std::string tmp = path_ + ".tmp";
    verifyWritten(tmp, records_);
    syncFile(tmp);
    std::error_code ec;
    fs::rename(tmp, path_, ec);
    if (ec) throw WriteError(path_, "cannot rename into place: " + ec.message());
}

void RawlogWriter::verifyWritten(const std::string& tmp, std::size_t records) {
    std::size_t read = 0;
    try {
        RawlogReader back(tmp);
        mrpt::obs::CObservation::Ptr obs;
        std::size_t last_entry = std::string::npos;
        while (back.next(obs)) {
            // Sensory frames hold several observations: count entries, not observations.
            if (back.recordIndex() != last_entry) ++read;
            last_entry = back.recordIndex();
        }
    } catch (const std::exception& e) {
        throw WriteError(tmp, "read-back after " + std::to_string(read) + " of " +
                                  std::to_string(records) +
                                  " records failed (disk full?): " + errorLine(e));
    }
    if (read != records) {
        throw WriteError(tmp, "read-back found " + std::to_string(read) + " of " +
                                  std::to_string(records) + " records (disk full?)");
    }
}

}  // namespace lookup::common

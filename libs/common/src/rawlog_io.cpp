#include "lookup/common/rawlog_io.h"

#include <mrpt/obs/CActionCollection.h>
#include <mrpt/obs/CActionRobotMovement2D.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/obs/CSensoryFrame.h>
#include <mrpt/system/filesystem.h>

#include <cstdio>
#include <filesystem>

namespace lookup::common {
namespace fs = std::filesystem;

RawlogError::RawlogError(const std::string& file, std::size_t record, const std::string& reason)
    : std::runtime_error(file + ": record " + std::to_string(record) + ": " + reason) {}

RawlogError::RawlogError(const std::string& file, const std::string& reason)
    : std::runtime_error(file + ": " + reason) {}

std::string imagesDirectoryFor(const std::string& rawlog_path) {
    const fs::path p = fs::absolute(rawlog_path);
    return (p.parent_path() / (p.stem().string() + "_Images")).string();
}

RawlogReader::RawlogReader(const std::string& path) : path_(path) {
    if (!fs::is_regular_file(path)) throw RawlogError(path, "no such rawlog file");
    std::string error;
    if (!file_.open(path, error)) throw RawlogError(path, "cannot open: " + error);
    archive_ = std::make_unique<mrpt::serialization::CArchiveStreamBase<
        mrpt::io::CFileGZInputStream>>(file_);
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
            // Nothing consumed: a clean end between records. Otherwise a record was cut.
            if (file_.getPosition() == position_before) return false;
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
        } else if (auto actions =
                       std::dynamic_pointer_cast<mrpt::obs::CActionCollection>(object)) {
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
    archive_ = std::make_unique<mrpt::serialization::CArchiveStreamBase<
        mrpt::io::CFileGZOutputStream>>(file_);
}

RawlogWriter::~RawlogWriter() {
    if (closed_) return;
    try {
        close();
    } catch (...) {
        // Destructors must not throw; the .tmp file is left behind for inspection.
    }
}

void RawlogWriter::writeWithExternalImage(mrpt::obs::CObservationImage& obs,
                                          const std::string& file_name) {
    const std::string full = images_dir_ + "/" + file_name;
    if (!obs.image.saveToFile(full)) {
        throw RawlogError(path_, records_, "cannot write image " + full);
    }
    obs.image.setExternalStorage(file_name);
    write(obs);
    // The in-memory observation now refers to a relative name; make it usable again.
    obs.image.setExternalStorage(full);
}

void RawlogWriter::write(const mrpt::obs::CObservation& obs) {
    (*archive_) << obs;
    ++records_;
}

void RawlogWriter::close() {
    if (closed_) return;
    closed_ = true;
    archive_.reset();
    file_.close();
    std::error_code ec;
    fs::rename(path_ + ".tmp", path_, ec);
    if (ec) throw RawlogError(path_, "cannot rename into place: " + ec.message());
}

}  // namespace lookup::common

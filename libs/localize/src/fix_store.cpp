#include "lookup/localize/fix_store.h"

#include <fcntl.h>
#include <mrpt/system/md5.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lookup/common/rawlog_io.h"
#include "lookup/database/reference.h"
#include "lookup/database/reference_database.h"
#include "lookup/localize/pose_stream.h"

namespace lookup::localize {

namespace {

std::string fileContent(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    return s.str();
}

void writeAll(int fd, const std::string& text, const std::string& path) {
    std::size_t done = 0;
    while (done < text.size()) {
        const ssize_t n = ::write(fd, text.data() + done, text.size() - done);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) throw std::runtime_error(path + ": cannot write: " + std::strerror(errno));
        done += static_cast<std::size_t>(n);
    }
}

/// A state file of `format` ("a LookUP `what` file"): a missing file, another format or one
/// that does not parse is said in `why_not`, naming the file; `read` takes the fields (throwing
/// on a missing or mistyped one, said as corrupt) and checks them.
template <typename Read>
auto readStateFile(const std::string& path, const std::string& format, const std::string& what,
                   const std::string& missing, std::string& why_not, Read read)
    -> decltype(read(nlohmann::json{})) {
    if (!std::filesystem::exists(path)) {
        why_not = path + ": " + missing;
        return std::nullopt;
    }
    try {
        const auto j = nlohmann::json::parse(fileContent(path));
        if (j.value("format", "") != format) {
            why_not = path + ": not a LookUP " + what + " file (no \"format\": \"" + format + "\")";
            return std::nullopt;
        }
        return read(j);
    } catch (const std::exception& e) {
        why_not = path + ": corrupt: " + std::string(e.what()).substr(0, 200);
        return std::nullopt;
    }
}

}  // namespace

std::string databaseIdentity(const database::ReferenceDatabase& db) {
    const std::string dir = db.directory() + "/";
    return mrpt::system::md5(fileContent(dir + database::kDbIni) +
                             fileContent(dir + database::kRefsTum)) +
           "-" + std::to_string(db.size());
}

void writeFixFile(const std::string& path, const SavedFix& fix) {
    nlohmann::json j;
    j["format"] = "lookup-fix";
    j["version"] = 1;
    j["t_fix"] = fix.time_s;
    j["t_saved"] = fix.saved_unix_s;
    j["x"] = fix.pose.mean.x();
    j["y"] = fix.pose.mean.y();
    j["yaw"] = fix.pose.mean.phi();
    std::vector<double> cov;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) cov.push_back(fix.pose.cov(r, c));
    j["cov"] = cov;
    j["db"] = {{"path", fix.db_dir}, {"identity", fix.db_identity}};
    const std::string text = j.dump(2) + "\n";

    // The temporary lies beside the target so that rename() stays on one file system.
    const std::string tmp = path + ".tmp" + std::to_string(::getpid());
    const int fd = ::open(tmp.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
    if (fd < 0) throw std::runtime_error(tmp + ": cannot create: " + std::strerror(errno));
    try {
        writeAll(fd, text, tmp);
        if (::fsync(fd) != 0) throw std::runtime_error(tmp + ": fsync: " + std::strerror(errno));
    } catch (...) {
        ::close(fd);
        ::unlink(tmp.c_str());
        throw;
    }
    ::close(fd);
    if (std::rename(tmp.c_str(), path.c_str()) != 0) {
        const std::string why = std::strerror(errno);
        ::unlink(tmp.c_str());
        throw std::runtime_error(path + ": cannot replace: " + why);
    }
    // The rename itself is durable once the folder is synced.
    const auto parent = std::filesystem::absolute(path).parent_path();
    const int dir_fd = ::open(parent.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    if (dir_fd >= 0) {
        ::fsync(dir_fd);
        ::close(dir_fd);
    }
}

std::optional<SavedFix> readFixFile(const std::string& path, const std::string& db_identity,
                                    std::string& why_not) {
    return readStateFile(
        path, "lookup-fix", "fix", "no persisted fix yet", why_not,
        [&](const nlohmann::json& j) -> std::optional<SavedFix> {
            SavedFix fix;
            fix.time_s = j.at("t_fix").get<double>();
            fix.saved_unix_s = j.at("t_saved").get<double>();
            const auto& cov = j.at("cov");
            if (!cov.is_array() || cov.size() != 9) {
                why_not = path + ": \"cov\" is not 9 numbers";
                return std::nullopt;
            }
            fix.pose.mean = mrpt::poses::CPose2D(j.at("x").get<double>(), j.at("y").get<double>(),
                                                 j.at("yaw").get<double>());
            bool finite = std::isfinite(fix.pose.mean.x()) && std::isfinite(fix.pose.mean.y()) &&
                          std::isfinite(fix.pose.mean.phi());
            for (int k = 0; k < 9; ++k) {
                fix.pose.cov(k / 3, k % 3) = cov.at(k).get<double>();
                finite = finite && std::isfinite(fix.pose.cov(k / 3, k % 3));
            }
            if (!finite) {
                why_not = path + ": pose or covariance not finite";
                return std::nullopt;
            }
            fix.db_dir = j.at("db").at("path").get<std::string>();
            fix.db_identity = j.at("db").at("identity").get<std::string>();
            if (fix.db_identity != db_identity) {
                why_not = path + ": made on another database (" + fix.db_dir + ", identity " +
                          fix.db_identity + "; this one: " + db_identity + ")";
                return std::nullopt;
            }
            return fix;
        });
}

void writeCameraClockFile(const std::string& path, const SavedCameraClock& clock) {
    nlohmann::json j;
    j["format"] = "lookup-camera-clock";
    j["version"] = 1;
    j["camera"] = clock.camera;
    j["offset_s"] = clock.estimate.offset_s;
    j["sigma_s"] = clock.estimate.sigma_s;
    j["pairs"] = clock.estimate.pairs;
    j["t_saved"] = clock.saved_unix_s;
    common::writeFileAtomically(path, j.dump(2) + "\n");
}

std::optional<SavedCameraClock> readCameraClockFile(const std::string& path,
                                                    const std::string& camera,
                                                    std::string& why_not) {
    return readStateFile(path, "lookup-camera-clock", "camera clock", "no carried estimate yet",
                         why_not, [&](const nlohmann::json& j) -> std::optional<SavedCameraClock> {
                             SavedCameraClock clock;
                             clock.camera = j.at("camera").get<std::string>();
                             clock.estimate.offset_s = j.at("offset_s").get<double>();
                             clock.estimate.sigma_s = j.at("sigma_s").get<double>();
                             clock.estimate.pairs = j.at("pairs").get<std::size_t>();
                             clock.saved_unix_s = j.value("t_saved", 0.0);
                             if (!std::isfinite(clock.estimate.offset_s) ||
                                 !std::isfinite(clock.estimate.sigma_s) ||
                                 !(clock.estimate.sigma_s > 0)) {
                                 why_not = path + ": offset not finite or sigma not positive";
                                 return std::nullopt;
                             }
                             if (clock.camera != camera) {
                                 why_not = path + ": the offset of camera '" + clock.camera +
                                           "', not of '" + camera + "'";
                                 return std::nullopt;
                             }
                             return clock;
                         });
}

FixPersister::FixPersister(std::string path, double interval_s, std::string db_dir,
                           std::string db_identity)
    : path_(std::move(path)), interval_s_(interval_s) {
    fix_.db_dir = std::move(db_dir);
    fix_.db_identity = std::move(db_identity);
    writer_ = std::thread([this] { writerLoop(); });
}

FixPersister::~FixPersister() { flush(); }

void FixPersister::update(const FrameResult& frame) {
    if (frame.status != FrameStatus::Refined || !frame.has_pose) return;
    std::lock_guard<std::mutex> lock(mutex_);
    fix_.time_s = frame.time_s;
    fix_.pose = frame.pose;
    dirty_ = true;
}

void FixPersister::flush() {
    std::unique_lock<std::mutex> lock(mutex_);
    if (!writer_.joinable()) return;
    stopping_ = true;
    lock.unlock();
    wake_.notify_one();
    writer_.join();
    lock.lock();
    if (dirty_) writeLocked(lock);
}

std::size_t FixPersister::writes() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return writes_;
}

void FixPersister::writerLoop() {
    std::unique_lock<std::mutex> lock(mutex_);
    while (!stopping_) {
        wake_.wait_for(lock, std::chrono::duration<double>(interval_s_),
                       [this] { return stopping_; });
        if (!stopping_ && dirty_) writeLocked(lock);
    }
}

void FixPersister::writeLocked(std::unique_lock<std::mutex>& lock) {
    SavedFix fix = fix_;
    dirty_ = false;
    fix.saved_unix_s = PoseStream::unixTime();
    lock.unlock();  // frames go on updating while the file is written
    std::string error;
    try {
        writeFixFile(path_, fix);
    } catch (const std::exception& e) {
        error = e.what();
    }
    lock.lock();
    if (error.empty()) {
        ++writes_;
        error_logged_ = false;
        return;
    }
    dirty_ = true;  // retried at the next interval
    if (!error_logged_) {
        std::fprintf(stderr, "lookup-localize: persisted fix not written: %s\n", error.c_str());
    }
    error_logged_ = true;
}

}  // namespace lookup::localize

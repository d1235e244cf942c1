#include "lookup/database/database_writer.h"

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/serialization/CArchive.h>

#include <fcntl.h>
#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "lookup/common/camera_params.h"
#include "lookup/common/errors.h"
#include "lookup/common/grey.h"
#include "lookup/common/pose_files.h"
#include "lookup/database/manifest.h"
#include "lookup/database/reference_database.h"
#include "lookup/obs/observation_lookup_reference.h"

namespace lookup::database {
namespace fs = std::filesystem;
namespace {

std::string normalised(const std::string& dir) {
    fs::path p = fs::absolute(dir).lexically_normal();
    if (p.filename().empty()) p = p.parent_path();  // drop a trailing '/'
    return p.string();
}

// The pixels the localiser reads: 8-bit grey, as ImageCache loads them.
cv::Mat greyPixels(const mrpt::obs::CObservationImage& src, const std::string& target) {
    cv::Mat grey;
    try {
        if (src.image.isExternallyStored()) {
            grey = cv::imread(src.image.getExternalStorageFileAbsolutePath(), cv::IMREAD_GRAYSCALE);
        } else {
            grey = common::greyOf(src.image.asCvMatRef());
            if (!grey.empty() && grey.depth() != CV_8U) grey.convertTo(grey, CV_8U);
        }
    } catch (const std::exception& e) {
        throw common::WriteError(target, std::string("cannot read the source image: ") + e.what());
    }
    if (grey.empty()) {
        const std::string from = src.image.isExternallyStored()
                                     ? src.image.getExternalStorageFileAbsolutePath()
                                     : std::string("an in-memory image");
        throw common::WriteError(target, "cannot read the source image " + from);
    }
    return grey;
}

// Stores the image of `src` as `images_dir/name`, an uncompressed 8-bit grey PGM, and returns
// an observation that refers to it by `name`, leaving `src` untouched (CImage copies share
// their pixels and external path). Uncompressed because a lost vehicle reads dozens of
// references per frame: PGM decodes about 100 times faster than PNG (docs/benchmarks.md,
// "Reference images stored uncompressed"). An image wider than `max_width` (> 0) is averaged
// down to it, its intrinsics with it.
mrpt::obs::CObservationImage::Ptr storedCopy(const mrpt::obs::CObservationImage& src,
                                             const std::string& images_dir, const std::string& name,
                                             int max_width = 0) {
    const std::string target = images_dir + "/" + name;
    cv::Mat grey = greyPixels(src, target);
    auto out = mrpt::obs::CObservationImage::Create();
    out->sensorLabel = src.sensorLabel;
    out->timestamp = src.timestamp;
    out->cameraPose = src.cameraPose;
    out->cameraParams = src.cameraParams;
    const cv::Mat stored = common::averagedDownTo(grey, max_width);
    if (stored.cols != grey.cols && src.cameraParams.ncols > 0) {
        out->cameraParams = common::resizedCamera(src.cameraParams, stored.cols, stored.rows);
    }
    grey = stored;
    std::vector<uchar> pgm;
    if (!cv::imencode(".pgm", grey, pgm)) throw common::WriteError(target, "cannot encode image");
    std::ofstream file(target, std::ios::binary);
    file.write(reinterpret_cast<const char*>(pgm.data()), static_cast<std::streamsize>(pgm.size()));
    file.close();
    if (!file) throw common::WriteError(target, "cannot write image");
    out->image.setExternalStorage(name);
    return out;
}

// fsync of a file or folder; WriteError naming it on failure.
void syncPath(const fs::path& path, bool directory) {
    const int fd = ::open(path.c_str(), directory ? (O_RDONLY | O_DIRECTORY) : O_RDONLY);
    if (fd < 0) throw common::WriteError(path.string(), std::strerror(errno));
    const int rc = ::fsync(fd);
    const int err = errno;
    ::close(fd);
    if (rc != 0)
        throw common::WriteError(path.string(), std::string("fsync: ") + std::strerror(err));
}

// Every file and folder under `dir` (and `dir` itself) on disk before the rename.
void syncTree(const fs::path& dir) {
    for (const auto& e : fs::recursive_directory_iterator(dir)) {
        syncPath(e.path(), e.is_directory());
    }
    syncPath(dir, true);
}

// The pid in a leftover's name "<base>.tmp-<pid>-XXXXXX" (0 when the name has none).
long ownerPid(const std::string& name, const std::string& prefix) {
    return std::strtol(name.c_str() + prefix.size(), nullptr, 10);
}

bool processAlive(long pid) { return pid > 0 && (::kill(pid_t(pid), 0) == 0 || errno == EPERM); }

std::string megabytes(const fs::path& dir) {
    std::uintmax_t bytes = 0;
    std::error_code ec;
    for (const auto& e : fs::recursive_directory_iterator(dir, ec)) {
        if (e.is_regular_file(ec)) bytes += e.file_size(ec);
    }
    char buf[32];
    std::snprintf(buf, sizeof(buf), "%.1f MB", bytes / 1.0e6);
    return buf;
}

bool isFinite(const mrpt::poses::CPose3D& p) {
    const auto v = p.asVectorVal();
    return std::all_of(v.begin(), v.end(), [](double x) { return std::isfinite(x); });
}

bool isFinite(const mrpt::math::CMatrixDouble33& m) {
    bool finite = true;
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) finite &= std::isfinite(m(r, c));
    return finite;
}

// Refuses a reference the database must not hold; `index` is the id it would get.
void checkStorable(const ReferenceInput& in, const std::string& out_dir, std::size_t index) {
    if (!in.ceiling) throw DatabaseError("DatabaseWriter::add: reference without ceiling image");
    const std::string which = out_dir + ": reference " + std::to_string(index) + " (t=" +
                              std::to_string(mrpt::Clock::toDouble(in.ceiling->timestamp)) + " s)";
    // The last line of defence: whatever went wrong upstream, no NaN reaches the database.
    if (!isFinite(in.vehicle_pose) || !isFinite(in.vehicle_cov) ||
        !isFinite(in.ceiling->cameraPose) || (in.forward && !isFinite(in.forward_vehicle_pose))) {
        throw DatabaseError(which + " has a non-finite pose or covariance; not stored");
    }
    // All-zero focal lengths: no calibration recorded (the localiser refuses the reference).
    const auto& camera = in.ceiling->cameraParams;
    const bool unset = camera.fx() == 0 && camera.fy() == 0;
    if (const auto why = common::cameraProblem(camera); !unset && !why.empty()) {
        throw DatabaseError(which + ": ceiling camera " + why + "; not stored");
    }
}

std::string imageName(const char* prefix, const char* stem) {
    return std::string(prefix) + stem + ".pgm";
}

// The in-memory reference, without its image paths.
Reference referenceOf(const ReferenceInput& in, uint32_t id) {
    Reference ref;
    ref.id = id;
    ref.traverse = in.traverse;
    ref.time_s = mrpt::Clock::toDouble(in.ceiling->timestamp);
    ref.vehicle_pose = in.vehicle_pose;
    ref.vehicle_cov = in.vehicle_cov;
    ref.ceiling_camera_mount = in.ceiling->cameraPose;
    ref.ceiling_camera_pose = in.vehicle_pose + in.ceiling->cameraPose;
    ref.ceiling_camera = in.ceiling->cameraParams;
    ref.sharpness = in.sharpness;
    ref.mean_intensity = in.mean_intensity;
    ref.travelled_m = in.travelled_m;
    ref.source = in.source;
    ref.superseded_by = in.superseded_by;
    if (in.forward) {
        ref.has_forward = true;
        ref.forward_time_s = mrpt::Clock::toDouble(in.forward->timestamp);
        ref.forward_camera_pose = in.forward_vehicle_pose + in.forward->cameraPose;
    }
    return ref;
}

// The vehicle pose as a standard MRPT record, for viewers.
mrpt::obs::CObservationRobotPose poseRecord(const ReferenceInput& in) {
    mrpt::obs::CObservationRobotPose pose;
    pose.sensorLabel = kPoseLabel;
    pose.timestamp = in.ceiling->timestamp;
    pose.pose.mean = in.vehicle_pose;
    // CPose3DPDFGaussian orders (x, y, z, yaw, pitch, roll); ours is (x, y, yaw).
    const int map_index[3] = {0, 1, 3};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            pose.pose.cov(map_index[r], map_index[c]) = in.vehicle_cov(r, c);
    return pose;
}

// The record ReferenceDatabase::load reads the reference back from.
obs::CObservationLookupReference referenceRecord(const ReferenceInput& in, const Reference& ref,
                                                 const std::string& ceiling_name,
                                                 const std::string& forward_name) {
    obs::CObservationLookupReference record;
    record.sensorLabel = kReferenceLabel;
    record.timestamp = in.ceiling->timestamp;
    record.sensorPose = in.ceiling->cameraPose;
    record.reference_id = ref.id;
    record.traverse = in.traverse;
    record.vehicle_pose = in.vehicle_pose;
    record.vehicle_cov = in.vehicle_cov;
    record.ceiling_camera_pose = ref.ceiling_camera_pose;
    record.has_ceiling_camera = true;
    record.ceiling_camera = ref.ceiling_camera;
    record.forward_camera_pose = ref.forward_camera_pose;
    record.ceiling_image_file = ceiling_name;
    record.forward_image_file = forward_name;
    record.forward_time_s = ref.forward_time_s;
    record.sharpness = in.sharpness;
    record.mean_intensity = in.mean_intensity;
    record.travelled_m = in.travelled_m;
    record.source = in.source;
    record.superseded_by = in.superseded_by;
    return record;
}

}  // namespace

void testKillPoint(const char* point) {
    const char* at = std::getenv("LOOKUP_TEST_KILL_AT");
    if (at != nullptr && std::strcmp(at, point) == 0) ::raise(SIGKILL);
}

std::vector<std::string> recoverInterrupted(const std::string& out) {
    const fs::path target(normalised(out));
    const std::string base = target.filename().string();
    std::vector<fs::path> staging, old;
    std::error_code ec;
    for (const auto& e : fs::directory_iterator(target.parent_path(), ec)) {
        const std::string name = e.path().filename().string();
        for (const auto& [kind, list] : {std::pair{".tmp-", &staging}, std::pair{".old-", &old}}) {
            const std::string prefix = base + kind;
            if (name.rfind(prefix, 0) == 0 && !processAlive(ownerPid(name, prefix))) {
                list->push_back(e.path());
            }
        }
    }
    std::vector<std::string> done;
    if (!fs::exists(target) && !old.empty()) {
        // Killed between the renames: the old database is complete; put the newest back.
        std::sort(old.begin(), old.end(), [](const fs::path& a, const fs::path& b) {
            std::error_code e;
            return fs::last_write_time(a, e) < fs::last_write_time(b, e);
        });
        const fs::path back = old.back();
        old.pop_back();
        fs::rename(back, target, ec);
        if (ec) {
            throw common::WriteError(target.string(), "no database, and cannot rename " +
                                                          back.string() + " back: " + ec.message());
        }
        done.push_back(target.string() +
                       ": restored the database an interrupted lookup-survey "
                       "had moved to " +
                       back.string());
    }
    for (const auto* list : {&staging, &old}) {
        for (const auto& p : *list) {
            const std::string size = megabytes(p);
            fs::remove_all(p, ec);
            done.push_back((ec ? "cannot remove " : "removed ") + p.string() + " (" + size +
                           ", left by an interrupted lookup-survey)" +
                           (ec ? ": " + ec.message() : std::string()));
        }
    }
    return done;
}

DatabaseWriter::DatabaseWriter(const std::string& out_dir, int ceiling_max_width_px)
    : out_dir_(normalised(out_dir)), ceiling_max_width_px_(ceiling_max_width_px) {
    std::error_code ec;
    fs::create_directories(fs::path(out_dir_).parent_path(), ec);
    std::string templ = out_dir_ + ".tmp-" + std::to_string(::getpid()) + "-XXXXXX";
    if (mkdtemp(templ.data()) == nullptr) {
        throw common::WriteError(out_dir_, std::string("cannot create a staging folder beside "
                                                       "it: ") +
                                               std::strerror(errno));
    }
    staging_ = templ;
    rawlog_ = std::make_unique<common::RawlogWriter>(staging_ + "/" + kRefsRawlog);
    testKillPoint("staging-created");
}

DatabaseWriter::~DatabaseWriter() {
    if (committed_) return;
    rawlog_.reset();
    std::error_code ec;
    fs::remove_all(staging_, ec);  // a failed survey leaves nothing behind
}

uint32_t DatabaseWriter::add(const ReferenceInput& in) {
    checkStorable(in, out_dir_, references_.size());
    const auto id = static_cast<uint32_t>(references_.size());
    char stem[32];
    std::snprintf(stem, sizeof(stem), "%06u", id);
    const std::string images_dir = rawlog_->imagesDirectory();

    Reference ref = referenceOf(in, id);
    const std::string ceiling_name = imageName("ceiling_", stem);
    const auto ceiling = storedCopy(*in.ceiling, images_dir, ceiling_name, ceiling_max_width_px_);
    ref.ceiling_camera = ceiling->cameraParams;
    writeRecord(*ceiling);
    ref.ceiling_image_path = images_dir + "/" + ceiling_name;
    std::string forward_name;
    if (in.forward) {
        forward_name = imageName("forward_", stem);
        writeRecord(*storedCopy(*in.forward, images_dir, forward_name));
        ref.forward_image_path = images_dir + "/" + forward_name;
    }
    writeRecord(poseRecord(in));
    writeRecord(referenceRecord(in, ref, ceiling_name, forward_name));
    references_.push_back(std::move(ref));
    return id;
}

void DatabaseWriter::setMap(const mrpt::maps::COccupancyGridMap2D& map) {
    const std::string grid = staging_ + "/" + kMapGrid;
    try {
        {
            mrpt::io::CFileGZOutputStream f;
            if (!f.open(grid)) throw common::WriteError(grid, "cannot open for writing");
            auto arch = mrpt::serialization::archiveFrom(f);
            arch << map;
        }
        // MRPT's gz stream does not report a failed write (a full disk): read it back.
        mrpt::io::CFileGZInputStream in(grid);
        mrpt::maps::COccupancyGridMap2D back;
        auto arch = mrpt::serialization::archiveFrom(in);
        arch >> back;
    } catch (const common::WriteError&) {
        throw;
    } catch (const std::exception& e) {
        throw common::WriteError(grid, "does not read back (" + common::errorLine(e) + ")");
    }
    if (!map.saveAsBitmapFile(staging_ + "/" + kMapPng)) {
        throw common::WriteError(staging_ + "/" + kMapPng, "cannot write");
    }
    has_map_ = true;
}

void DatabaseWriter::writeRecord(const mrpt::obs::CObservation& obs) {
    try {
        rawlog_->write(obs);
    } catch (const std::exception& e) {
        throw common::WriteError(staging_ + "/" + kRefsRawlog, common::errorLine(e));
    }
}

void DatabaseWriter::writeTextFile(const std::string& name, const std::string& content) {
    const std::string path = staging_ + "/" + name;
    std::ofstream out(path);
    out << content;
    out.close();
    if (!out) throw common::WriteError(path, "cannot write");
}

void DatabaseWriter::commit(DatabaseInfo info) {
    if (committed_) throw DatabaseError(out_dir_ + ": database already committed");
    // The localiser's camera is that of the stored images.
    auto& camera = info.ceiling_camera;
    if (const auto size =
            common::cappedSize(int(camera.ncols), int(camera.nrows), ceiling_max_width_px_);
        size.x != int(camera.ncols)) {
        camera = common::resizedCamera(camera, size.x, size.y);
    }
    try {
        rawlog_->close();
    } catch (const std::exception& e) {
        throw common::WriteError(staging_ + "/" + kRefsRawlog, common::errorLine(e));
    }
    common::PoseTrack track;
    for (const auto& r : references_) track.push_back({r.time_s, r.vehicle_pose});
    try {
        common::writeTumPoseFile(staging_ + "/" + kRefsTum, track);
    } catch (const std::exception& e) {
        throw common::WriteError(staging_ + "/" + kRefsTum, common::errorLine(e));
    }
    info.reference_count = references_.size();
    info.map_file = has_map_ ? kMapGrid : "";
    writeDatabaseInfo(staging_ + "/" + kDbIni, info);
    writeManifest(staging_);
    syncTree(staging_);
    verifyStaged();
    swapIntoPlace();
}

void DatabaseWriter::verifyStaged() const {
    // A write that failed unnoticed (a full disk under a buffered stream) shows up here as a
    // database that does not load, before anything at out_dir is touched.
    try {
        const auto db = ReferenceDatabase::load(staging_, 1);
        if (db.size() != references_.size()) {
            throw DatabaseError(staging_ + ": holds " + std::to_string(db.size()) + " of " +
                                std::to_string(references_.size()) + " references");
        }
    } catch (const common::WriteError&) {
        throw;
    } catch (const std::exception& e) {
        throw common::WriteError(staging_, "the database just written does not load back (" +
                                               common::errorLine(e) + ")");
    }
}

void DatabaseWriter::swapIntoPlace() {
    std::error_code ec;
    std::string old;
    if (fs::exists(out_dir_)) {
        old = staging_;
        old.replace(old.rfind(".tmp-"), 5, ".old-");
        fs::rename(out_dir_, old, ec);
        if (ec) {
            throw common::WriteError(out_dir_,
                                     "cannot move the old database aside: " + ec.message());
        }
    }
    testKillPoint("between-renames");
    fs::rename(staging_, out_dir_, ec);
    if (ec) {
        std::error_code ignored;
        if (!old.empty()) fs::rename(old, out_dir_, ignored);
        throw common::WriteError(out_dir_,
                                 "cannot rename " + staging_ + " into place: " + ec.message());
    }
    committed_ = true;
    syncPath(fs::path(out_dir_).parent_path(), true);
    testKillPoint("before-old-removed");
    if (!old.empty()) fs::remove_all(old, ec);
}

}  // namespace lookup::database

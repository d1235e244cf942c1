#include "lookup/database/database_writer.h"

#include <mrpt/io/CFileGZOutputStream.h>
#include <mrpt/obs/CObservationRobotPose.h>
#include <mrpt/serialization/CArchive.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>

#include "lookup/common/pose_files.h"
#include "lookup/obs/observation_lookup_reference.h"

namespace lookup::database {
namespace fs = std::filesystem;
namespace {

std::string normalised(const std::string& dir) {
    fs::path p = fs::absolute(dir).lexically_normal();
    if (p.filename().empty()) p = p.parent_path();  // drop a trailing '/'
    return p.string();
}

std::string extensionOf(const std::string& path, const char* fallback) {
    const std::string ext = fs::path(path).extension().string();
    return ext.empty() ? fallback : ext;
}

// Puts the image of `src` into `images_dir/name` (copying the file when it is external) and
// returns an observation that refers to it by `name`, leaving `src` untouched (CImage copies
// share their pixels and external path).
mrpt::obs::CObservationImage::Ptr externalCopy(const mrpt::obs::CObservationImage& src,
                                               const std::string& images_dir,
                                               const std::string& name) {
    const std::string target = images_dir + "/" + name;
    if (src.image.isExternallyStored()) {
        const std::string from = src.image.getExternalStorageFileAbsolutePath();
        std::error_code ec;
        fs::copy_file(from, target, fs::copy_options::overwrite_existing, ec);
        if (ec)
            throw DatabaseError("cannot copy image " + from + " to " + target + ": " +
                                ec.message());
    } else if (!src.image.saveToFile(target)) {
        throw DatabaseError("cannot write image " + target);
    }
    auto out = mrpt::obs::CObservationImage::Create();
    out->sensorLabel = src.sensorLabel;
    out->timestamp = src.timestamp;
    out->cameraPose = src.cameraPose;
    out->cameraParams = src.cameraParams;
    out->image.setExternalStorage(name);
    return out;
}

}  // namespace

DatabaseWriter::DatabaseWriter(const std::string& out_dir) : out_dir_(normalised(out_dir)) {
    std::error_code ec;
    fs::create_directories(fs::path(out_dir_).parent_path(), ec);
    std::string templ = out_dir_ + ".tmp-XXXXXX";
    if (mkdtemp(templ.data()) == nullptr) {
        throw DatabaseError(out_dir_ + ": cannot create a staging folder beside it");
    }
    staging_ = templ;
    rawlog_ = std::make_unique<common::RawlogWriter>(staging_ + "/" + kRefsRawlog);
}

DatabaseWriter::~DatabaseWriter() {
    if (committed_) return;
    rawlog_.reset();
    std::error_code ec;
    fs::remove_all(staging_, ec);  // a failed survey leaves nothing behind
}

uint32_t DatabaseWriter::add(const ReferenceInput& in) {
    if (!in.ceiling) throw DatabaseError("DatabaseWriter::add: reference without ceiling image");
    const auto id = static_cast<uint32_t>(references_.size());
    char stem[32];
    std::snprintf(stem, sizeof(stem), "%06u", id);
    const std::string images_dir = rawlog_->imagesDirectory();

    Reference ref;
    ref.id = id;
    ref.traverse = in.traverse;
    ref.time_s = mrpt::Clock::toDouble(in.ceiling->timestamp);
    ref.vehicle_pose = in.vehicle_pose;
    ref.vehicle_cov = in.vehicle_cov;
    ref.ceiling_camera_mount = in.ceiling->cameraPose;
    ref.ceiling_camera_pose = in.vehicle_pose + in.ceiling->cameraPose;
    ref.sharpness = in.sharpness;
    ref.mean_intensity = in.mean_intensity;
    ref.travelled_m = in.travelled_m;

    const std::string ceiling_name = std::string("ceiling_") + stem +
                                     extensionOf(in.ceiling->image.isExternallyStored()
                                                     ? in.ceiling->image.getExternalStorageFile()
                                                     : "",
                                                 ".png");
    auto ceiling = externalCopy(*in.ceiling, images_dir, ceiling_name);
    ref.ceiling_image_path = images_dir + "/" + ceiling_name;
    rawlog_->write(*ceiling);

    std::string forward_name;
    if (in.forward) {
        forward_name = std::string("forward_") + stem +
                       extensionOf(in.forward->image.isExternallyStored()
                                       ? in.forward->image.getExternalStorageFile()
                                       : "",
                                   ".png");
        auto forward = externalCopy(*in.forward, images_dir, forward_name);
        rawlog_->write(*forward);
        ref.has_forward = true;
        ref.forward_time_s = mrpt::Clock::toDouble(in.forward->timestamp);
        ref.forward_image_path = images_dir + "/" + forward_name;
        ref.forward_camera_pose = in.forward_vehicle_pose + in.forward->cameraPose;
    }

    mrpt::obs::CObservationRobotPose pose;
    pose.sensorLabel = kPoseLabel;
    pose.timestamp = in.ceiling->timestamp;
    pose.pose.mean = in.vehicle_pose;
    // CPose3DPDFGaussian orders (x, y, z, yaw, pitch, roll); ours is (x, y, yaw).
    const int map_index[3] = {0, 1, 3};
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            pose.pose.cov(map_index[r], map_index[c]) = in.vehicle_cov(r, c);
    rawlog_->write(pose);

    obs::CObservationLookupReference record;
    record.sensorLabel = kReferenceLabel;
    record.timestamp = in.ceiling->timestamp;
    record.sensorPose = in.ceiling->cameraPose;
    record.reference_id = id;
    record.traverse = in.traverse;
    record.vehicle_pose = in.vehicle_pose;
    record.vehicle_cov = in.vehicle_cov;
    record.ceiling_camera_pose = ref.ceiling_camera_pose;
    record.forward_camera_pose = ref.forward_camera_pose;
    record.ceiling_image_file = ceiling_name;
    record.forward_image_file = forward_name;
    record.forward_time_s = ref.forward_time_s;
    record.sharpness = in.sharpness;
    record.mean_intensity = in.mean_intensity;
    record.travelled_m = in.travelled_m;
    rawlog_->write(record);

    references_.push_back(std::move(ref));
    return id;
}

void DatabaseWriter::setMap(const mrpt::maps::COccupancyGridMap2D& map) {
    const std::string grid = staging_ + "/" + kMapGrid;
    {
        mrpt::io::CFileGZOutputStream f;
        if (!f.open(grid)) throw DatabaseError(grid + ": cannot open for writing");
        auto arch = mrpt::serialization::archiveFrom(f);
        arch << map;
    }
    if (!map.saveAsBitmapFile(staging_ + "/" + kMapPng)) {
        throw DatabaseError(staging_ + "/" + kMapPng + ": cannot write");
    }
    has_map_ = true;
}

void DatabaseWriter::writeTextFile(const std::string& name, const std::string& content) {
    const std::string path = staging_ + "/" + name;
    std::ofstream out(path);
    out << content;
    if (!out) throw DatabaseError(path + ": cannot write");
}

void DatabaseWriter::commit(DatabaseInfo info) {
    if (committed_) throw DatabaseError(out_dir_ + ": database already committed");
    try {
        rawlog_->close();
    } catch (const std::exception& e) {
        throw DatabaseError(e.what());
    }
    common::PoseTrack track;
    for (const auto& r : references_) track.push_back({r.time_s, r.vehicle_pose});
    try {
        common::writeTumPoseFile(staging_ + "/" + kRefsTum, track);
    } catch (const std::exception& e) {
        throw DatabaseError(e.what());
    }
    info.reference_count = references_.size();
    info.map_file = has_map_ ? kMapGrid : "";
    writeDatabaseInfo(staging_ + "/" + kDbIni, info);

    // Swap into place: the old database is only removed once the new one is there.
    std::error_code ec;
    std::string old;
    if (fs::exists(out_dir_)) {
        old = staging_;
        old.replace(old.rfind(".tmp-"), 5, ".old-");
        fs::rename(out_dir_, old, ec);
        if (ec)
            throw DatabaseError(out_dir_ + ": cannot move the old database aside: " + ec.message());
    }
    fs::rename(staging_, out_dir_, ec);
    if (ec) {
        std::error_code ignored;
        if (!old.empty()) fs::rename(old, out_dir_, ignored);
        throw DatabaseError(out_dir_ + ": cannot rename " + staging_ +
                            " into place: " + ec.message());
    }
    committed_ = true;
    if (!old.empty()) fs::remove_all(old, ec);
}

}  // namespace lookup::database

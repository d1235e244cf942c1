#pragma once
// The reference database's data model (paper Sec. III-A): what one reference is, and the
// database-wide metadata stored in db.ini. See docs/survey.md for the folder layout.

#include <mrpt/img/TCamera.h>
#include <mrpt/math/CMatrixFixed.h>
#include <mrpt/poses/CPose3D.h>

#include <cstdint>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "lookup/common/stamp_row.h"

namespace lookup::database {

/// File names inside a database folder.
inline constexpr const char* kRefsRawlog = "refs.rawlog";     ///< records of every reference
inline constexpr const char* kRefsImagesDir = "refs_Images";  ///< external images of refs.rawlog
inline constexpr const char* kRefsTum = "refs.tum";           ///< reference vehicle poses, TUM
inline constexpr const char* kDbIni = "db.ini";               ///< DatabaseInfo
inline constexpr const char* kMapGrid = "map.gridmap.gz";     ///< COccupancyGridMap2D (gz)
inline constexpr const char* kMapPng = "map.png";             ///< the grid as an image
inline constexpr const char* kReport = "survey_report.json";  ///< lookup-survey's report

/// Sensor labels of the records written to refs.rawlog for each reference.
inline constexpr const char* kPoseLabel = "SURVEY_POSE";      ///< CObservationRobotPose
inline constexpr const char* kReferenceLabel = "LOOKUP_REF";  ///< CObservationLookupReference

/// Reference::source (and traverse) of the references a localiser run adds in memory.
inline constexpr const char* kOnlineSource = "online";

/// A database folder that cannot be read or written: the message names the file (and record).
class DatabaseError : public std::runtime_error {
  public:
    using std::runtime_error::runtime_error;
};

/// One reference: a surveyed ceiling image (and the forward image nearest in time).
struct Reference {
    uint32_t id = 0;                    ///< index in the database (dense, 0-based)
    std::string traverse;               ///< survey traverse name
    double time_s = 0;                  ///< ceiling image time stamp [s, mrpt::Clock::toDouble]
    mrpt::poses::CPose3D vehicle_pose;  ///< vehicle (base) pose in the map frame [m, rad]
    mrpt::math::CMatrixDouble33 vehicle_cov;    ///< covariance of (x [m], y [m], yaw [rad])
    mrpt::poses::CPose3D ceiling_camera_pose;   ///< ceiling camera in the map frame
    mrpt::poses::CPose3D ceiling_camera_mount;  ///< ceiling camera on the vehicle
    /// Intrinsics and distortion of the ceiling image (databases written before references
    /// kept their own give every reference DatabaseInfo::ceiling_camera).
    mrpt::img::TCamera ceiling_camera;
    std::string ceiling_image_path;            ///< absolute path of the ceiling image
    bool has_forward = false;                  ///< whether a forward image is attached
    double forward_time_s = 0;                 ///< forward image time stamp [s]
    std::string forward_image_path;            ///< absolute path of the forward image ("" if none)
    mrpt::poses::CPose3D forward_camera_pose;  ///< forward camera in the map frame
    double sharpness = 0;                      ///< variance of the Laplacian of the ceiling image
    double mean_intensity = 0;                 ///< mean grey level of the ceiling image [0..255]
    double travelled_m = 0;                    ///< distance along the traverse [m]
    /// "survey", or "refresh": an operating drive's image added where the ceiling changed
    /// (lookup-survey --refresh), or kOnlineSource: one the localiser added in memory during
    /// its run (ReferenceDatabase::addInMemory).
    std::string source = "survey";
    /// The operating drive over which this reference no longer matched ("" = current). A
    /// superseded reference stays in the database but no spatial query returns it.
    std::string superseded_by;

    bool current() const { return superseded_by.empty(); }
};

/// Database-wide metadata (db.ini).
struct DatabaseInfo {
    std::string name;  ///< free text, e.g. the dataset name
    std::string ceiling_camera_label = "CEILING_CAM";
    std::string forward_camera_label = "FORWARD_CAM";
    /// Intrinsics of the first reference's ceiling camera: the camera the localiser rectifies
    /// every ceiling image into (lookup::refine::Rectifier), and the camera of references
    /// stored without their own.
    mrpt::img::TCamera ceiling_camera;
    mrpt::img::TCamera forward_camera;  ///< intrinsics of the forward camera
    double ceiling_height_m = 0;  ///< ceiling height above the floor (prior for refinement) [m]
    /// The survey ceiling camera's rolling shutter ([survey] ceiling_readout_ms): first row to
    /// last row [ms], 0 = a global shutter; and the row its stamp (offset applied) refers to,
    /// "first" or "middle". db.ini lists them only for a rolling shutter.
    double ceiling_readout_ms = 0;
    common::StampRow ceiling_stamp_row = common::StampRow::First;
    /// How well the survey ceiling camera's stamps are known against its laser poses, its time
    /// offset applied (the survey's applied sigma) [s]; absent in databases written before it
    /// was recorded, or with poses from a file: unknown.
    std::optional<double> ceiling_time_offset_sigma_s;
    std::vector<std::string> source_rawlogs;  ///< absolute paths of the survey rawlogs
    std::string pose_source;                  ///< "laser" (ICP-SLAM + MCL) or "file:<path>"
    std::string map_file;                     ///< map file name in the folder ("" if none)
    std::size_t reference_count = 0;          ///< filled by the writer
    /// Options used to build the database, as .ini text (copied into db.ini verbatim).
    std::string options_ini;
    /// Heat-map files (one per reference, relative to the folder) written later by the FCN
    /// trainer into db.ini [heatmaps]; empty when none yet.
    std::string heatmaps_dir;
};

/// Reads db.ini strictly (errors name the file, section and key).
DatabaseInfo readDatabaseInfo(const std::string& db_ini_path);
/// Writes db.ini (sections [database], [ceiling_camera], [forward_camera], [heatmaps] and the
/// options text).
void writeDatabaseInfo(const std::string& db_ini_path, const DatabaseInfo& info);

}  // namespace lookup::database

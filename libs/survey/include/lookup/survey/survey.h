#pragma once
// The survey: rawlogs in, reference database out (paper Sec. III-A, "reference database"),
// with laser-derived poses (ICP-SLAM map + MCL per traverse, see laser_poses.h) or a surveyed
// pose file, a pose per ceiling image by time (vehicle pose ⊕ camera mounting pose), keyframes
// by travel, and a report with reference-pose errors when ground truth exists.

#include <mrpt/config/CConfigFileMemory.h>

#include <string>
#include <vector>

#include "lookup/common/config.h"
#include "lookup/survey/ceiling_distance.h"
#include "lookup/survey/image_quality.h"
#include "lookup/survey/laser_poses.h"
#include "lookup/survey/lidar_sweep.h"
#include "lookup/survey/pose_audit.h"
#include "lookup/survey/pose_graph.h"
#include "lookup/survey/survey_options.h"
#include "lookup/survey/time_offset.h"

namespace lookup::survey {

/// One input traverse.
struct TraverseSpec {
    std::string name;          ///< e.g. "middle"
    std::string rawlog;        ///< path of the rawlog
    std::string ground_truth;  ///< MRPT .GT.txt or TUM ("" = none); only for the report
    bool mapping = true;       ///< used to build the map (the first such traverse is)
    bool reference = true;     ///< its ceiling images become references
};

/// SurveyInputs::poses_file value meaning "each traverse's own ground-truth file" (surveyed
/// poses per traverse, e.g. from a total station), instead of one pose file for all.
inline constexpr const char* kPosesFromGroundTruth = "ground-truth";

struct SurveyInputs {
    std::vector<TraverseSpec> traverses;
    std::string out_dir;     ///< database folder to (re)create
    std::string poses_file;  ///< surveyed poses replacing the laser stage ("" = laser,
                             ///< kPosesFromGroundTruth = each traverse's ground truth)
    std::string map_file;    ///< existing grid map replacing ICP-SLAM ("" = build one)
    std::string name;        ///< database name (e.g. the dataset's)
    /// A dataset's stated ceiling height (0 = none): used only with
    /// SurveyOptions::use_dataset_ceiling_height, else ignored with a note.
    double ceiling_height_m = 0;
    /// The dataset's operator start pose of the mapping traverse ("x y yaw_deg", "" = none);
    /// SurveyOptions::start_pose overrides it.
    std::string start_pose;
    /// ... and its end pose ("" = none); SurveyOptions::end_pose overrides it.
    std::string end_pose;
    /// ... and its marks along the drive ("" = none); SurveyOptions::marks overrides them.
    std::string marks;
    bool show_progress = false;  ///< progress bar on stderr
};

/// Reference-pose error against ground truth (planar position and heading).
struct PoseErrorStats {
    std::size_t count = 0;
    double mean_m = 0, p95_m = 0, max_m = 0;  ///< position error [m]
    double mean_yaw_deg = 0;                  ///< |heading error| mean [deg]
};

/// A stretch of a traverse (by distance travelled) and its reference-pose error.
struct SegmentError {
    double from_m = 0, to_m = 0;  ///< travelled distance range [m]
    double x = 0, y = 0;          ///< map position at the segment's middle reference [m]
    PoseErrorStats error;
};

struct TraverseReport {
    std::string name;
    std::size_t ceiling_frames = 0;       ///< ceiling images in the rawlog
    std::size_t frames_without_pose = 0;  ///< outside the pose track (dropped)
    std::size_t references = 0;           ///< kept as references
    std::size_t rejected_blur = 0;
    std::size_t rejected_exposure = 0;
    std::size_t rejected_image = 0;    ///< ceiling images unreadable, empty or of the wrong size
    std::size_t rejected_forward = 0;  ///< forward images unreadable, empty or of the wrong size
    std::size_t rejected_audit = 0;    ///< frames in a stretch the images contradict (pose_audit.h)
    std::size_t without_forward = 0;   ///< references with no forward image in time
    SkippedRecords skipped;            ///< sensor records refused while reading the rawlog
    std::size_t scans_deskewed = 0;    ///< lidar scans redrawn for the motion over their sweep
    LevellingReport levelling;         ///< odometry and scans projected onto the horizontal
    std::string first_image_problem;   ///< the first refused image: file and reason
    ImageQuality ceiling_images;       ///< medians over the references' ceiling images
    /// The survey camera's lens as judged over the references (LensShading): images the mean
    /// took, the share of the image behind dirt, the least transmission, and whether the
    /// references were corrected.
    struct Lens {
        std::size_t images = 0;
        double dirty_share = 0, least_transmission = 1;
        bool corrected = false;
    } lens;
    double localisation_time_s = 0;     ///< MCL (or ICP-SLAM) wall time for this traverse
    std::string start_source;           ///< "map origin", "ground truth" or "scan match"
    mrpt::poses::CPose2D start;         ///< first scan's pose in the map frame
    double start_goodness = 0;          ///< ICP goodness of the scan-matched start
    std::size_t start_tied_places = 0;  ///< other places its start's fit tied with
    std::string start_ceiling;          ///< what the ceiling made of the tie (StartFix::ceiling)
    bool has_ground_truth = false;
    PoseErrorStats error;                ///< over the references (when ground truth)
    std::vector<SegmentError> segments;  ///< error per 10 m of travel (when ground truth)
};

/// One warning line per kind of refused input of a traverse, and one where its references'
/// ceiling images are dim or saturated enough to cost fixes (`o.warn_*`).
std::vector<std::string> traverseWarnings(const TraverseReport& r, const std::string& rawlog,
                                          const SurveyOptions& o);

/// How the map frame was tied to the operator's end mark (SurveyOptions::end_pose).
struct EndMarkReport {
    bool given = false;                    ///< an end pose was given (and a laser map built)
    bool used = false;                     ///< ... and agreed with the map within its uncertainty
    double disagreement_m = 0;             ///< end mark against the map's last pose, before [m]
    double disagreement_deg = 0;           ///< ... in heading [deg]
    double chi2 = 0;                       ///< of every used mark's residual after the fit
    mrpt::poses::CPose2D correction;       ///< rigid correction applied about the start [m, rad]
    double std_xy_m = 0, std_yaw_deg = 0;  ///< the map frame's uncertainty at the start after it
};

/// A surveyed mark along the mapping drive (SurveyOptions::marks) against the map.
struct DriveMarkReport {
    double time_s = 0;
    bool used = false;  ///< agreed with the map and the other marks within their uncertainty
    double disagreement_m = 0;    ///< against the map's pose at its time, before the fit [m]
    double disagreement_deg = 0;  ///< ... in heading [deg]
    double residual_m = 0;        ///< after the fit [m]
};

enum class SurveyStatus { Ok, Failed };

struct SurveyResult {
    SurveyStatus status = SurveyStatus::Failed;
    std::string reason;  ///< why it failed (file, record, reason), one line
    std::string detail;  ///< the full error text (MRPT call stack), for --verbose
    int exit_code = 0;   ///< common::kExit* of the failure
    std::string out_dir;
    std::string pose_source;  ///< "laser", "laser+map:<file>" or "file:<path>"
    std::size_t references = 0;
    double total_time_s = 0, mapping_time_s = 0, localisation_time_s = 0, writing_time_s = 0;
    PoseGraphReport pose_graph;    ///< keyframes = 0: no pose graph was optimised
    std::uint64_t size_bytes = 0;  ///< database folder size
    std::vector<TraverseReport> traverses;
    CeilingDistanceEstimate ceiling;  ///< the database's ceiling height and how it was found
    std::string ceiling_source;       ///< "estimated", "configured" or "dataset"
    /// Each camera's time offset against the pose track (ceiling, then forward), as applied.
    std::vector<TimeOffsetEstimate> time_offsets;
    LidarSweepEstimate lidar_sweep;  ///< the lidar's sweep as applied to every scan
    PoseAudit pose_audit;            ///< the laser poses checked by the images
    /// The ceiling camera's offset from the audit's fixes across traverses (tried when the
    /// image motion did not pin it down; applied, and copied into time_offsets, if estimated).
    TimeOffsetEstimate time_offset_across;
    EndMarkReport end_mark;  ///< the map frame tied to the end mark (and the drive's marks)
    std::vector<DriveMarkReport> drive_marks;  ///< the marks along the drive, when given
    /// Refused or skipped input, one line each (file, record, reason, count); lookup-survey
    /// prints them on stderr.
    std::vector<std::string> warnings;

    bool ok() const { return status == SurveyStatus::Ok; }
    /// The one-line summary lookup-survey prints.
    std::string summaryLine() const;
    /// survey_report.json contents.
    std::string toJson() const;
};

class Survey {
  public:
    /// `config`: the whole .ini (the [survey] section must already be in `options`; the MRPT
    /// sections of the laser stage are read from here).
    Survey(SurveyOptions options, const mrpt::config::CConfigFileBase& config);

    /// Runs the survey. Never throws for bad input: a failure is returned with its reason,
    /// and leaves no database folder behind (and an existing one intact).
    SurveyResult run(const SurveyInputs& inputs) const;

  private:
    /// The database's ceiling height: estimated from the images (ceiling_distance.h), or the
    /// configured / dataset value as the options say; recorded in `result`.
    double ceilingHeight(const SurveyInputs& in, const std::vector<TraverseData>& data,
                         const std::vector<LaserTrack>& tracks, SurveyResult& result) const;

    /// The lidar's sweep: estimated from the mapping traverse's scans (lidar_sweep.h) unless
    /// disabled, every traverse's scans de-skewed with it, recorded in `result`.
    void lidarSweep(const SurveyInputs& in, std::vector<TraverseData>& data,
                    SurveyResult& result) const;
    /// The ceiling camera's time offset: estimated from the images (time_offset.h) unless
    /// disabled, applied to the traverses' ceiling stamps, recorded in `result` with the
    /// forward camera's configured one.
    void timeOffsets(const SurveyInputs& in, std::vector<TraverseData>& data,
                     const std::vector<LaserTrack>& tracks, double ceiling_height_m,
                     SurveyResult& result) const;

    /// The reference traverses' laser poses checked against one another's images
    /// (pose_audit.h), recorded in `result` with a warning per suspect stretch. Where the
    /// ceiling camera's offset was not estimated from the image motion, the audit's fixes
    /// across traverses may estimate it: then it is applied to the stamps and the audit rerun.
    void auditPoses(const SurveyInputs& in, std::vector<TraverseData>& data,
                    const std::vector<LaserTrack>& tracks, double ceiling_height_m,
                    SurveyResult& result) const;

    SurveyOptions options_;
    PoseGraphOptions graph_options_;
    common::NamedConfigFile config_;  ///< a copy of the whole .ini, named as its source
};

}  // namespace lookup::survey

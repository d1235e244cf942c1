#pragma once
// Options of lookup-survey ([survey] section of share/lookup/survey.ini). The laser stage's
// MRPT components read their own sections of the same file, exactly as MRPT's icp-slam and
// pf-localization apps do: [MappingApplication] (CMetricMapBuilderICP::TConfigParams with the
// map definition), [ICP] (CICP::TConfigParams), [PF_options] (CParticleFilter),
// [KLD_options] (TKLDParams) and [LikelihoodOptions] (the grid's scan likelihood for MCL).

#include <mrpt/config/CLoadableOptions.h>
#include <mrpt/poses/CPose2D.h>

#include <optional>

#include <string>
#include <vector>

#include "lookup/common/options_table.h"
#include "lookup/common/stamp_row.h"
#include "lookup/database/refresh_bridge.h"
#include "lookup/refine/lens_shading.h"

namespace lookup::survey {

struct SurveyOptions : public common::TableOptions<SurveyOptions> {
    // --- sensor labels -----------------------------------------------------------------
    std::string ceiling_camera_label = "CEILING_CAM";  ///< CObservationImage, looking up
    std::string forward_camera_label = "FORWARD_CAM";  ///< CObservationImage ("" = none)
    std::string lidar_label = "LIDAR";                 ///< CObservation2DRangeScan
    std::string odometry_label = "ODOMETRY";           ///< CObservationOdometry
    /// CObservationIMU with IMU_PITCH and IMU_ROLL (an inclinometer): odometry and scans are
    /// projected onto the horizontal (levelling.h). Absent from a rawlog: level ground assumed.
    std::string imu_label = "IMU";
    /// With it, lidar returns less than this above the floor ahead are dropped (levelling.h):
    /// above the floor's relief, below any scan plane's height [m] (0 = keep all).
    double floor_return_margin_m = 0.3;
    /// ... and returns more than this above the scanner's own height over the floor (the scan
    /// plane meeting the roof ahead): on a constant grade every wall return lies at that height
    /// within the floor's relief; 1 m keeps the walls up to ~12 m ahead in a 10 m vertical curve
    /// of 8° [m] (0 = keep all).
    double roof_return_margin_m = 1.0;

    // --- keyframes (paper Sec. III-A: references sampled along the survey) ---------------
    double keyframe_spacing_m = 0.25;  ///< travel between kept references [m]
    /// Dirt on the survey camera's lens, found in the mean of each traverse's references and
    /// divided out of them before they are stored (lens_shading.h; the lens_* keys, as the
    /// localiser's): the references show the ceiling, not the blotches, as the vehicle's
    /// corrected images do.
    refine::LensShadingOptions lens;
    double min_sharpness = 10.0;         ///< min variance of Laplacian [grey^2]; below = blurred
    double min_mean_intensity = 3.0;     ///< darker mean grey level = no light [0..255]
    double max_mean_intensity = 250.0;   ///< brighter mean grey level = washed out [0..255]
    double max_clipped_fraction = 0.95;  ///< max share of pixels at <=2 or >=253 [0..1]
    /// A traverse whose references' median mean grey level is below this, or whose median
    /// clipped share is above that, is said as a warning: the camera localises, but dim images
    /// delay the first fix and saturated ones lose refined frames (docs/vehicle.md).
    double warn_dim_mean_intensity = 10.0;
    double warn_clipped_fraction = 0.5;
    /// Ceiling images are stored (and so matched) averaged down to at most this width, their
    /// intrinsics scaled with them: the matcher's pixel settings hold for any camera, and a
    /// finer image costs time without a finer fix (docs/benchmarks.md, "Camera resolution")
    /// [px]; 0 = as recorded.
    int ceiling_max_width_px = 320;

    // --- time association -----------------------------------------------------------------
    double forward_max_dt_s = 0.25;  ///< max |t_forward - t_ceiling| to attach a forward image [s]
    double max_pose_gap_s = 1.0;     ///< no pose interpolation across larger gaps [s]
    /// Share of ceiling images allowed outside the pose track (start/end); more = mismatched
    /// time stamps, an error.
    double max_outside_fraction = 0.2;

    // --- geometry -------------------------------------------------------------------------
    /// Prior of the ceiling plane's height above the vehicle base (the refiner's h, so the
    /// camera-to-ceiling distance is h minus the camera mount's z) [m]. The survey estimates h
    /// from the images (ceiling_distance.h) and uses this value only when that fails.
    double ceiling_height_m = 5.0;
    bool ceiling_estimate = true;           ///< estimate h from image triples (else: the prior)
    double ceiling_sample_spacing_m = 2.0;  ///< travel between sampled frames [m]
    double ceiling_baseline_m = 1.0;        ///< travel to each of the two neighbours [m]
    double ceiling_prior_sigma_m = 1.0;     ///< h prior of the estimates (weak: images decide) [m]
    int ceiling_min_pairs = 8;              ///< fewer accepted estimates = warning, prior used
    /// A dataset.ini's `ceiling_height_m` (old lookup-sim output: the simulator's truth) is
    /// ignored with a note unless this is set; then it replaces the estimate.
    bool use_dataset_ceiling_height = false;

    // --- camera time offsets (time_offset.h) ------------------------------------------------
    /// Added to each camera's time stamps to put them on the lidar / odometry clock [s] (a
    /// camera stamping 30 ms after the exposure: -0.030). The ceiling camera's is the start of
    /// the estimate (time_offset_estimate), the forward camera's is used as configured.
    double ceiling_time_offset_s = 0;
    double forward_time_offset_s = 0;
    /// Standard deviation of the configured ceiling_time_offset_s (its calibration's) [s]. When
    /// the images do not pin the offset down, it (or the fit's, if tighter) is the applied
    /// offset's, and every reference's covariance grows by speed x it along the motion.
    double ceiling_time_offset_sigma_s = 0.05;
    /// The ceiling camera's rolling shutter, first row to last row [ms] (0 = a global shutter),
    /// and the row its stamp refers to once ceiling_time_offset_s is applied ("first" or
    /// "middle"): stored in the database, where the localiser sees each reference's rows from
    /// the survey vehicle's poses at their times.
    double ceiling_readout_ms = 0;
    common::StampRow ceiling_stamp_row = common::StampRow::First;
    bool time_offset_estimate = true;  ///< estimate the ceiling camera's offset from the images
    double time_offset_max_s = 0.2;    ///< search range around the configured offset [s]
    /// A fit not trusted as the offset that lies farther than this (and 3 sigmas) from the
    /// configured offset contradicts it: the configured offset's sigma is widened to cover the
    /// fit [s]. Above the fit's bias on a ceiling with relief.
    double time_offset_contradiction_s = 0.15;
    double time_offset_baseline_m = 0.5;  ///< travel between the two images of a pair [m]
    int time_offset_max_pairs = 300;      ///< image pairs measured, at most
    int time_offset_min_pairs = 20;       ///< fewer usable pairs = warning, configured offset used
    /// A fit less certain than this (too little acceleration or turning) = warning, configured
    /// offset used [s].
    double time_offset_max_sigma_s = 0.005;
    /// The estimate across traverses (pose_audit.h) counts only fixes where the two traverses'
    /// velocities differ by this much (driven in opposite directions, or at other speeds) [m/s].
    double time_offset_min_velocity_difference_mps = 2.0;

    // --- the laser poses checked by the images (pose_audit.h) ------------------------------
    bool pose_audit = true;
    double pose_audit_spacing_m = 2.0;  ///< travel between audited frames of a traverse [m]
    /// Another traverse's camera this near an audited frame's saw most of its ceiling [m].
    double pose_audit_view_distance_m = 1.5;
    /// A frame that matches nothing at its laser pose is searched this far along its heading
    /// on each side [m].
    double pose_audit_search_m = 3.0;
    /// A fix farther than this from the frame's laser pose contradicts it [m].
    double pose_audit_max_disagreement_m = 0.4;

    // --- laser stage (ICP-SLAM map, then MCL per traverse) ---------------------------------
    int mcl_particles = 600;              ///< particles of CMonteCarloLocalization2D
    double mcl_init_std_xy_m = 0.2;       ///< spread of the initial particles around the start [m]
    double mcl_init_std_yaw_deg = 3.0;    ///< ... and in yaw [deg]
    double odometry_min_std_xy_m = 0.04;  ///< CActionRobotMovement2D gaussian minStdXY [m]
    double odometry_min_std_yaw_deg = 2.0;  ///< ... minStdPHI [deg]
    /// Diagnostic only: start ICP-SLAM and every MCL at the first ground-truth pose when a GT
    /// file exists. Off: the map frame is `start_pose` (or the dataset's) and every other
    /// traverse is found in the map by scan matching (start_search.h).
    bool start_at_ground_truth = false;
    /// Operator's start pose of the mapping traverse, "x y yaw_deg" in mine coordinates
    /// ("" = the dataset's `start_pose`, else the origin). Defines the map frame.
    std::string start_pose;
    /// Its standard deviation (a vehicle parked over a surveyed mark, aligned by eye with a
    /// painted line), carried by every reference's covariance as a rigid error of the map [m] /
    /// [deg].
    double start_pose_std_xy_m = 0.05;
    double start_pose_std_yaw_deg = 0.1;
    /// Operator's end pose of the mapping traverse: the vehicle at rest over a second surveyed
    /// mark at its last lidar scan, "x y yaw_deg" ("" = the dataset's `end_pose`, else none).
    /// The map is turned and moved rigidly to agree with both marks (docs/survey.md).
    std::string end_pose;
    double end_pose_std_xy_m = 0.05;    ///< its standard deviation [m]
    double end_pose_std_yaw_deg = 0.1;  ///< ... in heading [deg]
    /// Operator's marks along the mapping traverse: the vehicle at rest over a surveyed mark at
    /// rawlog time t, "t x y yaw_deg; t x y yaw_deg; ..." ("" = the dataset's `marks`, else
    /// none). Fitted with the start and end marks; one that disagrees with the others and the
    /// map is left out, with a warning (docs/survey.md).
    std::string marks;
    double marks_std_xy_m = 0.05;         ///< each one's standard deviation [m]
    double marks_std_yaw_deg = 0.1;       ///< ... in heading [deg]
    double start_search_spacing_m = 1.0;  ///< spacing of the start guesses along the map [m]
    double start_match_travel_m = 4.0;    ///< scans of the first metres matched together [m]
    double start_min_goodness = 0.5;      ///< a start with a lower ICP goodness is an error
    /// Start fits tied along a uniform drive are decided by the ceiling images (start_search.h).
    bool start_by_ceiling = true;
    /// Lidar returns farther than this are dropped before ICP-SLAM [m] (0 = keep all). Far
    /// returns graze the walls of a long drive sparsely and match the frontier of the map
    /// built so far, which pulls every scan back and shrinks the map along the drive.
    double icp_max_range_m = 0;
    /// Time the lidar takes from its first ray to its last (the scanner's data sheet: a 270°
    /// aperture at 10 Hz sweeps in 75 ms); every scan is de-skewed with the odometry's motion
    /// over it (scan_deskew.h). The time stamp refers to the first ray. 0 = instantaneous [ms].
    double lidar_sweep_ms = 0;
    /// Estimate the sweep from the scans (lidar_sweep.h), lidar_sweep_ms being the fallback;
    /// on the first lidar_sweep_estimate_m of the mapping traverse's travel [m].
    bool lidar_sweep_estimate = true;
    double lidar_sweep_estimate_m = 100;
    /// Error of the ICP-SLAM map itself, added to every laser pose's covariance: MCL's particle
    /// spread is relative to the map and alone is over-confident (docs/benchmarks.md) [m].
    double map_std_xy_m = 0.08;
    double map_std_yaw_deg = 0.3;  ///< ... in heading [deg]

    // --- pose file (--poses) ---------------------------------------------------------------
    double pose_file_std_xy_m = 0.02;    ///< stated std of surveyed positions [m]
    double pose_file_std_yaw_deg = 0.5;  ///< stated std of surveyed headings [deg]
    // --- refresh from an operating drive (--refresh, refresh.h): the refresh_* keys ---------
    database::RefreshOptions refresh;

    /// Adds every key of its .ini section to `t` (load, save and the unknown-key check).
    void declareKeys(common::OptionsTable& t);
    /// Throws common::ConfigError naming every invalid field.
    void check() const;
};

/// "x y yaw_deg" (blank-separated, finite) as a pose; nullopt when malformed. Start and end
/// poses alike.
std::optional<mrpt::poses::CPose2D> parseStartPose(const std::string& text);

/// A surveyed mark the vehicle stood over at a time of the mapping traverse.
struct TimedMark {
    double time_s = 0;
    mrpt::poses::CPose2D pose;
};

/// "t x y yaw_deg; t x y yaw_deg; ..." (SurveyOptions::marks) as marks; nullopt when any one
/// is malformed. "" gives none.
std::optional<std::vector<TimedMark>> parseMarks(const std::string& text);

}  // namespace lookup::survey

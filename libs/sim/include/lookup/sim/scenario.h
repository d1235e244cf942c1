#pragma once
// The scenario of a synthetic mine: world, vehicle, sensors and traverses, read strictly from an
// MRPT-style .ini file (share/lookup/scenarios/*.ini) and written back fully resolved as
// `scenario.ini` in every generated dataset. See docs/sim.md for the model behind each key.

#include <mrpt/config/CLoadableOptions.h>
#include <mrpt/poses/CPose3D.h>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "lookup/common/stamp_row.h"

namespace lookup::sim {

/// A sensor's mounting pose on the vehicle (vehicle frame: +x forward, +y left, +z up, origin on
/// the floor under the vehicle centre). Angles follow mrpt::poses::CPose3D (yaw about z, then
/// pitch about y, then roll about x).
struct MountPose {
    double x_m = 0, y_m = 0, z_m = 0;                 ///< translation [m]
    double yaw_deg = 0, pitch_deg = 0, roll_deg = 0;  ///< rotation [deg]
    mrpt::poses::CPose3D pose() const;
};

/// Tunnel network, ceiling texture and the 3-D furniture below the ceiling.
struct WorldOptions {
    std::string layout = "single";  ///< "single": one main tunnel (Mine B); "twin": two parallel
                                    ///< tunnels joined by a crosscut at the far end (Mine A)
    double length_m = 1000;         ///< length of the (each, for twin) main tunnel [m]
    double width_m = 5.5;           ///< tunnel width, wall to wall [m]
    double ceiling_height_m = 5.0;  ///< h: height of the quasi-planar ceiling above the floor [m]
    double arch_radius_m = 1.2;     ///< radius of the rounded corners between walls and roof [m]
    double segment_length_m = 80;   ///< mean length of straight centre-line pieces [m]
    double bend_max_deg = 10;       ///< largest heading change between pieces [deg]
    double twin_separation_m = 40;  ///< twin: distance between the two tunnels' centre lines [m]
    double drawpoint_spacing_m =
        40;  ///< distance between draw points along the tunnel, 0 = none [m]
    double drawpoint_length_m = 12;   ///< depth of a draw point (side opening) [m]
    double drawpoint_width_m = 4.5;   ///< width of a draw point [m]
    double drawpoint_angle_deg = 60;  ///< angle between a draw point and the tunnel axis [deg]
    double junction_spacing_m = 250;  ///< distance between crossing tunnels, 0 = none [m]
    double junction_length_m = 30;    ///< length of a crossing tunnel on each side [m]
    double bump_amplitude_m = 0.12;   ///< low-frequency ceiling relief amplitude (+-) [m]
    double bump_wavelength_m = 4.0;   ///< wavelength of that relief [m]
    double floor_roughness_m = 0.04;  ///< floor relief amplitude (gives vehicle pitch and roll) [m]
    double rock_contrast = 1.0;       ///< contrast of the multi-scale rock albedo (0 = flat grey)
    double bolt_spacing_m =
        1.3;                     ///< rock-bolt grid pitch along and across the tunnel, 0 = none [m]
    double bolt_plate_m = 0.15;  ///< side of a square bolt plate [m]
    double mesh_fraction = 0.35;      ///< share of the ceiling covered by weld mesh [0,1]
    double mesh_pitch_m = 0.1;        ///< weld-mesh pitch [m]
    double shotcrete_fraction = 0.3;  ///< share of the ceiling covered by shotcrete patches [0,1]
    std::string texture_image;        ///< optional grey image tiled as the rock albedo ("" = none)
    double texture_image_size_m = 4;  ///< ceiling extent covered by one tile of that image [m]
    double duct_radius_m = 0.35;      ///< ventilation duct radius, 0 = none [m]
    double duct_offset_m = 1.9;      ///< duct axis lateral offset from the centre line (+ left) [m]
    double duct_drop_m = 0.6;        ///< duct axis distance below the ceiling [m]
    double pipe_radius_m = 0.08;     ///< service pipe radius, 0 = none [m]
    double pipe_offset_m = -1.9;     ///< pipe lateral offset (+ left) [m]
    double pipe_drop_m = 0.35;       ///< pipe axis distance below the ceiling [m]
    double cable_offset_m = -0.9;    ///< hanging cable lateral offset (+ left) [m]
    double cable_span_m = 3.0;       ///< distance between cable hangers, 0 = no cable [m]
    double cable_sag_m = 0.15;       ///< cable sag at mid span [m]
    double light_spacing_m = 25;     ///< distance between tunnel lights, 0 = none [m]
    double sign_spacing_m = 60;      ///< mean distance between reflective wall signs, 0 = none [m]
    double grid_resolution_m = 0.1;  ///< occupancy-grid cell size (map.gridmap.gz, lidar) [m]
    /// Relief of the rock walls (+-) [m]: world-anchored multi-scale noise (wavelengths 4 m down
    /// to 0.5 m) that moves the wall surface in and out, in the occupancy grid (so the lidar
    /// sees it and is no longer degenerate along a straight drive) and in the rendered views.
    /// 0 = perfectly straight walls.
    double wall_roughness_m = 0.15;
    double niche_spacing_m = 30;  ///< mean distance between niches (alcoves) along a main
                                  ///< tunnel, random side, 0 = none [m]
    double niche_depth_m = 1.5;   ///< depth of a niche into the wall [m]
    double niche_width_m = 3.0;   ///< width of a niche's mouth along the wall [m]
    /// Grade profile along the route (declines, ramps between levels): comma list of ramps
    /// "S0 S1 G", the floor rising G metres per metre (negative: descending; "1:7" or "-1:7"
    /// also read) from route distance S0 to S1 [m]. Floor, roof, furniture and lamps follow
    /// it; empty = a level mine (the old geometry, bit for bit).
    std::string grade;
    double grade_transition_m = 20;  ///< length of the vertical curve at each ramp end [m]
};

/// One ramp of WorldOptions::grade.
struct GradeRamp {
    double start_m = 0, end_m = 0;  ///< route distances [m]
    double grade = 0;               ///< rise per metre along the route (negative: descending)
};

/// Parses WorldOptions::grade; throws std::invalid_argument saying which ramp is malformed or
/// steeper than 1:4 (what a rubber-tyred vehicle cannot climb).
std::vector<GradeRamp> parseGrade(const std::string& grade);

/// The vehicle body: where its wheels touch the floor (pitch and roll follow the floor relief).
struct VehicleOptions {
    std::string name = "light";  ///< free text, e.g. "heavy loader", "light vehicle"
    double wheelbase_m = 2.8;    ///< distance between axles [m]
    double track_m = 1.8;        ///< distance between left and right wheels [m]
};

/// When a sensor's record is stamped and whether it arrives at all (every sensor has its own).
struct SensorTiming {
    double latency_ms = 0;  ///< constant stamp offset, stamp = true time + latency (either sign)
    double jitter_ms = 0;   ///< standard deviation of a Gaussian stamp error, per record [ms]
    double drop_rate = 0;   ///< share of records lost in transmission [0, 1)
};

/// A grey camera rendered by ray casting: pinhole, optionally with lens distortion, rolling
/// shutter and the image effects of a real sensor (all off by default).
struct CameraOptions {
    std::string label;       ///< sensorLabel of its observations
    double rate_hz = 20;     ///< frame rate [Hz]
    double phase_s = 0;      ///< time of the first frame after the traverse start [s]
    int width_px = 320;      ///< image width [px]
    int height_px = 240;     ///< image height [px]
    double hfov_deg = 95;    ///< horizontal field of view [deg]; fx = fy, principal point centred
    MountPose mount;         ///< camera pose on the vehicle (+Z optical axis, MRPT convention)
    double exposure_ms = 4;  ///< exposure time, sets the motion-blur length [ms]
    double exposure_variation = 0.15;  ///< relative amplitude of per-frame exposure changes
    double noise_std_dn = 1.2;         ///< read-noise standard deviation [grey levels]
    double light_gain = 1.0;  ///< vehicle-light intensity (1: ceiling at nominal range ~ albedo)
    double light_falloff_exp = 1.5;  ///< vehicle-light beam: intensity ~ cos(off-axis)^exp
    double max_range_m = 60;         ///< rays beyond this see darkness [m]
    /// Lens distortion as a calibration records it (mrpt::img::DistortionModel names): "none",
    /// "plumb_bob" (radial-tangential k1, k2, p1, p2, k3) or "kannala_brandt" (fisheye k1..k4,
    /// read from dist_k1, dist_k2, dist_k3, dist_k4). fx, fy, cx, cy stay those of hfov_deg.
    std::string distortion = "none";
    double dist_k1 = 0, dist_k2 = 0, dist_p1 = 0, dist_p2 = 0, dist_k3 = 0, dist_k4 = 0;
    /// Rolling shutter: time from the first row's exposure to the last row's, 0 = global [ms].
    double readout_ms = 0;
    common::StampRow stamp_row = common::StampRow::First;  ///< row the time stamp refers to
    SensorTiming timing;
    double response_gamma = 1;         ///< output = linear^(1/gamma) (1: linear response)
    double response_knee_dn = 0;       ///< knee point, above it the slope drops, 0 = none [DN]
    double response_knee_slope = 0.3;  ///< slope above the knee (relative)
    /// Auto-exposure: the gain follows the mean grey level towards this target, 0 = off (fixed
    /// gain, with the exposure_variation drift) [DN].
    double auto_exposure_target_dn = 0;
    double auto_exposure_tau_s = 0.5;  ///< time constant of that control loop [s]
    double bloom_strength = 0;         ///< share of the light above saturation spread around [0, 1]
    double bloom_radius_px = 6;        ///< Gaussian radius of that spread [px]
    int dirt_spots = 0;                ///< fixed dark out-of-focus blotches on the lens
    double dirt_opacity = 0.35;        ///< light a blotch's centre blocks [0, 1)
    int water_drops = 0;               ///< fixed water drops (defocused discs) on the lens
    double drop_radius_px = 10;        ///< mean radius of a drop [px]
    double haze_extinction_per_m = 0;  ///< dust haze: light attenuation exp(-beta d) [1/m]
    double haze_airlight = 0.15;       ///< radiance of the lit haze at full depth (1 = white)
};

/// A horizontal 2-D scanner simulated by MRPT against the occupancy grid.
struct LidarOptions {
    std::string label = "LIDAR";
    double rate_hz = 10;          ///< scan rate [Hz]
    double phase_s = 0.027;       ///< time of the first scan after the traverse start [s]
    double aperture_deg = 270;    ///< field of view [deg]
    double resolution_deg = 0.5;  ///< angle between rays [deg]
    double max_range_m = 30;      ///< maximum range [m]
    double noise_std_m = 0.01;    ///< range noise standard deviation [m]
    /// Scanner pose on the vehicle; its height is the scan plane's (it must lie below the
    /// arch, above the floor).
    MountPose mount{1.9, 0.0, 1.2, 0.0, 0.0, 0.0};
    SensorTiming timing;
    /// Duration of one sweep from the first ray to the last; the vehicle moves during it (scan
    /// skew). The stamp refers to the first ray. 0 = instantaneous [ms].
    double sweep_ms = 0;
    double dust_rate = 0;         ///< share of rays returning from airborne dust [0, 1)
    double dust_max_range_m = 8;  ///< dust returns are uniform in [0.3, this] [m]
};

/// Wheel odometry: accumulated 2-D pose with scale error, yaw bias and noise.
struct OdometryOptions {
    std::string label = "ODOMETRY";
    double rate_hz = 50;               ///< record rate [Hz]
    double phase_s = 0.005;            ///< time of the first record after the traverse start [s]
    double scale_error = 0.01;         ///< relative distance error (0.01 = 1 % too long)
    double yaw_bias_deg_per_m = 0.02;  ///< heading drift per metre travelled [deg/m]
    double noise_std_m = 0.002;        ///< translation noise per record [m]
    double noise_std_deg = 0.02;       ///< heading noise per record [deg]
    SensorTiming timing;
    double slip_fraction = 0;     ///< share of the distance driven in wheel-slip episodes [0, 1]
    double slip_episode_m = 5;    ///< length of one slip episode [m]
    double slip_factor = 1.3;     ///< odometry distance / true distance while slipping
    double dropout_fraction = 0;  ///< share of the time in odometry dropouts (no records) [0, 1)
    double dropout_s = 2;         ///< duration of one dropout [s]
};

/// An inclinometer (the attitude output of the vehicle's IMU): pitch and roll against gravity,
/// one CObservationIMU (IMU_PITCH, IMU_ROLL) with every odometry record.
struct ImuOptions {
    /// Auto: on in a graded mine, where the survey needs it; off on the level, so that level
    /// datasets stay byte for byte what they were. On / Off force it.
    enum class Mode { Auto, On, Off };
    Mode enabled = Mode::Auto;
    bool activeIn(bool graded) const {
        return enabled == Mode::On || (enabled == Mode::Auto && graded);
    }
    std::string label = "IMU";
    /// An industrial MEMS unit's dynamic attitude accuracy (a few tenths of a degree).
    double noise_std_deg = 0.2;  ///< noise per record on pitch and roll [deg]
    double bias_std_deg = 0.5;   ///< spread of a per-traverse constant bias on each [deg]
};

/// One drive along the route.
struct TraverseOptions {
    std::string name;               ///< file stem of its rawlog, e.g. "left"
    std::string roles;              ///< comma list of mapping, reference, query, refresh
    double lateral_offset_m = 0;    ///< offset from the centre line (+ left) [m]
    double zigzag_amplitude_m = 0;  ///< amplitude of a sinusoidal lateral weave [m]
    double zigzag_period_m = 40;    ///< its period along the route [m]
    double speed_kmh = 20;          ///< cruise speed [km/h]
    double speed_variation = 0.15;  ///< relative slow variation of the cruise speed
    double accel_mps2 = 1.5;        ///< acceleration and braking at start and end [m/s^2]
    double start_m = 0;             ///< start along the route [m]
    double end_m = -1;              ///< end along the route, -1 = route end [m]
    /// "forward": start_m to end_m; "reverse": end_m to start_m, the vehicle facing its way.
    std::string direction = "forward";
    /// Duty cycle, replacing start-to-end: comma list of legs from start_m, "drive S" (to route
    /// position S [m], facing the way of travel), "reverse S" (backing up to S), "stop T"
    /// (stand still T [s]); "drive end" goes to the traverse's end (end_m, else the route's).
    /// The vehicle cannot turn round: all motion keeps one facing.
    std::string plan;
    /// The mapping traverse stops over a surveyed mark at every stop of its plan: dataset.ini
    /// gets the operator's mark of each (`marks`), with a mark's error (docs/sim.md).
    bool marks_at_stops = false;
    /// Per-traverse overrides ([traverse_i.SECTION]); empty = the scenario's section. The world
    /// override changes appearance keys only (the mine's geometry is one for all traverses).
    std::optional<WorldOptions> world;
    std::optional<VehicleOptions> vehicle;
    std::optional<CameraOptions> ceiling_camera;
    std::optional<CameraOptions> forward_camera;
    std::optional<LidarOptions> lidar;
    std::optional<OdometryOptions> odometry;
};

/// One leg of a traverse plan.
struct PlanLeg {
    enum class Kind { Drive, Reverse, Stop } kind = Kind::Drive;
    /// Target route position [m] (Drive, Reverse; infinity: "end", the traverse's end) or
    /// dwell [s] (Stop).
    double value = 0;
};

/// Parses TraverseOptions::plan; throws std::invalid_argument saying which leg is malformed.
std::vector<PlanLeg> parsePlan(const std::string& plan);

/// The whole scenario. Sections: [scenario], [world], [vehicle], [ceiling_camera],
/// [forward_camera], [lidar], [odometry], [imu], [traverse_0] ... [traverse_{traverse_count-1}],
/// and optional overrides [traverse_i.world] (appearance keys), [traverse_i.vehicle],
/// [traverse_i.ceiling_camera], [traverse_i.forward_camera], [traverse_i.lidar],
/// [traverse_i.odometry] holding the keys that differ on that traverse.
/// Loading is strict: unknown sections or keys and malformed values are refused with a
/// common::ConfigError naming the file, section and key.
struct ScenarioOptions : public mrpt::config::CLoadableOptions {
    std::string name = "scenario";  ///< dataset name
    uint64_t seed = 1;              ///< everything random derives from it: same seed, same bytes
    int threads = 0;               ///< render threads, 0 = all cores (output does not depend on it)
    double start_time_s = 1.7e9;   ///< time stamp of the first traverse's start [s, UNIX]
    double traverse_gap_s = 1000;  ///< traverse k starts at start_time_s + k * gap (or later) [s]
    WorldOptions world;
    VehicleOptions vehicle;
    CameraOptions ceiling_camera;
    CameraOptions forward_camera;
    LidarOptions lidar;
    OdometryOptions odometry;
    ImuOptions imu;
    std::vector<TraverseOptions> traverses;

    /// Name that error messages give the source (the file path when read by fromFile()).
    std::string source_name = "<scenario>";

    ScenarioOptions();

    /// Reads the whole scenario; `section` is ignored (a scenario spans several sections).
    void loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                            const std::string& section) override;
    void saveToConfigFile(mrpt::config::CConfigFileBase& target,
                          const std::string& section) const override;

    /// Throws common::ConfigError naming every invalid field.
    void check() const;

    /// Loads and checks `path`; throws common::ConfigError (file, section, key) when malformed.
    static ScenarioOptions fromFile(const std::string& path);

    /// The resolved scenario as .ini text (what `scenario.ini` holds).
    std::string toIniText() const;

    /// Traverse i's sensors, vehicle and world: its override, else the scenario's.
    const WorldOptions& worldFor(std::size_t i) const;
    const VehicleOptions& vehicleFor(std::size_t i) const;
    const CameraOptions& ceilingCameraFor(std::size_t i) const;
    const CameraOptions& forwardCameraFor(std::size_t i) const;
    const LidarOptions& lidarFor(std::size_t i) const;
    const OdometryOptions& odometryFor(std::size_t i) const;

  private:
    /// Reads [SECTION.world] ... [SECTION.odometry] of traverse `tr` on top of this scenario's
    /// (already loaded) sections.
    void loadOverrides(const mrpt::config::CConfigFileBase& source, const std::string& section,
                       TraverseOptions& tr) const;
};

/// `<dir>/<name>.ini` for the first dir in `search_dirs` that has it; throws ConfigError
/// listing the dirs tried otherwise.
std::string findPreset(const std::string& name, const std::vector<std::string>& search_dirs);

}  // namespace lookup::sim

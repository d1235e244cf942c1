#include "lookup/sim/scenario.h"

#include <lookup/common/config.h>
#include <lookup/common/options_table.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/core/bits_math.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <functional>
#include <iomanip>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <type_traits>

namespace lookup::sim {
namespace {

using common::ConfigError;
using common::IniSection;

using common::OptionsTable;

void addMount(OptionsTable& t, const std::string& prefix, MountPose& m) {
    t.add(prefix + "x_m", m.x_m);
    t.add(prefix + "y_m", m.y_m);
    t.add(prefix + "z_m", m.z_m);
    t.add(prefix + "yaw_deg", m.yaw_deg);
    t.add(prefix + "pitch_deg", m.pitch_deg);
    t.add(prefix + "roll_deg", m.roll_deg);
}

void addTiming(OptionsTable& t, SensorTiming& timing) {
    t.add("latency_ms", timing.latency_ms);
    t.add("jitter_ms", timing.jitter_ms);
    t.add("drop_rate", timing.drop_rate);
}

/// World keys that change how the mine looks, not its shape: what may differ per traverse.
void addAppearanceKeys(OptionsTable& t, WorldOptions& w) {
    t.add("rock_contrast", w.rock_contrast);
    t.add("bolt_spacing_m", w.bolt_spacing_m);
    t.add("bolt_plate_m", w.bolt_plate_m);
    t.add("mesh_fraction", w.mesh_fraction);
    t.add("mesh_pitch_m", w.mesh_pitch_m);
    t.add("shotcrete_fraction", w.shotcrete_fraction);
    t.add("texture_image", w.texture_image);
    t.add("texture_image_size_m", w.texture_image_size_m);
    t.add("duct_radius_m", w.duct_radius_m);
    t.add("duct_offset_m", w.duct_offset_m);
    t.add("duct_drop_m", w.duct_drop_m);
    t.add("pipe_radius_m", w.pipe_radius_m);
    t.add("pipe_offset_m", w.pipe_offset_m);
    t.add("pipe_drop_m", w.pipe_drop_m);
    t.add("cable_offset_m", w.cable_offset_m);
    t.add("cable_span_m", w.cable_span_m);
    t.add("cable_sag_m", w.cable_sag_m);
    t.add("light_spacing_m", w.light_spacing_m);
    t.add("sign_spacing_m", w.sign_spacing_m);
}

OptionsTable worldAppearanceKeys(WorldOptions& w) {
    OptionsTable t;
    addAppearanceKeys(t, w);
    return t;
}

OptionsTable worldKeys(WorldOptions& w) {
    OptionsTable t;
    t.add("layout", w.layout);
    t.add("length_m", w.length_m);
    t.add("width_m", w.width_m);
    t.add("ceiling_height_m", w.ceiling_height_m);
    t.add("arch_radius_m", w.arch_radius_m);
    t.add("segment_length_m", w.segment_length_m);
    t.add("bend_max_deg", w.bend_max_deg);
    t.add("twin_separation_m", w.twin_separation_m);
    t.add("drawpoint_spacing_m", w.drawpoint_spacing_m);
    t.add("drawpoint_length_m", w.drawpoint_length_m);
    t.add("drawpoint_width_m", w.drawpoint_width_m);
    t.add("drawpoint_angle_deg", w.drawpoint_angle_deg);
    t.add("junction_spacing_m", w.junction_spacing_m);
    t.add("junction_length_m", w.junction_length_m);
    t.add("bump_amplitude_m", w.bump_amplitude_m);
    t.add("bump_wavelength_m", w.bump_wavelength_m);
    t.add("floor_roughness_m", w.floor_roughness_m);
    t.add("grid_resolution_m", w.grid_resolution_m);
    t.add("wall_roughness_m", w.wall_roughness_m);
    t.add("niche_spacing_m", w.niche_spacing_m);
    t.add("niche_depth_m", w.niche_depth_m);
    t.add("niche_width_m", w.niche_width_m);
    t.add("grade", w.grade);
    t.saveOnlyIf([&w]() { return !w.grade.empty(); });
    t.add("grade_transition_m", w.grade_transition_m);
    t.saveOnlyIf([&w]() { return !w.grade.empty(); });
    addAppearanceKeys(t, w);
    return t;
}

OptionsTable vehicleKeys(VehicleOptions& v) {
    OptionsTable t;
    t.add("name", v.name);
    t.add("wheelbase_m", v.wheelbase_m);
    t.add("track_m", v.track_m);
    return t;
}

OptionsTable cameraKeys(CameraOptions& c) {
    OptionsTable t;
    t.add("label", c.label);
    t.add("rate_hz", c.rate_hz);
    t.add("phase_s", c.phase_s);
    t.add("width_px", c.width_px);
    t.add("height_px", c.height_px);
    t.add("hfov_deg", c.hfov_deg);
    addMount(t, "pose_", c.mount);
    t.add("exposure_ms", c.exposure_ms);
    t.add("exposure_variation", c.exposure_variation);
    t.add("noise_std_dn", c.noise_std_dn);
    t.add("light_gain", c.light_gain);
    t.add("light_falloff_exp", c.light_falloff_exp);
    t.add("max_range_m", c.max_range_m);
    t.add("distortion", c.distortion);
    t.add("dist_k1", c.dist_k1);
    t.add("dist_k2", c.dist_k2);
    t.add("dist_p1", c.dist_p1);
    t.add("dist_p2", c.dist_p2);
    t.add("dist_k3", c.dist_k3);
    t.add("dist_k4", c.dist_k4);
    t.add("readout_ms", c.readout_ms);
    t.add("stamp_row", c.stamp_row, common::stampRowNames());
    addTiming(t, c.timing);
    t.add("response_gamma", c.response_gamma);
    t.add("response_knee_dn", c.response_knee_dn);
    t.add("response_knee_slope", c.response_knee_slope);
    t.add("auto_exposure_target_dn", c.auto_exposure_target_dn);
    t.add("auto_exposure_tau_s", c.auto_exposure_tau_s);
    t.add("bloom_strength", c.bloom_strength);
    t.add("bloom_radius_px", c.bloom_radius_px);
    t.add("dirt_spots", c.dirt_spots);
    t.add("dirt_opacity", c.dirt_opacity);
    t.add("water_drops", c.water_drops);
    t.add("drop_radius_px", c.drop_radius_px);
    t.add("haze_extinction_per_m", c.haze_extinction_per_m);
    t.add("haze_airlight", c.haze_airlight);
    return t;
}

OptionsTable lidarKeys(LidarOptions& l) {
    OptionsTable t;
    t.add("label", l.label);
    t.add("rate_hz", l.rate_hz);
    t.add("phase_s", l.phase_s);
    t.add("aperture_deg", l.aperture_deg);
    t.add("resolution_deg", l.resolution_deg);
    t.add("max_range_m", l.max_range_m);
    t.add("noise_std_m", l.noise_std_m);
    addMount(t, "pose_", l.mount);
    addTiming(t, l.timing);
    t.add("sweep_ms", l.sweep_ms);
    t.add("dust_rate", l.dust_rate);
    t.add("dust_max_range_m", l.dust_max_range_m);
    return t;
}

OptionsTable odometryKeys(OdometryOptions& o) {
    OptionsTable t;
    t.add("label", o.label);
    t.add("rate_hz", o.rate_hz);
    t.add("phase_s", o.phase_s);
    t.add("scale_error", o.scale_error);
    t.add("yaw_bias_deg_per_m", o.yaw_bias_deg_per_m);
    t.add("noise_std_m", o.noise_std_m);
    t.add("noise_std_deg", o.noise_std_deg);
    addTiming(t, o.timing);
    t.add("slip_fraction", o.slip_fraction);
    t.add("slip_episode_m", o.slip_episode_m);
    t.add("slip_factor", o.slip_factor);
    t.add("dropout_fraction", o.dropout_fraction);
    t.add("dropout_s", o.dropout_s);
    return t;
}

OptionsTable imuKeys(ImuOptions& o) {
    OptionsTable t;
    t.add("enabled", o.enabled,
          common::EnumNames<ImuOptions::Mode>{{"auto", ImuOptions::Mode::Auto},
                                              {"true", ImuOptions::Mode::On},
                                              {"false", ImuOptions::Mode::Off}});
    t.add("label", o.label);
    t.add("noise_std_deg", o.noise_std_deg);
    t.add("bias_std_deg", o.bias_std_deg);
    return t;
}

OptionsTable traverseKeys(TraverseOptions& tr) {
    OptionsTable t;
    t.add("name", tr.name);
    t.add("roles", tr.roles);
    t.add("lateral_offset_m", tr.lateral_offset_m);
    t.add("zigzag_amplitude_m", tr.zigzag_amplitude_m);
    t.add("zigzag_period_m", tr.zigzag_period_m);
    t.add("speed_kmh", tr.speed_kmh);
    t.add("speed_variation", tr.speed_variation);
    t.add("accel_mps2", tr.accel_mps2);
    t.add("start_m", tr.start_m);
    t.add("end_m", tr.end_m);
    t.add("direction", tr.direction);
    t.add("plan", tr.plan);
    t.add("marks_at_stops", tr.marks_at_stops);
    return t;
}

std::string traverseSection(std::size_t i) { return "traverse_" + std::to_string(i); }

const char* const kOverridable[] = {"world",          "vehicle", "ceiling_camera",
                                    "forward_camera", "lidar",   "odometry"};

/// Applies `fn(section, optional, table_of_base)` to each per-traverse override of `tr`.
template <typename Fn>
void forEachOverride(TraverseOptions& tr, Fn&& fn) {
    fn("world", tr.world, [](WorldOptions& w) { return worldAppearanceKeys(w); });
    fn("vehicle", tr.vehicle, [](VehicleOptions& v) { return vehicleKeys(v); });
    fn("ceiling_camera", tr.ceiling_camera, [](CameraOptions& c) { return cameraKeys(c); });
    fn("forward_camera", tr.forward_camera, [](CameraOptions& c) { return cameraKeys(c); });
    fn("lidar", tr.lidar, [](LidarOptions& l) { return lidarKeys(l); });
    fn("odometry", tr.odometry, [](OdometryOptions& o) { return odometryKeys(o); });
}

void checkTiming(common::OptionsCheck& c, const SensorTiming& t, const std::string& p,
                 double rate_hz) {
    c.require(std::abs(t.latency_ms) <= 1000, p + ".latency_ms",
              "in [-1000, 1000] (a latency over a second is a broken clock, not latency)");
    c.require(t.jitter_ms >= 0 && t.jitter_ms <= 0.5e3 / rate_hz, p + ".jitter_ms",
              "in [0, half the record period]");
    c.require(t.drop_rate >= 0 && t.drop_rate < 1, p + ".drop_rate", "in [0, 1)");
}

void checkCameraEffects(common::OptionsCheck& c, const CameraOptions& cam, const std::string& p) {
    c.require(cam.distortion == "none" || cam.distortion == "plumb_bob" ||
                  cam.distortion == "kannala_brandt",
              p + ".distortion", "none, plumb_bob or kannala_brandt");
    for (double k :
         {cam.dist_k1, cam.dist_k2, cam.dist_p1, cam.dist_p2, cam.dist_k3, cam.dist_k4}) {
        c.require(std::abs(k) <= 5, p + ".dist_*", "coefficients in [-5, 5]");
    }
    c.require(cam.readout_ms >= 0 && cam.readout_ms < 1000 / cam.rate_hz, p + ".readout_ms",
              "in [0, frame period " + std::to_string(1000 / cam.rate_hz) +
                  " ms): rows are read within one frame");
    checkTiming(c, cam.timing, p, cam.rate_hz);
    c.require(cam.response_gamma >= 0.2 && cam.response_gamma <= 5, p + ".response_gamma",
              "in [0.2, 5]");
    c.require(cam.response_knee_dn >= 0 && cam.response_knee_dn < 255, p + ".response_knee_dn",
              "in [0, 255)");
    c.require(cam.response_knee_slope > 0 && cam.response_knee_slope <= 1,
              p + ".response_knee_slope", "in (0, 1]");
    c.require(cam.auto_exposure_target_dn >= 0 && cam.auto_exposure_target_dn < 255,
              p + ".auto_exposure_target_dn", "in [0, 255)");
    c.require(cam.auto_exposure_tau_s > 0, p + ".auto_exposure_tau_s", "> 0");
    c.require(cam.bloom_strength >= 0 && cam.bloom_strength <= 1, p + ".bloom_strength",
              "in [0, 1]");
    c.require(cam.bloom_radius_px > 0 && cam.bloom_radius_px <= 100, p + ".bloom_radius_px",
              "in (0, 100]");
    c.require(cam.dirt_spots >= 0 && cam.dirt_spots <= 200, p + ".dirt_spots", "in [0, 200]");
    c.require(cam.dirt_opacity >= 0 && cam.dirt_opacity < 1, p + ".dirt_opacity", "in [0, 1)");
    c.require(cam.water_drops >= 0 && cam.water_drops <= 200, p + ".water_drops", "in [0, 200]");
    c.require(cam.drop_radius_px > 0 && cam.drop_radius_px <= 200, p + ".drop_radius_px",
              "in (0, 200]");
    c.require(cam.haze_extinction_per_m >= 0 && cam.haze_extinction_per_m <= 2,
              p + ".haze_extinction_per_m", "in [0, 2]");
    c.require(cam.haze_airlight >= 0 && cam.haze_airlight <= 2, p + ".haze_airlight", "in [0, 2]");
}

void checkCamera(common::OptionsCheck& c, const CameraOptions& cam, const std::string& p) {
    c.require(!cam.label.empty(), p + ".label", "non-empty");
    c.require(cam.rate_hz > 0 && cam.rate_hz <= 1000, p + ".rate_hz", "in (0, 1000]");
    c.require(cam.phase_s >= 0, p + ".phase_s", ">= 0");
    c.require(cam.width_px >= 8 && cam.width_px <= 4096, p + ".width_px", "in [8, 4096]");
    c.require(cam.height_px >= 8 && cam.height_px <= 4096, p + ".height_px", "in [8, 4096]");
    c.require(cam.hfov_deg > 1 && cam.hfov_deg < 170, p + ".hfov_deg", "in (1, 170)");
    c.require(cam.exposure_ms >= 0 && cam.exposure_ms < 100, p + ".exposure_ms", "in [0, 100)");
    c.require(cam.exposure_variation >= 0 && cam.exposure_variation < 1, p + ".exposure_variation",
              "in [0, 1)");
    c.require(cam.noise_std_dn >= 0, p + ".noise_std_dn", ">= 0");
    c.require(cam.light_gain > 0, p + ".light_gain", "> 0");
    c.require(cam.light_falloff_exp >= 0, p + ".light_falloff_exp", ">= 0");
    c.require(cam.max_range_m > 0, p + ".max_range_m", "> 0");
    checkCameraEffects(c, cam, p);
}

void checkCameraMount(common::OptionsCheck& c, const CameraOptions& cam, const std::string& p,
                      double ceiling_height_m) {
    c.require(cam.mount.z_m > 0.2 && cam.mount.z_m < ceiling_height_m - 0.5, p + ".pose_z_m",
              "in (0.2, ceiling_height_m - 0.5)");
}

void checkLidar(common::OptionsCheck& c, const LidarOptions& lidar, const std::string& p,
                const WorldOptions& w) {
    c.require(!lidar.label.empty(), p + ".label", "non-empty");
    c.require(lidar.rate_hz > 0 && lidar.rate_hz <= 200, p + ".rate_hz", "in (0, 200]");
    c.require(lidar.phase_s >= 0, p + ".phase_s", ">= 0");
    c.require(lidar.aperture_deg > 0 && lidar.aperture_deg <= 360, p + ".aperture_deg",
              "in (0, 360]");
    c.require(lidar.resolution_deg >= 0.05 && lidar.resolution_deg <= 10, p + ".resolution_deg",
              "in [0.05, 10]");
    c.require(lidar.max_range_m > 1, p + ".max_range_m", "> 1");
    c.require(lidar.noise_std_m >= 0, p + ".noise_std_m", ">= 0");
    c.require(lidar.mount.z_m > 0.2 && lidar.mount.z_m < w.ceiling_height_m - w.arch_radius_m,
              p + ".pose_z_m", "in (0.2, ceiling_height_m - arch_radius_m): the scan plane");
    checkTiming(c, lidar.timing, p, lidar.rate_hz);
    c.require(lidar.sweep_ms >= 0 && lidar.sweep_ms <= 1000 / lidar.rate_hz, p + ".sweep_ms",
              "in [0, scan period]");
    c.require(lidar.dust_rate >= 0 && lidar.dust_rate < 1, p + ".dust_rate", "in [0, 1)");
    c.require(lidar.dust_max_range_m > 0.3 && lidar.dust_max_range_m <= lidar.max_range_m,
              p + ".dust_max_range_m", "in (0.3, max_range_m]");
}

void checkOdometry(common::OptionsCheck& c, const OdometryOptions& o, const std::string& p) {
    c.require(!o.label.empty(), p + ".label", "non-empty");
    c.require(o.rate_hz > 0 && o.rate_hz <= 1000, p + ".rate_hz", "in (0, 1000]");
    c.require(o.phase_s >= 0, p + ".phase_s", ">= 0");
    c.require(o.noise_std_m >= 0, p + ".noise_std_m", ">= 0");
    c.require(o.noise_std_deg >= 0, p + ".noise_std_deg", ">= 0");
    checkTiming(c, o.timing, p, o.rate_hz);
    c.require(o.slip_fraction >= 0 && o.slip_fraction <= 1, p + ".slip_fraction", "in [0, 1]");
    c.require(o.slip_episode_m > 0, p + ".slip_episode_m", "> 0");
    c.require(o.slip_factor >= 0.5 && o.slip_factor <= 3, p + ".slip_factor", "in [0.5, 3]");
    c.require(o.dropout_fraction >= 0 && o.dropout_fraction < 1, p + ".dropout_fraction",
              "in [0, 1)");
    c.require(o.dropout_s > 0, p + ".dropout_s", "> 0");
}

void checkPlan(common::OptionsCheck& c, const TraverseOptions& t, const std::string& p) {
    c.require(t.direction == "forward" || t.direction == "reverse", p + ".direction",
              "forward or reverse");
    if (t.plan.empty()) return;
    try {
        const std::vector<PlanLeg> legs = parsePlan(t.plan);
        double s = t.start_m;
        int facing = 0;
        for (std::size_t k = 0; k < legs.size(); ++k) {
            const PlanLeg& leg = legs[k];
            const std::string what = p + ".plan leg " + std::to_string(k + 1);
            if (leg.kind == PlanLeg::Kind::Stop) continue;
            c.require(
                std::isinf(leg.value) || (leg.value >= 0 && (t.end_m < 0 || leg.value <= t.end_m)),
                what, "a target on the route (in [0, end_m], or end)");
            if (leg.value == s) continue;
            const int travel = leg.value > s ? 1 : -1;
            const int face = leg.kind == PlanLeg::Kind::Drive ? travel : -travel;
            c.require(facing == 0 || face == facing, what,
                      "keeps the vehicle's facing (it cannot turn round in the tunnel: use "
                      "reverse)");
            facing = face;
            s = leg.value;
        }
    } catch (const std::invalid_argument& e) {
        c.require(false, p + ".plan", e.what());
    }
}

void checkGrade(common::OptionsCheck& c, const WorldOptions& w) {
    c.require(w.grade_transition_m >= 0 && w.grade_transition_m <= 200, "world.grade_transition_m",
              "in [0, 200]");
    if (w.grade.empty()) return;
    try {
        const std::vector<GradeRamp> ramps = parseGrade(w.grade);
        for (std::size_t k = 1; k < ramps.size(); ++k) {
            c.require(ramps[k].start_m >= ramps[k - 1].end_m,
                      "world.grade ramp " + std::to_string(k + 1),
                      "starts after ramp " + std::to_string(k) + " ends (ramps in route order)");
        }
    } catch (const std::invalid_argument& e) {
        c.require(false, "world.grade",
                  std::string("ramps 'S0 S1 G', none steeper than 1:4 (") + e.what() + ")");
    }
}

void checkAppearance(common::OptionsCheck& c, const WorldOptions& w, const std::string& p) {
    c.require(w.rock_contrast >= 0 && w.rock_contrast <= 2, p + ".rock_contrast", "in [0, 2]");
    c.require(w.bolt_spacing_m == 0 || w.bolt_spacing_m >= 0.3, p + ".bolt_spacing_m",
              "0 or >= 0.3");
    c.require(w.bolt_plate_m > 0 && w.bolt_plate_m < 0.5, p + ".bolt_plate_m", "in (0, 0.5)");
    c.require(w.mesh_fraction >= 0 && w.mesh_fraction <= 1, p + ".mesh_fraction", "in [0, 1]");
    c.require(w.mesh_pitch_m >= 0.02, p + ".mesh_pitch_m", ">= 0.02");
    c.require(w.shotcrete_fraction >= 0 && w.shotcrete_fraction <= 1, p + ".shotcrete_fraction",
              "in [0, 1]");
    c.require(w.texture_image_size_m > 0, p + ".texture_image_size_m", "> 0");
    c.require(w.duct_radius_m >= 0 && w.duct_radius_m < 1.5, p + ".duct_radius_m", "in [0, 1.5)");
    c.require(w.pipe_radius_m >= 0 && w.pipe_radius_m < 0.5, p + ".pipe_radius_m", "in [0, 0.5)");
    c.require(w.duct_drop_m > w.duct_radius_m, p + ".duct_drop_m", "> duct_radius_m");
    c.require(w.pipe_drop_m > w.pipe_radius_m, p + ".pipe_drop_m", "> pipe_radius_m");
    c.require(w.cable_span_m == 0 || w.cable_span_m >= 0.5, p + ".cable_span_m", "0 or >= 0.5");
    c.require(w.cable_sag_m >= 0 && w.cable_sag_m < 1, p + ".cable_sag_m", "in [0, 1)");
    c.require(w.light_spacing_m == 0 || w.light_spacing_m >= 2, p + ".light_spacing_m",
              "0 or >= 2");
    c.require(w.sign_spacing_m == 0 || w.sign_spacing_m >= 5, p + ".sign_spacing_m", "0 or >= 5");
}

/// The [scenario] section's own keys.
void checkScenarioKeys(common::OptionsCheck& c, const ScenarioOptions& sc) {
    c.require(!sc.name.empty(), "name", "non-empty");
    c.require(sc.threads >= 0, "threads", ">= 0");
    c.require(sc.start_time_s >= 0, "start_time_s", ">= 0");
    c.require(sc.traverse_gap_s >= 0, "traverse_gap_s", ">= 0");
}

/// The tunnels' plan and cross-section: layout, size, bends, draw points and junctions.
void checkWorldShape(common::OptionsCheck& c, const WorldOptions& w) {
    c.require(w.layout == "single" || w.layout == "twin", "world.layout", "single or twin");
    c.require(w.length_m >= 10 && w.length_m <= 20000, "world.length_m", "in [10, 20000]");
    c.require(w.width_m >= 2 && w.width_m <= 20, "world.width_m", "in [2, 20]");
    c.require(w.ceiling_height_m >= 2 && w.ceiling_height_m <= 20, "world.ceiling_height_m",
              "in [2, 20]");
    c.require(w.arch_radius_m >= 0 && w.arch_radius_m < w.width_m / 2 &&
                  w.arch_radius_m < w.ceiling_height_m - 1,
              "world.arch_radius_m", "in [0, min(width/2, ceiling_height - 1))");
    c.require(w.segment_length_m >= 5, "world.segment_length_m", ">= 5");
    c.require(w.bend_max_deg >= 0 && w.bend_max_deg <= 45, "world.bend_max_deg", "in [0, 45]");
    c.require(w.twin_separation_m >= w.width_m + 2, "world.twin_separation_m", ">= width_m + 2");
    c.require(w.drawpoint_spacing_m == 0 || w.drawpoint_spacing_m >= 5, "world.drawpoint_spacing_m",
              "0 or >= 5");
    c.require(w.drawpoint_length_m > 0, "world.drawpoint_length_m", "> 0");
    c.require(w.drawpoint_width_m > 1 && w.drawpoint_width_m <= w.width_m,
              "world.drawpoint_width_m", "in (1, width_m]");
    c.require(w.drawpoint_angle_deg >= 20 && w.drawpoint_angle_deg <= 90,
              "world.drawpoint_angle_deg", "in [20, 90]");
    c.require(w.junction_spacing_m == 0 || w.junction_spacing_m >= 20, "world.junction_spacing_m",
              "0 or >= 20");
    c.require(w.junction_length_m > 0, "world.junction_length_m", "> 0");
}

/// Roof and floor relief.
void checkWorldRelief(common::OptionsCheck& c, const WorldOptions& w) {
    c.require(w.bump_amplitude_m >= 0 && w.bump_amplitude_m <= 0.5, "world.bump_amplitude_m",
              "in [0, 0.5]");
    c.require(w.bump_wavelength_m > 0.2, "world.bump_wavelength_m", "> 0.2");
    c.require(w.floor_roughness_m >= 0 && w.floor_roughness_m <= 0.3, "world.floor_roughness_m",
              "in [0, 0.3]");
}

/// The map grid, the wall relief and the niches.
void checkWorldWalls(common::OptionsCheck& c, const WorldOptions& w) {
    c.require(w.grid_resolution_m >= 0.02 && w.grid_resolution_m <= 0.5, "world.grid_resolution_m",
              "in [0.02, 0.5]");
    c.require(w.wall_roughness_m >= 0 && w.wall_roughness_m <= 0.5, "world.wall_roughness_m",
              "in [0, 0.5]");
    c.require(w.niche_spacing_m == 0 || w.niche_spacing_m >= 5, "world.niche_spacing_m",
              "0 or >= 5");
    c.require(w.niche_depth_m > 0 && w.niche_depth_m <= 10, "world.niche_depth_m", "in (0, 10]");
    c.require(w.niche_width_m >= 0.5 && w.niche_width_m <= 10, "world.niche_width_m",
              "in [0.5, 10]");
}

/// The [world] section.
void checkWorld(common::OptionsCheck& c, const WorldOptions& w) {
    checkWorldShape(c, w);
    checkWorldRelief(c, w);
    checkAppearance(c, w, "world");
    checkWorldWalls(c, w);
    checkGrade(c, w);
}

void checkVehicle(common::OptionsCheck& c, const VehicleOptions& v, const std::string& p) {
    c.require(v.wheelbase_m > 0.5, p + ".wheelbase_m", "> 0.5");
    c.require(v.track_m > 0.5, p + ".track_m", "> 0.5");
}

void checkOverrides(common::OptionsCheck& c, const ScenarioOptions& sc, std::size_t i) {
    const TraverseOptions& t = sc.traverses[i];
    const std::string p = traverseSection(i) + ".";
    const double h = sc.world.ceiling_height_m;
    if (t.world) checkAppearance(c, *t.world, p + "world");
    if (t.vehicle) checkVehicle(c, *t.vehicle, p + "vehicle");
    auto camera = [&](const std::optional<CameraOptions>& cam, const CameraOptions& base,
                      const std::string& name) {
        if (!cam) return;
        checkCamera(c, *cam, p + name);
        checkCameraMount(c, *cam, p + name, h);
        c.require(cam->label == base.label, p + name + ".label",
                  "the scenario's label (" + base.label + "): the dataset names one per sensor");
    };
    camera(t.ceiling_camera, sc.ceiling_camera, "ceiling_camera");
    camera(t.forward_camera, sc.forward_camera, "forward_camera");
    if (t.lidar) {
        checkLidar(c, *t.lidar, p + "lidar", sc.world);
        c.require(t.lidar->label == sc.lidar.label, p + "lidar.label", "the scenario's label");
    }
    if (t.odometry) {
        checkOdometry(c, *t.odometry, p + "odometry");
        c.require(t.odometry->label == sc.odometry.label, p + "odometry.label",
                  "the scenario's label");
    }
}

/// A traverse's name: a file stem, unique among the traverses before it.
void checkTraverseName(common::OptionsCheck& c, const std::vector<TraverseOptions>& traverses,
                       std::size_t i, const std::string& p) {
    const TraverseOptions& t = traverses[i];
    c.require(!t.name.empty() && t.name.find_first_of("/\\ .") == std::string::npos, p + ".name",
              "a non-empty file stem without '/', '\\', ' ' or '.'");
    for (std::size_t j = 0; j < i; ++j) {
        c.require(traverses[j].name != t.name, p + ".name",
                  "unique (repeats traverse_" + std::to_string(j) + ")");
    }
}

/// `roles`: a non-empty comma list of mapping, reference, query, refresh.
void checkRoles(common::OptionsCheck& c, const std::string& roles_list, const std::string& p) {
    std::stringstream roles(roles_list);
    std::string role;
    bool any = false;
    while (std::getline(roles, role, ',')) {
        role.erase(0, role.find_first_not_of(" \t"));
        role.erase(role.find_last_not_of(" \t") + 1);
        any = true;
        c.require(role == "mapping" || role == "reference" || role == "query" || role == "refresh",
                  p + ".roles",
                  "a comma list of mapping, reference, query, refresh (got '" + role + "')");
    }
    c.require(any, p + ".roles", "non-empty");
}

/// Where in the tunnel a traverse drives and how fast.
void checkDriving(common::OptionsCheck& c, const TraverseOptions& t, const std::string& p,
                  const WorldOptions& w) {
    c.require(std::abs(t.lateral_offset_m) + t.zigzag_amplitude_m < w.width_m / 2 - 0.8,
              p + ".lateral_offset_m", "|offset| + zigzag_amplitude_m < width_m / 2 - 0.8");
    c.require(t.zigzag_amplitude_m >= 0, p + ".zigzag_amplitude_m", ">= 0");
    c.require(t.zigzag_period_m >= 5, p + ".zigzag_period_m", ">= 5");
    c.require(t.speed_kmh > 0.5 && t.speed_kmh <= 60, p + ".speed_kmh", "in (0.5, 60]");
    c.require(t.speed_variation >= 0 && t.speed_variation < 0.8, p + ".speed_variation",
              "in [0, 0.8)");
    c.require(t.accel_mps2 > 0.05 && t.accel_mps2 <= 10, p + ".accel_mps2", "in (0.05, 10]");
    c.require(t.start_m >= 0, p + ".start_m", ">= 0");
    c.require(t.end_m == -1 || t.end_m > t.start_m + 5, p + ".end_m", "-1 or > start_m + 5");
}

/// The [traverse_i] section and its overrides.
void checkTraverse(common::OptionsCheck& c, const ScenarioOptions& sc, std::size_t i) {
    const TraverseOptions& t = sc.traverses[i];
    const std::string p = traverseSection(i);
    checkTraverseName(c, sc.traverses, i, p);
    checkRoles(c, t.roles, p);
    checkDriving(c, t, p, sc.world);
    checkPlan(c, t, p);
    checkOverrides(c, sc, i);
}

}  // namespace

std::vector<PlanLeg> parsePlan(const std::string& plan) {
    std::vector<PlanLeg> legs;
    std::stringstream list(plan);
    std::string item;
    while (std::getline(list, item, ',')) {
        std::istringstream words(item);
        std::string kind, target, rest;
        const std::string n = std::to_string(legs.size() + 1);
        std::size_t used = 0;
        double value = 0;
        if (words >> kind >> target && !(words >> rest)) {
            if (target == "end" && kind != "stop") {
                value = std::numeric_limits<double>::infinity();  // the traverse's end
                used = target.size();
            } else {
                try {
                    value = std::stod(target, &used);
                } catch (const std::exception&) {
                    used = 0;
                }
            }
        }
        if (target.empty() || used != target.size()) {
            throw std::invalid_argument("leg " + n + " '" + item +
                                        "' is not 'drive S', 'reverse S' or 'stop T'");
        }
        PlanLeg leg;
        leg.value = value;
        if (kind == "drive") {
            leg.kind = PlanLeg::Kind::Drive;
        } else if (kind == "reverse") {
            leg.kind = PlanLeg::Kind::Reverse;
        } else if (kind == "stop") {
            leg.kind = PlanLeg::Kind::Stop;
            if (!(value >= 0 && value <= 3600)) {
                throw std::invalid_argument("leg " + n + ": dwell must be in [0, 3600] s");
            }
        } else {
            throw std::invalid_argument("leg " + n + " '" + kind +
                                        "' is not drive, reverse or stop");
        }
        legs.push_back(leg);
    }
    if (legs.empty()) throw std::invalid_argument("no legs");
    return legs;
}

std::vector<GradeRamp> parseGrade(const std::string& grade) {
    std::vector<GradeRamp> ramps;
    std::stringstream list(grade);
    std::string item;
    while (std::getline(list, item, ',')) {
        std::istringstream words(item);
        std::string g, rest;
        GradeRamp r;
        const std::string n = "ramp " + std::to_string(ramps.size() + 1);
        if (!(words >> r.start_m >> r.end_m >> g) || (words >> rest)) {
            throw std::invalid_argument(n + " '" + item + "' is not 'S0 S1 G'");
        }
        std::size_t used = 0;
        try {
            const auto colon = g.find(':');
            if (colon == std::string::npos) {
                r.grade = std::stod(g, &used);
            } else {  // "1:7" (rise:run), sign in front
                const double rise = std::stod(g.substr(0, colon), &used);
                if (used != colon) throw std::invalid_argument(g);
                const std::string run_text = g.substr(colon + 1);
                const double run = std::stod(run_text, &used);
                if (used != run_text.size() || !(run > 0)) throw std::invalid_argument(g);
                r.grade = rise / run;
                used = g.size();
            }
        } catch (const std::exception&) {
            used = 0;
        }
        if (used != g.size() || !std::isfinite(r.grade)) {
            throw std::invalid_argument(n + ": grade '" + g + "' is not a number or 'RISE:RUN'");
        }
        if (!(r.start_m >= 0 && r.end_m > r.start_m)) {
            throw std::invalid_argument(n + ": needs 0 <= S0 < S1");
        }
        if (std::abs(r.grade) > 0.25) {
            std::ostringstream os;
            os << n << ": grade " << g << " (1:" << std::setprecision(3) << 1 / std::abs(r.grade)
               << ") is steeper than 1:4, which no mine vehicle climbs";
            throw std::invalid_argument(os.str());
        }
        ramps.push_back(r);
    }
    if (ramps.empty()) throw std::invalid_argument("no ramps");
    return ramps;
}

const WorldOptions& ScenarioOptions::worldFor(std::size_t i) const {
    return traverses.at(i).world ? *traverses[i].world : world;
}
const VehicleOptions& ScenarioOptions::vehicleFor(std::size_t i) const {
    return traverses.at(i).vehicle ? *traverses[i].vehicle : vehicle;
}
const CameraOptions& ScenarioOptions::ceilingCameraFor(std::size_t i) const {
    return traverses.at(i).ceiling_camera ? *traverses[i].ceiling_camera : ceiling_camera;
}
const CameraOptions& ScenarioOptions::forwardCameraFor(std::size_t i) const {
    return traverses.at(i).forward_camera ? *traverses[i].forward_camera : forward_camera;
}
const LidarOptions& ScenarioOptions::lidarFor(std::size_t i) const {
    return traverses.at(i).lidar ? *traverses[i].lidar : lidar;
}
const OdometryOptions& ScenarioOptions::odometryFor(std::size_t i) const {
    return traverses.at(i).odometry ? *traverses[i].odometry : odometry;
}

mrpt::poses::CPose3D MountPose::pose() const {
    return mrpt::poses::CPose3D(x_m, y_m, z_m, mrpt::DEG2RAD(yaw_deg), mrpt::DEG2RAD(pitch_deg),
                                mrpt::DEG2RAD(roll_deg));
}

ScenarioOptions::ScenarioOptions() {
    ceiling_camera.label = "CEILING_CAM";
    ceiling_camera.rate_hz = 25;
    ceiling_camera.mount = {0.5, 0.0, 2.6, 90.0, 0.0, 0.0};  // image up = vehicle forward
    forward_camera.label = "FORWARD_CAM";
    forward_camera.rate_hz = 10;
    forward_camera.phase_s = 0.013;
    forward_camera.width_px = 160;
    forward_camera.height_px = 120;
    forward_camera.hfov_deg = 90;
    forward_camera.exposure_ms = 8;
    forward_camera.light_falloff_exp = 2.0;
    forward_camera.light_gain = 2.0;
    forward_camera.mount = {1.8, 0.0, 2.0, -90.0, 0.0, -90.0};  // optical axis = vehicle +x
}

void ScenarioOptions::loadOverrides(const mrpt::config::CConfigFileBase& source,
                                    const std::string& section, TraverseOptions& tr) const {
    const ScenarioOptions& base = *this;
    auto baseOf = [&base](const char* name, auto* which) -> const auto& {
        using T = std::remove_pointer_t<decltype(which)>;
        if constexpr (std::is_same_v<T, WorldOptions>) {
            return base.world;
        } else if constexpr (std::is_same_v<T, VehicleOptions>) {
            return base.vehicle;
        } else if constexpr (std::is_same_v<T, LidarOptions>) {
            return base.lidar;
        } else if constexpr (std::is_same_v<T, OdometryOptions>) {
            return base.odometry;
        } else {
            return std::string(name) == "ceiling_camera" ? base.ceiling_camera
                                                         : base.forward_camera;
        }
    };
    forEachOverride(tr, [&](const char* name, auto& opt, auto table) {
        IniSection s(source, section + "." + name, source_name);
        if (!s.exists()) return;
        using T = typename std::remove_reference_t<decltype(opt)>::value_type;
        opt = baseOf(name, static_cast<T*>(nullptr));
        table(*opt).load(s);
    });
}

void ScenarioOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                         const std::string& /*section*/) {
    IniSection sc(source, "scenario", source_name);
    if (!sc.exists()) throw ConfigError(source_name + " [scenario]: required section is missing");
    int traverse_count = 0;
    {
        OptionsTable t;
        t.add("name", name);
        t.add("seed", seed);
        t.add("threads", threads);
        t.add("start_time_s", start_time_s);
        t.add("traverse_gap_s", traverse_gap_s);
        t.add("traverse_count", traverse_count);
        t.load(sc);
    }
    if (traverse_count < 1 || traverse_count > 100) {
        throw ConfigError(sc.where("traverse_count") + "must be in [1, 100]");
    }

    std::vector<std::string> known = {"scenario",       "world", "vehicle",  "ceiling_camera",
                                      "forward_camera", "lidar", "odometry", "imu"};
    for (int i = 0; i < traverse_count; ++i) {
        known.push_back(traverseSection(i));
        for (const char* o : kOverridable) known.push_back(traverseSection(i) + "." + o);
    }
    std::vector<std::string> sections;
    source.getAllSections(sections);
    for (const auto& s : sections) {
        if (!s.empty() && std::find(known.begin(), known.end(), s) == known.end()) {
            throw ConfigError(source_name + " [" + s +
                              "]: unknown section (traverse sections must be traverse_0 .. "
                              "traverse_" +
                              std::to_string(traverse_count - 1) +
                              ", overrides traverse_i.world, .vehicle, .ceiling_camera, "
                              ".forward_camera, .lidar, .odometry)");
        }
    }

    worldKeys(world).load(IniSection(source, "world", source_name));
    vehicleKeys(vehicle).load(IniSection(source, "vehicle", source_name));
    cameraKeys(ceiling_camera).load(IniSection(source, "ceiling_camera", source_name));
    cameraKeys(forward_camera).load(IniSection(source, "forward_camera", source_name));
    lidarKeys(lidar).load(IniSection(source, "lidar", source_name));
    odometryKeys(odometry).load(IniSection(source, "odometry", source_name));
    imuKeys(imu).load(IniSection(source, "imu", source_name));

    traverses.assign(traverse_count, TraverseOptions{});
    for (int i = 0; i < traverse_count; ++i) {
        IniSection s(source, traverseSection(i), source_name);
        if (!s.exists()) {
            throw ConfigError(source_name + " [" + traverseSection(i) +
                              "]: required section is missing (traverse_count = " +
                              std::to_string(traverse_count) + ")");
        }
        traverses[i].name = s.requireString("name");
        traverseKeys(traverses[i]).load(s);
        loadOverrides(source, traverseSection(i), traverses[i]);
    }
}

void ScenarioOptions::saveToConfigFile(mrpt::config::CConfigFileBase& target,
                                       const std::string& /*section*/) const {
    ScenarioOptions copy = *this;  // the key tables bind mutable references
    int traverse_count = static_cast<int>(traverses.size());
    {
        OptionsTable t;
        t.add("name", copy.name);
        t.add("seed", copy.seed);
        t.add("threads", copy.threads);
        t.add("start_time_s", copy.start_time_s);
        t.add("traverse_gap_s", copy.traverse_gap_s);
        t.add("traverse_count", traverse_count);
        t.save(target, "scenario");
    }
    worldKeys(copy.world).save(target, "world");
    vehicleKeys(copy.vehicle).save(target, "vehicle");
    cameraKeys(copy.ceiling_camera).save(target, "ceiling_camera");
    cameraKeys(copy.forward_camera).save(target, "forward_camera");
    lidarKeys(copy.lidar).save(target, "lidar");
    odometryKeys(copy.odometry).save(target, "odometry");
    // Only when on (and then resolved to true), so that a level scenario without one writes
    // the scenario.ini it did.
    if (copy.imu.activeIn(!copy.world.grade.empty())) {
        copy.imu.enabled = ImuOptions::Mode::On;
        imuKeys(copy.imu).save(target, "imu");
    }
    for (std::size_t i = 0; i < copy.traverses.size(); ++i) {
        traverseKeys(copy.traverses[i]).save(target, traverseSection(i));
        forEachOverride(copy.traverses[i], [&](const char* name, auto& opt, auto table) {
            if (opt) table(*opt).save(target, traverseSection(i) + "." + name);
        });
    }
}

void ScenarioOptions::check() const {
    common::OptionsCheck c("scenario");
    checkScenarioKeys(c, *this);
    checkWorld(c, world);
    checkVehicle(c, vehicle, "vehicle");
    checkCamera(c, ceiling_camera, "ceiling_camera");
    checkCamera(c, forward_camera, "forward_camera");
    checkCameraMount(c, ceiling_camera, "ceiling_camera", world.ceiling_height_m);
    checkCameraMount(c, forward_camera, "forward_camera", world.ceiling_height_m);
    checkLidar(c, lidar, "lidar", world);
    checkOdometry(c, odometry, "odometry");
    c.require(!imu.label.empty(), "imu.label", "not empty");
    c.require(imu.noise_std_deg >= 0 && imu.noise_std_deg <= 10, "imu.noise_std_deg", "in [0, 10]");
    c.require(imu.bias_std_deg >= 0 && imu.bias_std_deg <= 10, "imu.bias_std_deg", "in [0, 10]");
    c.require(!traverses.empty(), "traverse_count", ">= 1");
    for (std::size_t i = 0; i < traverses.size(); ++i) checkTraverse(c, *this, i);
    c.throwIfFailed();
}

ScenarioOptions ScenarioOptions::fromFile(const std::string& path) {
    if (!std::filesystem::is_regular_file(path)) {
        throw ConfigError(path + ": scenario file does not exist");
    }
    mrpt::config::CConfigFile file(path);
    ScenarioOptions s;
    s.source_name = path;
    s.loadFromConfigFile(file, "");
    try {
        s.check();
    } catch (const ConfigError& e) {
        throw ConfigError(path + ": " + e.what());
    }
    return s;
}

std::string ScenarioOptions::toIniText() const {
    mrpt::config::CConfigFileMemory mem;
    saveToConfigFile(mem, "");
    return "# Fully resolved lookup-sim scenario (reads back with --scenario).\n" +
           mem.getContent();
}

std::string findPreset(const std::string& name, const std::vector<std::string>& search_dirs) {
    std::string tried;
    for (const auto& dir : search_dirs) {
        const std::string path = dir + "/" + name + ".ini";
        if (std::filesystem::is_regular_file(path)) return path;
        tried += (tried.empty() ? "" : ", ") + path;
    }
    throw common::ConfigError("unknown preset '" + name + "' (tried " + tried + ")");
}

}  // namespace lookup::sim

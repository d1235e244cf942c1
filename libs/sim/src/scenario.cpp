#include "lookup/sim/scenario.h"

#include <lookup/common/config.h>
#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>
#include <mrpt/core/bits_math.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <sstream>

namespace lookup::sim {
namespace {

using common::ConfigError;
using common::IniSection;

/// One table of (key, field) per section drives loading, saving and the unknown-key check, so
/// the three can never disagree.
class KeyTable {
  public:
    void add(const std::string& key, double& v) {
        entries_.push_back({key, [&v, key](const IniSection& s) { v = s.getDouble(key, v); },
                            [&v]() { return fmt(v); }});
    }
    void add(const std::string& key, int& v) {
        entries_.push_back({key, [&v, key](const IniSection& s) { v = s.getInt(key, v); },
                            [&v]() { return std::to_string(v); }});
    }
    void add(const std::string& key, uint64_t& v) {
        entries_.push_back({key,
                            [&v, key](const IniSection& s) {
                                const std::string text = s.getString(key, "");
                                if (text.empty()) return;
                                std::size_t used = 0;
                                try {
                                    v = std::stoull(text, &used);
                                } catch (const std::exception&) {
                                    used = 0;
                                }
                                if (used != text.size() || text[0] == '-') {
                                    throw ConfigError(s.where(key) + "'" + text +
                                                      "' is not a non-negative integer");
                                }
                            },
                            [&v]() { return std::to_string(v); }});
    }
    void add(const std::string& key, std::string& v) {
        entries_.push_back({key, [&v, key](const IniSection& s) { v = s.getString(key, v); },
                            [&v]() { return v; }});
    }
    void add(const std::string& prefix, MountPose& m) {
        add(prefix + "x_m", m.x_m);
        add(prefix + "y_m", m.y_m);
        add(prefix + "z_m", m.z_m);
        add(prefix + "yaw_deg", m.yaw_deg);
        add(prefix + "pitch_deg", m.pitch_deg);
        add(prefix + "roll_deg", m.roll_deg);
    }

    void load(const IniSection& s) const {
        std::vector<std::string> known;
        for (const auto& e : entries_) known.push_back(e.key);
        s.rejectUnknownKeys(known);
        for (const auto& e : entries_) e.load(s);
    }
    void save(mrpt::config::CConfigFileBase& target, const std::string& section) const {
        for (const auto& e : entries_) target.write(section, e.key, e.text());
    }

  private:
    static std::string fmt(double v) {
        std::ostringstream os;
        os.precision(12);
        os << v;
        return os.str();
    }
    struct Entry {
        std::string key;
        std::function<void(const IniSection&)> load;
        std::function<std::string()> text;
    };
    std::vector<Entry> entries_;
};

KeyTable worldKeys(WorldOptions& w) {
    KeyTable t;
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
    t.add("grid_resolution_m", w.grid_resolution_m);
    t.add("wall_roughness_m", w.wall_roughness_m);
    t.add("niche_spacing_m", w.niche_spacing_m);
    t.add("niche_depth_m", w.niche_depth_m);
    t.add("niche_width_m", w.niche_width_m);
    return t;
}

KeyTable vehicleKeys(VehicleOptions& v) {
    KeyTable t;
    t.add("name", v.name);
    t.add("wheelbase_m", v.wheelbase_m);
    t.add("track_m", v.track_m);
    return t;
}

KeyTable cameraKeys(CameraOptions& c) {
    KeyTable t;
    t.add("label", c.label);
    t.add("rate_hz", c.rate_hz);
    t.add("phase_s", c.phase_s);
    t.add("width_px", c.width_px);
    t.add("height_px", c.height_px);
    t.add("hfov_deg", c.hfov_deg);
    t.add("pose_", c.mount);
    t.add("exposure_ms", c.exposure_ms);
    t.add("exposure_variation", c.exposure_variation);
    t.add("noise_std_dn", c.noise_std_dn);
    t.add("light_gain", c.light_gain);
    t.add("light_falloff_exp", c.light_falloff_exp);
    t.add("max_range_m", c.max_range_m);
    return t;
}

KeyTable lidarKeys(LidarOptions& l) {
    KeyTable t;
    t.add("label", l.label);
    t.add("rate_hz", l.rate_hz);
    t.add("phase_s", l.phase_s);
    t.add("aperture_deg", l.aperture_deg);
    t.add("resolution_deg", l.resolution_deg);
    t.add("max_range_m", l.max_range_m);
    t.add("noise_std_m", l.noise_std_m);
    t.add("pose_", l.mount);
    return t;
}

KeyTable odometryKeys(OdometryOptions& o) {
    KeyTable t;
    t.add("label", o.label);
    t.add("rate_hz", o.rate_hz);
    t.add("phase_s", o.phase_s);
    t.add("scale_error", o.scale_error);
    t.add("yaw_bias_deg_per_m", o.yaw_bias_deg_per_m);
    t.add("noise_std_m", o.noise_std_m);
    t.add("noise_std_deg", o.noise_std_deg);
    return t;
}

KeyTable traverseKeys(TraverseOptions& tr) {
    KeyTable t;
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
    return t;
}

std::string traverseSection(std::size_t i) { return "traverse_" + std::to_string(i); }

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
}

}  // namespace

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

void ScenarioOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                         const std::string& /*section*/) {
    IniSection sc(source, "scenario", source_name);
    if (!sc.exists()) throw ConfigError(source_name + " [scenario]: required section is missing");
    int traverse_count = 0;
    {
        KeyTable t;
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

    std::vector<std::string> known = {"scenario",       "world", "vehicle", "ceiling_camera",
                                      "forward_camera", "lidar", "odometry"};
    for (int i = 0; i < traverse_count; ++i) known.push_back(traverseSection(i));
    std::vector<std::string> sections;
    source.getAllSections(sections);
    for (const auto& s : sections) {
        if (!s.empty() && std::find(known.begin(), known.end(), s) == known.end()) {
            throw ConfigError(source_name + " [" + s +
                              "]: unknown section (traverse sections must be traverse_0 .. "
                              "traverse_" +
                              std::to_string(traverse_count - 1) + ")");
        }
    }

    worldKeys(world).load(IniSection(source, "world", source_name));
    vehicleKeys(vehicle).load(IniSection(source, "vehicle", source_name));
    cameraKeys(ceiling_camera).load(IniSection(source, "ceiling_camera", source_name));
    cameraKeys(forward_camera).load(IniSection(source, "forward_camera", source_name));
    lidarKeys(lidar).load(IniSection(source, "lidar", source_name));
    odometryKeys(odometry).load(IniSection(source, "odometry", source_name));

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
    }
}

void ScenarioOptions::saveToConfigFile(mrpt::config::CConfigFileBase& target,
                                       const std::string& /*section*/) const {
    ScenarioOptions copy = *this;  // the key tables bind mutable references
    int traverse_count = static_cast<int>(traverses.size());
    {
        KeyTable t;
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
    for (std::size_t i = 0; i < copy.traverses.size(); ++i) {
        traverseKeys(copy.traverses[i]).save(target, traverseSection(i));
    }
}

void ScenarioOptions::check() const {
    common::OptionsCheck c("scenario");
    c.require(!name.empty(), "name", "non-empty");
    c.require(threads >= 0, "threads", ">= 0");
    c.require(start_time_s >= 0, "start_time_s", ">= 0");
    c.require(traverse_gap_s >= 0, "traverse_gap_s", ">= 0");
    const WorldOptions& w = world;
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
    c.require(w.bump_amplitude_m >= 0 && w.bump_amplitude_m <= 0.5, "world.bump_amplitude_m",
              "in [0, 0.5]");
    c.require(w.bump_wavelength_m > 0.2, "world.bump_wavelength_m", "> 0.2");
    c.require(w.floor_roughness_m >= 0 && w.floor_roughness_m <= 0.3, "world.floor_roughness_m",
              "in [0, 0.3]");
    c.require(w.rock_contrast >= 0 && w.rock_contrast <= 2, "world.rock_contrast", "in [0, 2]");
    c.require(w.bolt_spacing_m == 0 || w.bolt_spacing_m >= 0.3, "world.bolt_spacing_m",
              "0 or >= 0.3");
    c.require(w.bolt_plate_m > 0 && w.bolt_plate_m < 0.5, "world.bolt_plate_m", "in (0, 0.5)");
    c.require(w.mesh_fraction >= 0 && w.mesh_fraction <= 1, "world.mesh_fraction", "in [0, 1]");
    c.require(w.mesh_pitch_m >= 0.02, "world.mesh_pitch_m", ">= 0.02");
    c.require(w.shotcrete_fraction >= 0 && w.shotcrete_fraction <= 1, "world.shotcrete_fraction",
              "in [0, 1]");
    c.require(w.texture_image_size_m > 0, "world.texture_image_size_m", "> 0");
    c.require(w.duct_radius_m >= 0 && w.duct_radius_m < 1.5, "world.duct_radius_m", "in [0, 1.5)");
    c.require(w.pipe_radius_m >= 0 && w.pipe_radius_m < 0.5, "world.pipe_radius_m", "in [0, 0.5)");
    c.require(w.duct_drop_m > w.duct_radius_m, "world.duct_drop_m", "> duct_radius_m");
    c.require(w.pipe_drop_m > w.pipe_radius_m, "world.pipe_drop_m", "> pipe_radius_m");
    c.require(w.cable_span_m == 0 || w.cable_span_m >= 0.5, "world.cable_span_m", "0 or >= 0.5");
    c.require(w.cable_sag_m >= 0 && w.cable_sag_m < 1, "world.cable_sag_m", "in [0, 1)");
    c.require(w.light_spacing_m == 0 || w.light_spacing_m >= 2, "world.light_spacing_m",
              "0 or >= 2");
    c.require(w.sign_spacing_m == 0 || w.sign_spacing_m >= 5, "world.sign_spacing_m", "0 or >= 5");
    c.require(w.grid_resolution_m >= 0.02 && w.grid_resolution_m <= 0.5, "world.grid_resolution_m",
              "in [0.02, 0.5]");
    c.require(w.wall_roughness_m >= 0 && w.wall_roughness_m <= 0.5, "world.wall_roughness_m",
              "in [0, 0.5]");
    c.require(w.niche_spacing_m == 0 || w.niche_spacing_m >= 5, "world.niche_spacing_m",
              "0 or >= 5");
    c.require(w.niche_depth_m > 0 && w.niche_depth_m <= 10, "world.niche_depth_m", "in (0, 10]");
    c.require(w.niche_width_m >= 0.5 && w.niche_width_m <= 10, "world.niche_width_m",
              "in [0.5, 10]");
    c.require(vehicle.wheelbase_m > 0.5, "vehicle.wheelbase_m", "> 0.5");
    c.require(vehicle.track_m > 0.5, "vehicle.track_m", "> 0.5");
    checkCamera(c, ceiling_camera, "ceiling_camera");
    checkCamera(c, forward_camera, "forward_camera");
    c.require(ceiling_camera.mount.z_m > 0.2 && ceiling_camera.mount.z_m < w.ceiling_height_m - 0.5,
              "ceiling_camera.pose_z_m", "in (0.2, ceiling_height_m - 0.5)");
    c.require(forward_camera.mount.z_m > 0.2 && forward_camera.mount.z_m < w.ceiling_height_m - 0.5,
              "forward_camera.pose_z_m", "in (0.2, ceiling_height_m - 0.5)");
    c.require(!lidar.label.empty(), "lidar.label", "non-empty");
    c.require(lidar.rate_hz > 0 && lidar.rate_hz <= 200, "lidar.rate_hz", "in (0, 200]");
    c.require(lidar.phase_s >= 0, "lidar.phase_s", ">= 0");
    c.require(lidar.aperture_deg > 0 && lidar.aperture_deg <= 360, "lidar.aperture_deg",
              "in (0, 360]");
    c.require(lidar.resolution_deg >= 0.05 && lidar.resolution_deg <= 10, "lidar.resolution_deg",
              "in [0.05, 10]");
    c.require(lidar.max_range_m > 1, "lidar.max_range_m", "> 1");
    c.require(lidar.noise_std_m >= 0, "lidar.noise_std_m", ">= 0");
    c.require(lidar.mount.z_m > 0.2 && lidar.mount.z_m < w.ceiling_height_m - w.arch_radius_m,
              "lidar.pose_z_m", "in (0.2, ceiling_height_m - arch_radius_m): the scan plane");
    c.require(!odometry.label.empty(), "odometry.label", "non-empty");
    c.require(odometry.rate_hz > 0 && odometry.rate_hz <= 1000, "odometry.rate_hz", "in (0, 1000]");
    c.require(odometry.phase_s >= 0, "odometry.phase_s", ">= 0");
    c.require(odometry.noise_std_m >= 0, "odometry.noise_std_m", ">= 0");
    c.require(odometry.noise_std_deg >= 0, "odometry.noise_std_deg", ">= 0");
    c.require(!traverses.empty(), "traverse_count", ">= 1");
    for (std::size_t i = 0; i < traverses.size(); ++i) {
        const TraverseOptions& t = traverses[i];
        const std::string p = traverseSection(i);
        c.require(!t.name.empty() && t.name.find_first_of("/\\ .") == std::string::npos,
                  p + ".name", "a non-empty file stem without '/', '\\', ' ' or '.'");
        for (std::size_t j = 0; j < i; ++j) {
            c.require(traverses[j].name != t.name, p + ".name",
                      "unique (repeats traverse_" + std::to_string(j) + ")");
        }
        std::stringstream roles(t.roles);
        std::string role;
        bool any = false;
        while (std::getline(roles, role, ',')) {
            role.erase(0, role.find_first_not_of(" \t"));
            role.erase(role.find_last_not_of(" \t") + 1);
            any = true;
            c.require(role == "mapping" || role == "reference" || role == "query", p + ".roles",
                      "a comma list of mapping, reference, query (got '" + role + "')");
        }
        c.require(any, p + ".roles", "non-empty");
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

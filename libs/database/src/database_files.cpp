#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/database/reference.h"

namespace lookup::database {
namespace {

std::string join(const std::vector<std::string>& items) {
    std::string out;
    for (const auto& s : items) out += (out.empty() ? "" : ",") + s;
    return out;
}

std::vector<std::string> split(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream in(s);
    std::string item;
    while (std::getline(in, item, ',')) {
        if (!item.empty()) out.push_back(item);
    }
    return out;
}

// [ceiling_camera] / [forward_camera]: MRPT's TCamera reader takes "fx = abc" as 0, so the
// keys and values are checked first, and the intrinsics must be usable.
// `may_be_unset`: all-zero focal lengths mean "no such camera" (a survey without forward
// images writes MRPT's default TCamera).
void readCamera(const mrpt::config::CConfigFileBase& cfg, const std::string& path,
                const std::string& section, mrpt::img::TCamera& camera, bool may_be_unset) {
    try {
        if (!cfg.sectionExists(section)) {
            throw common::ConfigError(path + ": no [" + section + "] section");
        }
        common::checkMrptSection(cfg, section, [&](const mrpt::config::CConfigFileBase& view) {
            camera.loadFromConfigFile(section, view);
        });
        const common::IniSection s(cfg, section, path);
        if (may_be_unset && camera.fx() == 0 && camera.fy() == 0) return;
        if (!(camera.fx() > 0 && camera.fy() > 0 && std::isfinite(camera.fx()) &&
              std::isfinite(camera.fy()))) {
            throw common::ConfigError(s.where("fx") + "focal lengths must be finite and > 0");
        }
        if (camera.ncols == 0 || camera.nrows == 0) {
            throw common::ConfigError(s.where("resolution") + "image size must be > 0");
        }
    } catch (const common::ConfigError& e) {
        throw DatabaseError(e.what());
    }
}

// db.ini's ceiling_stamp_row ("first" when absent, as older databases have it).
common::StampRow stampRowOf(const common::IniSection& db) {
    const std::string name = db.getString("ceiling_stamp_row", "first");
    if (const auto row = common::enumValue(common::stampRowNames(), name)) return *row;
    throw DatabaseError(db.where("ceiling_stamp_row") + "'" + name + "' is not first or middle");
}

}  // namespace

DatabaseInfo readDatabaseInfo(const std::string& path) {
    if (!std::filesystem::is_regular_file(path)) {
        throw DatabaseError(path + ": no such file (not a LookUP database?)");
    }
    std::unique_ptr<common::NamedConfigFile> file;
    try {
        file = common::loadIniFile(path);
    } catch (const common::ConfigError& e) {
        throw DatabaseError(e.what());
    }
    const auto& cfg = *file;
    DatabaseInfo info;
    try {
        common::IniSection db(cfg, "database", path);
        db.rejectUnknownKeys({"format_version", "name", "reference_count", "ceiling_camera_label",
                              "forward_camera_label", "ceiling_height_m", "pose_source", "map",
                              "source_rawlogs", "ceiling_readout_ms", "ceiling_stamp_row",
                              "ceiling_time_offset_sigma_s"});
        if (db.requireInt("format_version") != 1) {
            throw DatabaseError(db.where("format_version") + "unsupported version");
        }
        info.name = db.getString("name", "");
        const int count = db.requireInt("reference_count");
        if (count < 0) throw DatabaseError(db.where("reference_count") + "negative");
        info.reference_count = static_cast<std::size_t>(count);
        info.ceiling_camera_label = db.requireString("ceiling_camera_label");
        info.forward_camera_label = db.getString("forward_camera_label", "");
        info.ceiling_height_m = db.requireDouble("ceiling_height_m");
        info.pose_source = db.getString("pose_source", "");
        info.map_file = db.getString("map", "");
        info.source_rawlogs = split(db.getString("source_rawlogs", ""));
        info.ceiling_readout_ms = db.getDouble("ceiling_readout_ms", 0.0, 0.0, 999.999);
        info.ceiling_stamp_row = stampRowOf(db);
        if (db.has("ceiling_time_offset_sigma_s")) {
            info.ceiling_time_offset_sigma_s =
                db.getDouble("ceiling_time_offset_sigma_s", 0.0, 0.0, 1.0);
        }
        common::IniSection heat(cfg, "heatmaps", path);
        info.heatmaps_dir = heat.getString("directory", "");
    } catch (const common::ConfigError& e) {
        throw DatabaseError(e.what());
    }
    readCamera(cfg, path, "ceiling_camera", info.ceiling_camera, false);
    if (cfg.sectionExists("forward_camera")) {
        readCamera(cfg, path, "forward_camera", info.forward_camera, true);
    }
    return info;
}

void writeDatabaseInfo(const std::string& path, const DatabaseInfo& info) {
    mrpt::config::CConfigFileMemory cfg;
    cfg.write("database", "format_version", 1);
    cfg.write("database", "name", info.name);
    cfg.write("database", "reference_count", static_cast<int>(info.reference_count));
    cfg.write("database", "ceiling_camera_label", info.ceiling_camera_label);
    cfg.write("database", "forward_camera_label", info.forward_camera_label);
    cfg.write("database", "ceiling_height_m", info.ceiling_height_m);
    cfg.write("database", "pose_source", info.pose_source);
    cfg.write("database", "map", info.map_file);
    cfg.write("database", "source_rawlogs", join(info.source_rawlogs));
    if (info.ceiling_readout_ms > 0) {
        cfg.write("database", "ceiling_readout_ms", info.ceiling_readout_ms);
        cfg.write("database", "ceiling_stamp_row",
                  common::enumName(common::stampRowNames(), info.ceiling_stamp_row));
    }
    if (info.ceiling_time_offset_sigma_s) {
        cfg.write("database", "ceiling_time_offset_sigma_s", *info.ceiling_time_offset_sigma_s);
    }
    info.ceiling_camera.saveToConfigFile("ceiling_camera", cfg);
    info.forward_camera.saveToConfigFile("forward_camera", cfg);
    std::ofstream out(path);
    if (!out) throw common::WriteError(path, "cannot open for writing");
    out << "# LookUP reference database (written by lookup-survey; see docs/survey.md)\n";
    out << cfg.getContent() << "\n";
    out << "# Quality heat maps (paper Sec. III-C), one image per reference named <id>.png in\n"
           "# this folder (relative to the database); filled in by lookup-train.\n"
           "[heatmaps]\n"
           "directory = "
        << info.heatmaps_dir << "\n\n";
    out << "# Options used to build the database\n" << info.options_ini << "\n";
    out.close();
    if (!out) throw common::WriteError(path, "write failed");
}

}  // namespace lookup::database

#include <mrpt/config/CConfigFile.h>
#include <mrpt/config/CConfigFileMemory.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <stdexcept>

#include "lookup/common/config.h"
#include "lookup/sim/scenario.h"
#include "lookup/suite/suite.h"
#include "suite_internal.h"

namespace lookup::suite {
namespace fs = std::filesystem;

std::vector<std::uint64_t> parseSeeds(const std::string& text) {
    std::vector<std::uint64_t> seeds;
    std::size_t start = 0;
    while (start <= text.size()) {
        const std::size_t comma = std::min(text.find(',', start), text.size());
        const std::string item = text.substr(start, comma - start);
        const std::size_t dash = item.find('-');
        std::size_t used_lo = 0, used_hi = 0;
        try {
            const std::string lo_text = item.substr(0, dash);
            const std::string hi_text = dash == std::string::npos ? lo_text : item.substr(dash + 1);
            const std::uint64_t lo = std::stoull(lo_text, &used_lo);
            const std::uint64_t hi = std::stoull(hi_text, &used_hi);
            if (used_lo != lo_text.size() || used_hi != hi_text.size() || lo > hi ||
                hi - lo > 10000 || item.find_first_of("+ ") != std::string::npos) {
                throw std::invalid_argument(item);
            }
            for (std::uint64_t s = lo; s <= hi; ++s) seeds.push_back(s);
        } catch (const std::exception&) {
            throw std::invalid_argument("seeds '" + text + "': '" + item +
                                        "' is not a seed or a range A-B");
        }
        start = comma + 1;
    }
    std::sort(seeds.begin(), seeds.end());
    seeds.erase(std::unique(seeds.begin(), seeds.end()), seeds.end());
    return seeds;
}

namespace {

/// A file named in the suite: a path with a folder is relative to the suite file; a bare name
/// is looked up beside the suite file, then in the share folders.
std::string resolveFile(const common::IniSection& s, const std::string& key,
                        const std::string& suite_dir, const std::vector<std::string>& share_dirs) {
    const std::string name = s.requireString(key);
    const fs::path p(name);
    std::vector<fs::path> candidates;
    if (p.is_absolute()) {
        candidates = {p};
    } else {
        candidates = {fs::path(suite_dir) / p};
        if (!p.has_parent_path()) {
            for (const auto& d : share_dirs) candidates.push_back(fs::path(d) / p);
        }
    }
    for (const auto& c : candidates) {
        if (fs::is_regular_file(c)) return c.string();
    }
    throw common::ConfigError(s.where(key) + "'" + name + "' not found beside the suite file" +
                              (p.has_parent_path() ? "" : " nor in the share folders"));
}

/// Section names in the order the file gives them (the table keeps the author's order).
std::vector<std::string> sectionsInFileOrder(const std::string& path) {
    std::ifstream in(path);
    std::vector<std::string> sections;
    std::string line;
    while (std::getline(in, line)) {
        const auto open = line.find_first_not_of(" \t");
        if (open == std::string::npos || line[open] != '[') continue;
        const auto close = line.find(']', open);
        if (close == std::string::npos) continue;
        const std::string name = line.substr(open + 1, close - open - 1);
        if (std::find(sections.begin(), sections.end(), name) == sections.end()) {
            sections.push_back(name);
        }
    }
    return sections;
}

Condition readCondition(const mrpt::config::CConfigFileBase& ini, const std::string& section,
                        const std::string& source, const std::string& suite_dir,
                        const std::vector<std::string>& share_dirs,
                        const std::string& default_localize_ini) {
    const common::IniSection s(ini, section, source);
    Condition c;
    c.name = section.substr(std::string("condition.").size());
    const std::string preset = s.requireString("preset");
    if (fs::path(preset).extension() == ".ini") {
        c.scenario_path = resolveFile(s, "preset", suite_dir, {});
    } else {
        std::vector<std::string> dirs;
        for (const auto& d : share_dirs) dirs.push_back(d + "/scenarios");
        try {
            c.scenario_path = sim::findPreset(preset, dirs);
        } catch (const std::exception& e) {
            throw common::ConfigError(s.where("preset") + e.what());
        }
    }
    c.localize_ini = s.has("localize_ini") ? resolveFile(s, "localize_ini", suite_dir, share_dirs)
                                           : default_localize_ini;
    if (s.has("survey_ini")) c.survey_ini = resolveFile(s, "survey_ini", suite_dir, share_dirs);
    std::vector<std::string> keys;
    ini.getAllKeys(section, keys);
    for (const auto& key : keys) {
        if (key == "preset" || key == "localize_ini" || key == "survey_ini") continue;
        const std::size_t dot = key.rfind('.');  // sections may hold dots: traverse_3.world
        if (dot == std::string::npos || dot == 0 || dot + 1 == key.size()) {
            throw common::ConfigError(s.where(key) +
                                      "unknown key (overrides are SECTION.KEY = VALUE)");
        }
        c.overrides.push_back({key.substr(0, dot), key.substr(dot + 1), s.requireString(key)});
    }
    // Refuse a typo'd override now rather than after hours of other jobs.
    scenarioFor(c, 1, source, 1);
    return c;
}

}  // namespace

SuiteOptions SuiteOptions::fromFile(const std::string& path,
                                    const std::vector<std::string>& share_dirs) {
    if (!fs::is_regular_file(path)) throw common::ConfigError(path + ": suite file not found");
    mrpt::config::CConfigFile ini(path);
    SuiteOptions o;
    o.source = path;
    const std::string dir = fs::path(path).parent_path().string();
    const common::IniSection s(ini, "suite", path);
    if (!s.exists()) throw common::ConfigError(path + ": no [suite] section");
    s.rejectUnknownKeys({"name", "seeds", "localize_ini", "max_frames"});
    o.name = s.getString("name", o.name);
    try {
        o.seeds = parseSeeds(s.getString("seeds", "1"));
    } catch (const std::invalid_argument& e) {
        throw common::ConfigError(s.where("seeds") + e.what());
    }
    const int max_frames = s.getInt("max_frames", 0);
    if (max_frames < 0) throw common::ConfigError(s.where("max_frames") + "must be >= 0");
    o.max_frames = static_cast<std::size_t>(max_frames);
    const std::string localize_ini =
        s.has("localize_ini") ? resolveFile(s, "localize_ini", dir, share_dirs) : "";
    for (const auto& section : sectionsInFileOrder(path)) {
        if (section == "suite") continue;
        if (section.rfind("condition.", 0) != 0 || section.size() == 10) {
            throw common::ConfigError(path + " [" + section +
                                      "]: unknown section (expected [suite] or [condition.NAME])");
        }
        o.conditions.push_back(readCondition(ini, section, path, dir, share_dirs, localize_ini));
    }
    if (o.conditions.empty()) throw common::ConfigError(path + ": no [condition.NAME] section");
    return o;
}

sim::ScenarioOptions scenarioFor(const Condition& c, std::uint64_t seed,
                                 const std::string& suite_source, int threads) {
    mrpt::config::CConfigFile preset(c.scenario_path);
    mrpt::config::CConfigFileMemory merged;
    std::vector<std::string> sections, keys;
    preset.getAllSections(sections);
    for (const auto& section : sections) {
        preset.getAllKeys(section, keys);
        for (const auto& key : keys) {
            merged.write(section, key, preset.read_string(section, key, "", true));
        }
    }
    for (const auto& [section, key, value] : c.overrides) merged.write(section, key, value);
    sim::ScenarioOptions options;
    options.source_name = suite_source + " [condition." + c.name + "] over " + c.scenario_path;
    options.loadFromConfigFile(merged, "");
    try {
        options.check();
    } catch (const common::ConfigError& e) {
        throw common::ConfigError(options.source_name + ": " + e.what());
    }
    options.seed = seed;
    options.threads = threads;
    return options;
}

}  // namespace lookup::suite

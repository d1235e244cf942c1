#include "lookup/eval/run_io.h"

#include <mrpt/config/CConfigFile.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/rawlog_io.h"

namespace lookup::eval {
namespace fs = std::filesystem;
using ConfigError = RunError;  // bad run data: exit 2, not an options error

namespace {

const char* const kColumns[] = {"time_s",     "status",       "reason",     "x",
                                "y",          "yaw",          "cov_xx",     "cov_xy",
                                "cov_yy",     "cov_tt",       "coarse_x",   "coarse_y",
                                "coarse_yaw", "inlier_share", "references", "ms"};

// Optional: frames.csv files written before it lack it.
const char* const kHeightColumn = "z";

std::vector<std::string> splitCsv(const std::string& line) {
    std::vector<std::string> out;
    std::string cell;
    std::istringstream in(line);
    while (std::getline(in, cell, ',')) out.push_back(cell);
    if (!line.empty() && line.back() == ',') out.emplace_back();
    return out;
}

double parseNumber(const std::string& text, const std::string& where) {
    char* end = nullptr;
    const double v = std::strtod(text.c_str(), &end);
    if (text.empty() || *end != '\0') throw ConfigError(where + "'" + text + "' is not a number");
    return v;
}

// timing.json's throughput and frame counts into `run`.
void readTiming(const std::string& timing, Run& run) {
    std::ifstream in(timing);
    try {
        const auto j = nlohmann::json::parse(in);
        run.frames_per_s = j.value("frames_per_s", 0.0);
        if (j.contains("refine_ms_per_frame") && j["refine_ms_per_frame"].is_object()) {
            run.match_ms_per_frame = j["refine_ms_per_frame"].value("match", 0.0);
        }
        run.frames_dropped = j.value("frames_dropped", 0);
        run.timing_frames = j.value("frames", -1L);
        run.has_timing = true;
    } catch (const std::exception& e) {
        throw ConfigError(timing + ": malformed JSON: " + e.what());
    }
}

// Column name to index, refusing a header without one of kColumns.
std::map<std::string, size_t> columnsOf(const std::vector<std::string>& header,
                                        const std::string& csv) {
    std::map<std::string, size_t> col;
    for (size_t i = 0; i < header.size(); ++i) col[header[i]] = i;
    for (const char* name : kColumns) {
        if (!col.count(name)) throw ConfigError(csv + ":1: missing column '" + name + "'");
    }
    return col;
}

// The cells of one frames.csv line by column name; `where` ("<csv>:<line>: ") prefixes errors.
struct CsvRow {
    const std::vector<std::string>& cells;
    const std::map<std::string, size_t>& col;
    const std::string& where;

    const std::string& cell(const char* name) const { return cells[col.at(name)]; }
    double number(const char* name) const { return parseNumber(cell(name), where + name + ": "); }
    // An empty cell reads as 0.
    double numberOrZero(const char* name) const { return cell(name).empty() ? 0 : number(name); }
};

FrameRow parseRow(const CsvRow& row) {
    FrameRow r;
    r.time_s = row.number("time_s");
    r.status = row.cell("status");
    r.reason = row.cell("reason");
    r.has_pose = !row.cell("x").empty();
    if (r.has_pose) {
        r.x = row.number("x");
        r.y = row.number("y");
        r.yaw = row.number("yaw");
        r.cov_xx = row.number("cov_xx");
        r.cov_xy = row.number("cov_xy");
        r.cov_yy = row.number("cov_yy");
        r.cov_tt = row.number("cov_tt");
    }
    r.has_coarse = !row.cell("coarse_x").empty();
    if (r.has_coarse) {
        r.coarse_x = row.number("coarse_x");
        r.coarse_y = row.number("coarse_y");
        r.coarse_yaw = row.number("coarse_yaw");
    }
    return r;
}

// Drops a non-finite pose or coarse pose from the row; true when the row had any non-finite
// value.
bool dropNonFinite(FrameRow& r) {
    const bool pose_finite =
        std::isfinite(r.x + r.y + r.yaw + r.cov_xx + r.cov_xy + r.cov_yy + r.cov_tt);
    const bool coarse_finite = std::isfinite(r.coarse_x + r.coarse_y + r.coarse_yaw);
    if (!pose_finite) r.has_pose = false;
    if (!coarse_finite) r.has_coarse = false;
    return !pose_finite || !coarse_finite || !std::isfinite(r.time_s);
}

// Every row of frames.csv into run.frames.
void readFrames(const std::string& csv, Run& run) {
    std::ifstream in(csv);
    if (!in) throw ConfigError(csv + ": cannot open (is this a lookup-localize output folder?)");
    std::string line;
    if (!std::getline(in, line)) throw ConfigError(csv + ": empty file");
    const auto header = splitCsv(line);
    const auto col = columnsOf(header, csv);
    int line_no = 1;
    while (std::getline(in, line)) {
        ++line_no;
        if (line.empty()) continue;
        const auto cells = splitCsv(line);
        const std::string where = csv + ":" + std::to_string(line_no) + ": ";
        if (cells.size() != header.size()) {
            throw ConfigError(where + "expected " + std::to_string(header.size()) +
                              " columns, found " + std::to_string(cells.size()));
        }
        const CsvRow row{cells, col, where};
        FrameRow r = parseRow(row);
        if (dropNonFinite(r)) ++run.non_finite_rows;
        r.inlier_share = row.numberOrZero("inlier_share");
        r.references =
            row.cell("references").empty() ? 0 : static_cast<int>(row.number("references"));
        r.ms = row.numberOrZero("ms");
        if (col.count(kHeightColumn) && !row.cell(kHeightColumn).empty() && r.has_pose) {
            r.z = row.number(kHeightColumn);
            r.has_z = std::isfinite(r.z);
        }
        run.frames.push_back(std::move(r));
    }
}

}  // namespace

Run loadRun(const std::string& directory) {
    Run run;
    run.directory = directory;
    run.method = fs::path(directory).filename().string();
    const std::string ini = directory + "/run.ini";
    if (fs::exists(ini)) {
        mrpt::config::CConfigFile cfg(ini);
        run.method = common::IniSection(cfg, "run", ini).getString("method", run.method);
    }
    const std::string timing = directory + "/timing.json";
    if (fs::exists(timing)) readTiming(timing, run);
    readFrames(directory + "/frames.csv", run);
    return run;
}

std::string runProblem(const Run& run) {
    if (!run.has_timing) {
        return "no timing.json: the run did not finish (it failed, was killed or still runs)";
    }
    if (run.frames.empty()) return "frames.csv has no frames";
    if (run.timing_frames >= 0 && std::size_t(run.timing_frames) != run.frames.size()) {
        return "timing.json counts " + std::to_string(run.timing_frames) +
               " frames, frames.csv has " + std::to_string(run.frames.size()) + ": a partial run";
    }
    if (run.non_finite_rows > 0) {
        return std::to_string(run.non_finite_rows) + " frames with non-finite values";
    }
    return {};
}

std::string framesCsvHeader() {
    std::string out;
    for (const char* name : kColumns) out += std::string(out.empty() ? "" : ",") + name;
    return out + "," + kHeightColumn;
}

namespace {

/// `v` in printf `format` (fixed point) while that stays short; beyond 1e12 (no pose of a
/// mine, but garbage must still round-trip) or non-finite, the shortest exact "%.17g".
std::string cell(const char* format, double v) {
    char buf[48];
    const bool fixed = std::isfinite(v) && std::abs(v) < 1e12;
    const int n = std::snprintf(buf, sizeof buf, fixed ? format : "%.17g", v);
    return std::string(buf, static_cast<std::size_t>(std::clamp(n, 0, int(sizeof buf) - 1)));
}

}  // namespace

std::string formatFramesCsvRow(const FrameRow& r) {
    // The CSV has no quoting: reasons become one comma-free line of bounded length.
    std::string reason = r.reason.substr(0, 240);
    for (char& c : reason) {
        if (c == ',' || c == '\n' || c == '\r') c = ';';
    }
    std::string out = cell("%.6f", r.time_s) + "," + r.status + "," + reason + ",";
    if (r.has_pose) {
        for (const auto& [format, v] : {std::pair{"%.5f", r.x},
                                        {"%.5f", r.y},
                                        {"%.6f", r.yaw},
                                        {"%.4e", r.cov_xx},
                                        {"%.4e", r.cov_xy},
                                        {"%.4e", r.cov_yy},
                                        {"%.4e", r.cov_tt}}) {
            out += cell(format, v) + ",";
        }
    } else {
        out += ",,,,,,,";
    }
    if (r.has_coarse) {
        out += cell("%.5f", r.coarse_x) + "," + cell("%.5f", r.coarse_y) + "," +
               cell("%.6f", r.coarse_yaw) + ",";
    } else {
        out += ",,,";
    }
    return out + cell("%.4f", r.inlier_share) + "," + std::to_string(r.references) + "," +
           cell("%.3f", r.ms) + "," + (r.has_pose && r.has_z ? cell("%.4f", r.z) : "");
}

void writeFramesCsv(const std::string& path, const std::vector<FrameRow>& frames) {
    std::string text = framesCsvHeader() + "\n";
    for (const auto& r : frames) text += formatFramesCsvRow(r) + "\n";
    common::writeFileAtomically(path, text);
}

}  // namespace lookup::eval

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>
#include <stdexcept>

#include "lookup/common/rawlog_io.h"
#include "lookup/eval/report_json.h"
#include "lookup/suite/suite.h"
#include "suite_internal.h"

namespace lookup::suite {
namespace fs = std::filesystem;

namespace {

double meanOf(const std::vector<double>& v) {
    double s = 0;
    for (double x : v) s += x;
    return v.empty() ? 0 : s / v.size();
}

double medianOf(std::vector<double> v) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

/// Folds one job's rows into a condition's summary (the lists hold per-run values).
struct Columns {
    std::vector<double> refined, after_fix, fix_frame, fix_m, mean, median, p95, inside, coarse;
    bool some_never_fixed = false;
};

void addRun(const eval::MethodResult& m, Columns& c, ConditionSummary& s) {
    if (m.method == "coarse") {
        c.coarse.push_back(m.error.mean_m);
        return;
    }
    ++s.runs;
    c.refined.push_back(m.acceptance_share);
    c.after_fix.push_back(m.refined_after_first_fix_share);
    if (m.first_fix_frame < 0) {
        c.some_never_fixed = true;
    } else {
        c.fix_frame.push_back(static_cast<double>(m.first_fix_frame));
        c.fix_m.push_back(m.first_fix_distance_m);
    }
    c.mean.push_back(m.error.mean_m);
    c.median.push_back(m.error.median_m);
    c.p95.push_back(m.error.p95_m);
    c.inside.push_back(m.inside_95_share);
    s.max_m = std::max(s.max_m, m.error.max_m);
    s.confident_wrong += m.confident_wrong;
    s.frames_per_s_min =
        s.runs == 1 ? m.frames_per_s : std::min(s.frames_per_s_min, m.frames_per_s);
    s.frame_ms_p99_max = std::max(s.frame_ms_p99_max, m.frame_ms_p99);
}

void finish(const Columns& c, ConditionSummary& s) {
    s.refined_share = meanOf(c.refined);
    s.refined_after_first_fix_share = meanOf(c.after_fix);
    if (!c.some_never_fixed && !c.fix_frame.empty()) {
        s.first_fix_frame_median = medianOf(c.fix_frame);
        s.first_fix_frame_max = *std::max_element(c.fix_frame.begin(), c.fix_frame.end());
        s.first_fix_distance_m_max = *std::max_element(c.fix_m.begin(), c.fix_m.end());
    }
    s.mean_m = meanOf(c.mean);
    s.median_m = meanOf(c.median);
    s.p95_m = meanOf(c.p95);
    s.inside_95_share = meanOf(c.inside);
    if (!c.coarse.empty()) s.coarse_mean_m = meanOf(c.coarse);
}

std::string fmt(const char* format, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, format, v);
    return buf;
}

std::string firstFix(const ConditionSummary& s) {
    if (s.runs == 0) return "";
    if (s.first_fix_frame_max < 0) return "never (some run)";
    return fmt("%.0f", s.first_fix_frame_median) + " / " + fmt("%.0f", s.first_fix_frame_max) +
           " (" + fmt("%.1f", s.first_fix_distance_m_max) + " m)";
}

std::string markdown(const SuiteOptions& suite, const std::vector<ConditionSummary>& rows) {
    std::ostringstream out;
    out << "# Suite " << suite.name << "\n\nFrom `" << suite.source << "`, seeds";
    for (auto s : suite.seeds) out << " " << s;
    out << ". Laser-derived references, 24-point grid; figures are means over the runs (one "
           "per seed and query traverse) except where marked. `first fix`: median / worst frame "
           "of the first refined fix (worst metres driven before it). `confident wrong`: poses "
           "more than 0.5 m off and outside their reported 99.7 % ellipse, summed.\n\n"
        << "| condition | runs | refined | after first fix | first fix | mean (m) | median (m) "
           "| p95 (m) | max (m) | confident wrong | in 95 % ellipse | frames/s (min) "
           "| p99 ms (max) | coarse mean (m) |\n"
        << "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n";
    for (const auto& s : rows) {
        const bool any = s.runs > 0;
        out << "| " << s.condition << " | " << s.runs
            << (s.failed ? " (" + std::to_string(s.failed) + " failed)" : "") << " | "
            << (any ? fmt("%.1f %%", 100 * s.refined_share) : "") << " | "
            << (any ? fmt("%.1f %%", 100 * s.refined_after_first_fix_share) : "") << " | "
            << firstFix(s) << " | " << (any ? fmt("%.3f", s.mean_m) : "") << " | "
            << (any ? fmt("%.3f", s.median_m) : "") << " | " << (any ? fmt("%.3f", s.p95_m) : "")
            << " | " << (any ? fmt("%.3f", s.max_m) : "") << " | "
            << (any ? std::to_string(s.confident_wrong) : "") << " | "
            << (any ? fmt("%.1f %%", 100 * s.inside_95_share) : "") << " | "
            << (any ? fmt("%.1f", s.frames_per_s_min) : "") << " | "
            << (any ? fmt("%.1f", s.frame_ms_p99_max) : "") << " | "
            << (s.coarse_mean_m >= 0 ? fmt("%.2f", s.coarse_mean_m) : "") << " |\n";
    }
    for (const auto& s : rows) {
        for (const auto& f : s.failures) out << "\nFailed: " << s.condition << " " << f << "\n";
    }
    return out.str();
}

nlohmann::json summaryToJson(const ConditionSummary& s) {
    return {{"condition", s.condition},
            {"jobs", s.jobs},
            {"failed", s.failed},
            {"runs", s.runs},
            {"refined_share", s.refined_share},
            {"refined_after_first_fix_share", s.refined_after_first_fix_share},
            {"first_fix_frame_median", s.first_fix_frame_median},
            {"first_fix_frame_max", s.first_fix_frame_max},
            {"first_fix_distance_m_max", s.first_fix_distance_m_max},
            {"mean_m", s.mean_m},
            {"median_m", s.median_m},
            {"p95_m", s.p95_m},
            {"max_m", s.max_m},
            {"confident_wrong", s.confident_wrong},
            {"inside_95_ellipse_share", s.inside_95_share},
            {"frames_per_s_min", s.frames_per_s_min},
            {"frame_ms_p99_max", s.frame_ms_p99_max},
            {"coarse_mean_m", s.coarse_mean_m},
            {"failures", s.failures}};
}

}  // namespace

nlohmann::json toJson(const JobResult& r) {
    nlohmann::json rows = nlohmann::json::array();
    for (const auto& m : r.rows) rows.push_back(eval::toJson(m));
    return {{"condition", r.condition}, {"seed", r.seed},     {"ok", r.ok},
            {"reason", r.reason},       {"wall_s", r.wall_s}, {"rows", rows}};
}

JobResult jobFromJson(const nlohmann::json& j) {
    JobResult r;
    r.condition = j.at("condition");
    r.seed = j.at("seed");
    r.ok = j.at("ok");
    r.reason = j.at("reason");
    r.wall_s = j.at("wall_s");
    for (const auto& row : j.at("rows")) r.rows.push_back(eval::methodResultFromJson(row));
    return r;
}

std::vector<ConditionSummary> summarizeConditions(const SuiteOptions& suite,
                                                  const std::vector<JobResult>& results) {
    std::vector<ConditionSummary> out;
    for (const auto& condition : suite.conditions) {
        ConditionSummary s;
        s.condition = condition.name;
        Columns columns;
        for (const auto& r : results) {
            if (r.condition != condition.name) continue;
            ++s.jobs;
            if (!r.ok) {
                ++s.failed;
                s.failures.push_back("seed " + std::to_string(r.seed) + ": " + r.reason);
                continue;
            }
            for (const auto& m : r.rows) addRun(m, columns, s);
        }
        finish(columns, s);
        out.push_back(s);
    }
    return out;
}

void writeSuiteReport(const SuiteOptions& suite, const std::vector<JobResult>& results,
                      const std::string& out_dir) {
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) throw std::runtime_error(out_dir + ": cannot create: " + ec.message());
    const auto summaries = summarizeConditions(suite, results);
    nlohmann::json j;
    j["suite"] = suite.name;
    j["source"] = suite.source;
    j["seeds"] = suite.seeds;
    j["conditions"] = nlohmann::json::array();
    for (const auto& s : summaries) j["conditions"].push_back(summaryToJson(s));
    j["jobs"] = nlohmann::json::array();
    for (const auto& r : results) j["jobs"].push_back(toJson(r));
    common::writeFileAtomically(out_dir + "/suite.json", j.dump(2) + "\n");
    common::writeFileAtomically(out_dir + "/suite.md", markdown(suite, summaries));
}

}  // namespace lookup::suite

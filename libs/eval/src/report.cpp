#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <nlohmann/json.hpp>
#include <set>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/eval/evaluator.h"
#include "lookup/eval/report_json.h"
#include "plots.h"

namespace lookup::eval {
namespace fs = std::filesystem;

namespace {

std::string fmt(const char* format, double v) {
    char buf[64];
    std::snprintf(buf, sizeof buf, format, v);
    return buf;
}

std::string firstFix(const MethodResult& m) {
    if (m.first_fix_frame < 0) return "none";
    return std::to_string(m.first_fix_frame) + ", " + fmt("%.1f", m.first_fix_distance_m);
}

void writeMarkdown(const Report& r, const std::string& path) {
    std::ostringstream out;
    out << "# Localisation accuracy\n\n"
        << "Position error of the emitted pose against ground truth. Frames whose coarse error "
        << "exceeds " << r.options.coarse_exclusion_m
        << " m are excluded (the paper's rule); `excluded` counts them. `confident wrong`: poses "
        << "more than " << r.options.confident_wrong_min_error_m
        << " m off and outside their reported 99.7 % ellipse, over every frame. `first fix`: "
           "the first refined frame's index and the metres driven before it.\n\n"
        << "| traverse | method | frames | excluded | no pose | mean (m) | median (m) | p95 (m) "
           "| max (m) | yaw (deg) | accepted | after first fix | first fix (frame, m) "
           "| confident wrong | in 95% ellipse | frames/s | match ms/frame | p99 ms | flagged |\n"
        << "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:"
           "|---:|---|\n";
    for (const auto& m : r.rows) {
        const bool coarse = m.method == "coarse";
        out << "| " << m.traverse << " | " << m.method << " | " << m.frames << " | " << m.excluded
            << " | " << (coarse ? "" : std::to_string(m.without_pose)) << " | "
            << fmt("%.3f", m.error.mean_m) << " | " << fmt("%.3f", m.error.median_m) << " | "
            << fmt("%.3f", m.error.p95_m) << " | " << fmt("%.3f", m.error.max_m) << " | "
            << (coarse ? "" : fmt("%.2f", m.yaw_error_mean_deg)) << " | "
            << (coarse ? "" : fmt("%.1f %%", 100 * m.acceptance_share)) << " | "
            << (coarse ? "" : fmt("%.1f %%", 100 * m.refined_after_first_fix_share)) << " | "
            << (coarse ? "" : firstFix(m)) << " | "
            << (coarse ? "" : std::to_string(m.confident_wrong)) << " | "
            << (coarse ? "" : fmt("%.1f %%", 100 * m.inside_95_share)) << " | "
            << (coarse || m.frames_per_s <= 0 ? "" : fmt("%.1f", m.frames_per_s)) << " | "
            << (coarse || m.match_ms_per_frame <= 0 ? "" : fmt("%.2f", m.match_ms_per_frame))
            << " | " << (coarse || m.frame_ms_p99 <= 0 ? "" : fmt("%.1f", m.frame_ms_p99)) << " | "
            << m.flagged << " |\n";
    }
    for (const auto& m : r.rows) {
        if (m.height.count == 0) continue;
        out << "\nHeight of " << m.traverse << " / " << m.method
            << " (frames.csv `z` against the ground truth's z, " << m.height.count
            << " frames): mean " << fmt("%.3f", m.height.mean_m) << " m, p95 "
            << fmt("%.3f", m.height.p95_m) << " m, max " << fmt("%.3f", m.height.max_m) << " m.\n";
    }
    for (const auto& w : r.warnings) out << "\nWarning: " << w << "\n";
    common::writeFileAtomically(path, out.str());
}

void writeJson(const Report& r, const std::string& path) {
    nlohmann::json j;
    j["coarse_exclusion_m"] = r.options.coarse_exclusion_m;
    j["confident_wrong_min_error_m"] = r.options.confident_wrong_min_error_m;
    j["warnings"] = r.warnings;
    for (const auto& m : r.rows) {
        j["rows"].push_back(toJson(m));
    }
    common::writeFileAtomically(path, j.dump(2) + "\n");
}

/// Clustered bar chart of the mean error, like the paper's Fig. 8, drawn by gnuplot.
bool plotMeanErrors(const Report& r, const std::string& out_dir, std::string& warning) {
    std::vector<std::string> traverses, methods;
    std::map<std::pair<std::string, std::string>, double> mean;
    for (const auto& m : r.rows) {
        if (std::find(traverses.begin(), traverses.end(), m.traverse) == traverses.end())
            traverses.push_back(m.traverse);
        if (std::find(methods.begin(), methods.end(), m.method) == methods.end())
            methods.push_back(m.method);
        mean[{m.traverse, m.method}] = m.error.mean_m;
    }
    const std::string dat = out_dir + "/errors.dat", gp = out_dir + "/errors.gp";
    {
        std::ostringstream d;
        d << "traverse";
        for (const auto& me : methods) d << " \"" << me << "\"";
        d << "\n";
        for (const auto& t : traverses) {
            d << "\"" << t << "\"";
            for (const auto& me : methods) {
                auto it = mean.find({t, me});
                d << " " << (it == mean.end() ? std::string("NaN") : fmt("%.4f", it->second));
            }
            d << "\n";
        }
        common::writeFileAtomically(dat, d.str());
    }
    {
        std::ostringstream g;
        g << "set terminal pngcairo size 900,500 noenhanced\n"
          << "set output '" << out_dir << "/errors.png'\n"
          << "set style data histogram\nset style histogram clustered gap 1\n"
          << "set style fill solid 0.8 border -1\nset boxwidth 0.9\n"
          << "set ylabel 'mean position error (m)'\nset logscale y\nset grid ytics\n"
          << "set key outside right top\nset title 'Mean localisation error per traverse'\n"
          << "plot ";
        for (std::size_t i = 0; i < methods.size(); ++i) {
            g << (i ? ", \\\n     " : "") << "'" << dat << "' using " << i + 2
              << (i ? "" : ":xtic(1)") << " title columnhead(" << i + 2 << ") lc rgb '"
              << methodColour(methods[i], methods) << "'";
        }
        g << "\n";
        common::writeFileAtomically(gp, g.str());
    }
    return detail::runGnuplot(gp, out_dir, warning);
}

}  // namespace

nlohmann::json toJson(const MethodResult& m) {
    return {{"traverse", m.traverse},
            {"method", m.method},
            {"run", m.run_directory},
            {"frames", m.frames},
            {"excluded", m.excluded},
            {"without_pose", m.without_pose},
            {"evaluated", m.error.count},
            {"mean_m", m.error.mean_m},
            {"median_m", m.error.median_m},
            {"p95_m", m.error.p95_m},
            {"max_m", m.error.max_m},
            {"yaw_error_mean_deg", m.yaw_error_mean_deg},
            {"acceptance_share", m.acceptance_share},
            {"inside_95_ellipse_share", m.inside_95_share},
            {"frames_per_s", m.frames_per_s},
            {"match_ms_per_frame", m.match_ms_per_frame},
            {"frames_dropped", m.frames_dropped},
            {"first_fix_frame", m.first_fix_frame},
            {"first_fix_s", m.first_fix_s},
            {"first_fix_distance_m", m.first_fix_distance_m},
            {"refined_after_first_fix_share", m.refined_after_first_fix_share},
            {"confident_wrong", m.confident_wrong},
            {"frame_ms_p99", m.frame_ms_p99},
            {"flagged", m.flagged},
            {"height_error",
             {{"count", m.height.count},
              {"mean_m", m.height.mean_m},
              {"p95_m", m.height.p95_m},
              {"max_m", m.height.max_m}}}};
}

MethodResult methodResultFromJson(const nlohmann::json& j) {
    MethodResult m;
    j.at("traverse").get_to(m.traverse);
    j.at("method").get_to(m.method);
    j.at("run").get_to(m.run_directory);
    j.at("frames").get_to(m.frames);
    j.at("excluded").get_to(m.excluded);
    j.at("without_pose").get_to(m.without_pose);
    j.at("evaluated").get_to(m.error.count);
    j.at("mean_m").get_to(m.error.mean_m);
    j.at("median_m").get_to(m.error.median_m);
    j.at("p95_m").get_to(m.error.p95_m);
    j.at("max_m").get_to(m.error.max_m);
    j.at("yaw_error_mean_deg").get_to(m.yaw_error_mean_deg);
    j.at("acceptance_share").get_to(m.acceptance_share);
    j.at("inside_95_ellipse_share").get_to(m.inside_95_share);
    j.at("frames_per_s").get_to(m.frames_per_s);
    j.at("match_ms_per_frame").get_to(m.match_ms_per_frame);
    j.at("frames_dropped").get_to(m.frames_dropped);
    j.at("first_fix_frame").get_to(m.first_fix_frame);
    j.at("first_fix_s").get_to(m.first_fix_s);
    j.at("first_fix_distance_m").get_to(m.first_fix_distance_m);
    j.at("refined_after_first_fix_share").get_to(m.refined_after_first_fix_share);
    j.at("confident_wrong").get_to(m.confident_wrong);
    j.at("frame_ms_p99").get_to(m.frame_ms_p99);
    j.at("flagged").get_to(m.flagged);
    if (j.contains("height_error")) {  // reports written before heights have none
        const auto& h = j.at("height_error");
        h.at("count").get_to(m.height.count);
        h.at("mean_m").get_to(m.height.mean_m);
        h.at("p95_m").get_to(m.height.p95_m);
        h.at("max_m").get_to(m.height.max_m);
    }
    return m;
}

void writeReport(const Report& report, const std::string& out_dir) {
    std::error_code ec;
    fs::create_directories(out_dir, ec);
    if (ec) throw common::WriteError(out_dir, "cannot create: " + ec.message());
    Report r = report;
    std::string warning;
    if (!detail::haveGnuplot()) {
        r.warnings.push_back(
            "gnuplot not installed: errors.png and the per-traverse pictures "
            "not drawn");
    } else {
        if (!plotMeanErrors(r, out_dir, warning)) r.warnings.push_back(warning);
        warning.clear();
        if (!detail::plotRunPictures(r, out_dir, warning)) r.warnings.push_back(warning);
    }
    writeMarkdown(r, out_dir + "/report.md");
    writeJson(r, out_dir + "/report.json");
}

}  // namespace lookup::eval

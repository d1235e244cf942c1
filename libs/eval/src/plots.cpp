#include "plots.h"

#include <mrpt/io/CFileGZInputStream.h>
#include <mrpt/maps/COccupancyGridMap2D.h>
#include <mrpt/serialization/CArchive.h>

#include <algorithm>
#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/rawlog_io.h"

namespace lookup::eval {

const std::vector<std::pair<std::string, std::string>>& methodColourTable() {
    // One colour per name, fixed, so a method looks the same in every chart of every report
    // (gnuplot's own cycle has 8 colours and repeats them by column order).
    static const std::vector<std::pair<std::string, std::string>> table = {
        {"coarse", "#7f7f7f"},
        {"lookup-grid24", "#1f77b4"},
        {"lookup-fcn12", "#ff7f0e"},
        {"lookup-orb", "#2ca02c"},
        {"lookup-ecc", "#d62728"},
        {"surveyed-lookup-grid24", "#17becf"},
        {"surveyed-lookup-fcn12", "#bcbd22"},
        {"surveyed-orb-ransac", "#8c564b"},
        {"surveyed-ecc", "#e377c2"},
        {"laser-lookup-grid24", "#0b3d91"},
        {"laser-lookup-fcn12", "#b35806"},
        {"laser-orb-ransac", "#1b7837"},
        {"laser-ecc", "#9467bd"},
        {"oracle-grid", "#000000"},
        {"oracle-heatmap", "#c51b7d"},
    };
    return table;
}

std::string methodColour(const std::string& method, const std::vector<std::string>& methods) {
    const auto& table = methodColourTable();
    auto known = [&](const std::string& m) {
        return std::find_if(table.begin(), table.end(),
                            [&](const auto& e) { return e.first == m; });
    };
    if (auto it = known(method); it != table.end()) return it->second;
    static const char* kSpare[] = {"#66c2a5", "#fc8d62", "#8da0cb", "#a6d854",
                                   "#e6ab02", "#a6761d", "#4d4d4d", "#fb9a99"};
    std::size_t rank = 0;
    for (const auto& m : methods) {
        if (m == method) break;
        if (known(m) == table.end()) ++rank;
    }
    return kSpare[rank % (sizeof kSpare / sizeof kSpare[0])];
}

std::vector<std::array<double, 2>> loadMapWalls(const std::string& path) {
    mrpt::maps::COccupancyGridMap2D grid;
    mrpt::io::CFileGZInputStream f;
    std::error_code ec;
    if (!std::filesystem::is_regular_file(path, ec) || !f.open(path)) {
        throw common::ConfigError(path + ": cannot open the map");
    }
    try {
        auto arch = mrpt::serialization::archiveFrom(f);
        arch >> grid;
    } catch (const std::exception& e) {
        throw common::ConfigError(path + ": not an MRPT occupancy grid (" +
                                  std::string(e.what()).substr(0, 200) + ")");
    }
    std::vector<std::array<double, 2>> walls;
    const int nx = static_cast<int>(grid.getSizeX()), ny = static_cast<int>(grid.getSizeY());
    auto occupied = [&](int x, int y) { return grid.getCell(x, y) < 0.5f; };
    for (int y = 1; y + 1 < ny; ++y) {
        for (int x = 1; x + 1 < nx; ++x) {
            if (!occupied(x, y)) continue;
            if (occupied(x - 1, y) && occupied(x + 1, y) && occupied(x, y - 1) &&
                occupied(x, y + 1)) {
                continue;
            }
            walls.push_back({grid.idx2x(x), grid.idx2y(y)});
        }
    }
    return walls;
}

namespace detail {

bool haveGnuplot() { return std::system("command -v gnuplot >/dev/null 2>&1") == 0; }

bool runGnuplot(const std::string& gp, const std::string& out_dir, std::string& warning) {
    const std::string log = out_dir + "/gnuplot.log";
    if (std::system(("gnuplot '" + gp + "' 2>>'" + log + "'").c_str()) == 0) return true;
    // pngcairo may be missing from a minimal gnuplot; fall back to the plain png terminal.
    std::string script;
    {
        std::ifstream in(gp);
        script.assign(std::istreambuf_iterator<char>(in), {});
    }
    const auto at = script.find("pngcairo");
    if (at != std::string::npos) {
        script.replace(at, 8, "png");
        common::writeFileAtomically(gp, script);
        if (std::system(("gnuplot '" + gp + "' 2>>'" + log + "'").c_str()) == 0) return true;
    }
    warning = "gnuplot failed on " + gp + ", see " + log;
    return false;
}

std::string fileStem(const std::string& name) {
    std::string s = name.empty() ? "unnamed" : name;
    for (char& c : s) {
        if (!std::isalnum(static_cast<unsigned char>(c)) && c != '-' && c != '_' && c != '.')
            c = '_';
    }
    return s;
}

namespace {

std::string num(double v) {
    char buf[32];
    std::snprintf(buf, sizeof buf, "%.4f", v);
    return buf;
}

/// Writes `rows` (already formatted lines) to `path`; false (nothing written) when empty.
bool writeDat(const std::string& path, const std::vector<std::string>& rows) {
    if (rows.empty()) return false;
    std::ostringstream d;
    for (const auto& r : rows) d << r << "\n";
    common::writeFileAtomically(path, d.str());
    return true;
}

/// trajectory_<traverse>_<method>.png of one run.
bool plotTrajectory(const RunTrace& tr, const std::string& walls_dat, const std::string& colour,
                    const std::string& out_dir, std::string& warning) {
    const std::string stem =
        out_dir + "/trajectory_" + fileStem(tr.traverse) + "_" + fileStem(tr.method);
    std::vector<std::string> truth, refined, fallback, lost;
    std::vector<double> errors;
    for (const FrameTrace& f : tr.frames) {
        truth.push_back(num(f.truth_x) + " " + num(f.truth_y));
        if (!f.has_pose) {
            lost.push_back(num(f.truth_x) + " " + num(f.truth_y));
            continue;
        }
        const std::string row = num(f.x) + " " + num(f.y) + " " + num(f.error_m);
        (f.status == "refined" ? refined : fallback).push_back(row);
        errors.push_back(f.error_m);
    }
    if (truth.empty()) return true;
    std::sort(errors.begin(), errors.end());
    const double top = errors.empty() ? 1.0 : std::max(0.1, errors[errors.size() * 95 / 100]);
    std::vector<std::string> plots;
    if (!walls_dat.empty())
        plots.push_back("'" + walls_dat + "' w p pt 5 ps 0.2 lc rgb '#b0b0b0' t 'map walls'");
    writeDat(stem + "_truth.dat", truth);
    plots.push_back("'" + stem + "_truth.dat' w l lw 1.5 lc rgb 'black' t 'ground truth'");
    if (writeDat(stem + "_refined.dat", refined)) {
        plots.push_back("'" + stem + "_refined.dat' u 1:2:3 w p pt 7 ps 0.6 lc palette t '" +
                        tr.method + " refined (colour: error)'");
    }
    if (writeDat(stem + "_fallback.dat", fallback)) {
        plots.push_back("'" + stem + "_fallback.dat' u 1:2:3 w p pt 6 ps 1.0 lc palette t '" +
                        tr.method + " fallback (odometry)'");
    }
    if (writeDat(stem + "_lost.dat", lost)) {
        plots.push_back("'" + stem + "_lost.dat' w p pt 2 ps 1.0 lc rgb '" + colour +
                        "' t 'lost / no pose (at the true position)'");
    }
    std::ostringstream g;
    g << "set terminal pngcairo size 1100,700 noenhanced\n"
      << "set output '" << stem << ".png'\n"
      << "set size ratio -1\nset grid\nset key outside below\n"
      << "set xlabel 'x (m)'\nset ylabel 'y (m)'\n"
      << "set title '" << tr.traverse << ": " << tr.method << " over the map'\n"
      << "set palette defined (0 '#1a9850', 0.5 '#fee08b', 1 '#d73027')\n"
      << "set cbrange [0:" << num(top) << "]\nset cblabel 'position error (m)'\n"
      << "plot ";
    for (std::size_t i = 0; i < plots.size(); ++i) g << (i ? ", \\\n     " : "") << plots[i];
    g << "\n";
    common::writeFileAtomically(stem + ".gp", g.str());
    return runGnuplot(stem + ".gp", out_dir, warning);
}

/// error_along_<traverse>.png: every run of the traverse and its coarse stage.
bool plotErrorAlong(const Report& r, const std::string& traverse,
                    const std::vector<std::string>& methods, const std::string& out_dir,
                    std::string& warning) {
    const std::string stem = out_dir + "/error_along_" + fileStem(traverse);
    std::vector<std::string> plots;
    bool coarse_done = false;
    for (std::size_t k = 0; k < r.traces.size(); ++k) {
        const RunTrace& tr = r.traces[k];
        if (tr.traverse != traverse) continue;
        std::vector<std::string> rows, coarse;
        for (const FrameTrace& f : tr.frames) {
            if (f.has_pose)
                rows.push_back(num(f.distance_m) + " " + num(std::max(f.error_m, 1e-3)));
            if (f.coarse_error_m >= 0) {
                coarse.push_back(num(f.distance_m) + " " + num(std::max(f.coarse_error_m, 1e-3)));
            }
        }
        const std::string dat = stem + "_" + std::to_string(k) + ".dat";
        if (writeDat(dat, rows)) {
            plots.push_back("'" + dat + "' w lp pt 7 ps 0.4 lc rgb '" +
                            methodColour(tr.method, methods) + "' t '" + tr.method + "'");
        }
        if (!coarse_done && writeDat(stem + "_coarse.dat", coarse)) {
            coarse_done = true;
            plots.push_back("'" + stem + "_coarse.dat' w p pt 1 ps 0.5 lc rgb '" +
                            methodColour("coarse", methods) + "' t 'coarse'");
        }
    }
    if (plots.empty()) return true;
    std::ostringstream g;
    g << "set terminal pngcairo size 1100,500 noenhanced\n"
      << "set output '" << stem << ".png'\n"
      << "set logscale y\nset grid\nset key outside right top\n"
      << "set xlabel 'distance driven (m)'\nset ylabel 'position error (m)'\n"
      << "set title '" << traverse << ": error along the route'\nplot ";
    for (std::size_t i = 0; i < plots.size(); ++i) g << (i ? ", \\\n     " : "") << plots[i];
    g << "\n";
    common::writeFileAtomically(stem + ".gp", g.str());
    return runGnuplot(stem + ".gp", out_dir, warning);
}

}  // namespace

bool plotRunPictures(const Report& r, const std::string& out_dir, std::string& warning) {
    std::vector<std::string> methods, traverses;
    for (const auto& m : r.rows) {
        if (std::find(methods.begin(), methods.end(), m.method) == methods.end())
            methods.push_back(m.method);
    }
    std::string walls_dat;
    if (!r.map_walls.empty()) {
        std::vector<std::string> rows;
        for (const auto& w : r.map_walls) rows.push_back(num(w[0]) + " " + num(w[1]));
        walls_dat = out_dir + "/map_walls.dat";
        writeDat(walls_dat, rows);
    }
    bool ok = true;
    for (const RunTrace& tr : r.traces) {
        ok &= plotTrajectory(tr, walls_dat, methodColour(tr.method, methods), out_dir, warning);
        if (std::find(traverses.begin(), traverses.end(), tr.traverse) == traverses.end())
            traverses.push_back(tr.traverse);
    }
    for (const auto& t : traverses) ok &= plotErrorAlong(r, t, methods, out_dir, warning);
    return ok;
}

}  // namespace detail
}  // namespace lookup::eval

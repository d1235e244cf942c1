#include "lookup/fcn/heat_maps.h"

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <stdexcept>

#include "lookup/common/errors.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/heat_maps.h"
#include "lookup/database/manifest.h"
#include "lookup/database/reference.h"

namespace fs = std::filesystem;

namespace lookup::fcn {
namespace {

std::string trim(const std::string& s) {
    const auto b = s.find_first_not_of(" \t\r");
    const auto e = s.find_last_not_of(" \t\r");
    return b == std::string::npos ? std::string() : s.substr(b, e - b + 1);
}

// A folder name not yet used in the database: heatmaps_001, heatmaps_002, ...
std::string freshDirectoryName(const fs::path& db_dir) {
    for (int i = 1;; ++i) {
        char name[32];
        std::snprintf(name, sizeof name, "heatmaps_%03d", i);
        if (!fs::exists(db_dir / name) && !fs::exists(db_dir / (std::string(name) + ".tmp"))) {
            return name;
        }
    }
}

}  // namespace

void setHeatMapsDirectory(const std::string& db_ini_path, const std::string& directory) {
    std::ifstream in(db_ini_path);
    if (!in) throw std::runtime_error(db_ini_path + ": cannot read");
    std::vector<std::string> lines;
    for (std::string line; std::getline(in, line);) lines.push_back(line);
    in.close();

    bool in_section = false, found_section = false, written = false;
    std::vector<std::string> out;
    for (const auto& line : lines) {
        const std::string t = trim(line);
        if (!t.empty() && t.front() == '[') {
            if (in_section && !written) {
                out.push_back("directory = " + directory);
                written = true;
            }
            in_section = t == "[heatmaps]";
            found_section |= in_section;
        } else if (in_section && t.rfind("directory", 0) == 0 &&
                   trim(t.substr(9)).rfind('=', 0) == 0) {
            if (!written) out.push_back("directory = " + directory);
            written = true;
            continue;
        }
        out.push_back(line);
    }
    if (!found_section) {
        out.push_back("");
        out.push_back("[heatmaps]");
    }
    if (!written) out.push_back("directory = " + directory);

    const std::string tmp = db_ini_path + ".tmp";
    std::error_code ec;
    try {
        common::OutputFile o(tmp);
        for (const auto& l : out) o.write(l + "\n");
        o.close();
    } catch (const common::WriteError&) {
        fs::remove(tmp, ec);
        throw;
    }
    try {
        database::readDatabaseInfo(tmp);  // the rewritten file must still parse
    } catch (const std::exception& e) {
        fs::remove(tmp, ec);
        throw std::runtime_error(db_ini_path + ": rewritten file does not parse: " + e.what());
    }
    fs::rename(tmp, db_ini_path, ec);
    if (ec) {
        fs::remove(tmp, ec);
        throw common::WriteError(db_ini_path, "cannot replace: " + ec.message());
    }
}

HeatMapsWritten writeHeatMaps(const database::ReferenceDatabase& db, const HeatMapModel& model,
                              const ProgressFn& progress) {
    const auto t0 = std::chrono::steady_clock::now();
    const fs::path db_dir = db.directory();
    HeatMapsWritten result;
    result.directory = freshDirectoryName(db_dir);
    const fs::path staging = db_dir / (result.directory + ".tmp");
    const fs::path final_dir = db_dir / result.directory;
    try {
        fs::create_directories(staging);
        for (std::size_t i = 0; i < db.size(); ++i) {
            // At the network's resolution: a quarter of the pixels to decode in the localiser,
            // which resizes on load exactly as predict() does.
            const cv::Mat heat = model.predictAtNetworkScale(db.ceilingImage(i));
            const fs::path file = staging / database::heatMapFileName(i);
            if (!cv::imwrite(file.string(), database::encodeHeatMap(heat))) {
                throw common::WriteError(file.string(), "cannot write the heat map");
            }
            if (progress) progress(i + 1, db.size());
        }
        // The folder's own checksums: the survey's manifest stays as it is.
        database::writeManifest(staging.string());
        for (const auto& e : fs::directory_iterator(staging)) common::syncFile(e.path().string());
        common::syncDirectory(staging.string());
        fs::rename(staging, final_dir);
        common::syncDirectory(db_dir.string());
    } catch (const common::WriteError&) {
        std::error_code ec;
        fs::remove_all(staging, ec);
        throw;
    } catch (const std::exception& e) {
        std::error_code ec;
        fs::remove_all(staging, ec);
        throw std::runtime_error(db_dir.string() + ": heat maps not written: " + e.what());
    }
    const std::string db_ini = (db_dir / database::kDbIni).string();
    try {
        setHeatMapsDirectory(db_ini, result.directory);
    } catch (const std::exception& e) {
        std::error_code ec;
        fs::remove_all(final_dir, ec);
        throw std::runtime_error(std::string("heat maps not listed: ") + e.what());
    }
    // The previous maps are no longer referenced.
    const std::string previous = db.info().heatmaps_dir;
    if (!previous.empty() && previous != result.directory && previous.rfind("heatmaps_", 0) == 0) {
        std::error_code ec;
        fs::remove_all(db_dir / previous, ec);
    }
    result.count = db.size();
    result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return result;
}

}  // namespace lookup::fcn

namespace lookup::fcn {

cv::Mat heatMapFigure(const cv::Mat& image, const cv::Mat& heat,
                      const std::vector<cv::Point2f>& points) {
    CV_Assert(image.type() == CV_8UC1 && heat.type() == CV_32FC1 && image.size() == heat.size());
    cv::Mat left, heat8, right;
    cv::cvtColor(image, left, cv::COLOR_GRAY2BGR);
    double lo = 0, hi = 1;
    cv::minMaxLoc(heat, &lo, &hi);
    heat.convertTo(heat8, CV_8U, hi > lo ? 255.0 / (hi - lo) : 0.0,
                   hi > lo ? -255.0 * lo / (hi - lo) : 0.0);
    cv::applyColorMap(heat8, right, cv::COLORMAP_JET);
    for (cv::Mat* m : {&left, &right}) {
        for (const auto& p : points) {
            cv::circle(*m, p, 4, cv::Scalar(255, 255, 255), 2);
            cv::circle(*m, p, 4, cv::Scalar(0, 160, 0), 1);
        }
    }
    cv::Mat out;
    cv::hconcat(
        std::vector<cv::Mat>{left, cv::Mat(image.rows, 6, CV_8UC3, cv::Scalar::all(255)), right},
        out);
    return out;
}

}  // namespace lookup::fcn

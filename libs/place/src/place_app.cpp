#include "lookup/place/place_app.h"

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/obs/CObservationImage.h>
#include <mrpt/system/CTicTac.h>
#include <mrpt/system/os.h>

#include <malloc.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <numeric>

#include "lookup/common/cli.h"
#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/grey.h"
#include "lookup/common/options_table.h"
#include "lookup/common/pose_files.h"
#include "lookup/common/rawlog_io.h"
#include "lookup/database/reference_database.h"
#include "lookup/place/place_pose.h"
#include "lookup/refine/rectifier.h"

namespace lookup::place {

std::string buildPlaceIndex(const std::string& db_dir, const PlaceIndexOptions& options,
                            bool show_progress) {
    mrpt::system::CTicTac timer;
    const auto db = database::ReferenceDatabase::load(db_dir, 8);
    const auto progress = [&](std::size_t done, std::size_t total) {
        if (show_progress && (done == total || done % 50 == 0)) {
            std::fprintf(stderr, "\rplace index: %zu / %zu references", done, total);
            if (done == total) std::fprintf(stderr, "\n");
        }
    };
    const PlaceIndex index = PlaceIndex::build(db, options, progress);
    const std::string path = db_dir + "/" + kPlaceIndexFile;
    index.save(path);
    char line[256];
    std::snprintf(line, sizeof line,
                  "%s: %zu of %zu references, %zu %s features, %.1f MB in memory, %.1f s",
                  path.c_str(), index.indexedReferences(), db.size(), index.featureCount(),
                  toString(options.features), index.memoryBytes() / 1e6, timer.Tac());
    return line;
}

bool PlaceApp::initialize(int argc, const char* const* argv) {
    TCLAP::CmdLine cmd(std::string("lookup-place: builds or evaluates the ceiling place index of "
                                   "a LookUP database. ") +
                           common::kExitCodesHelp,
                       ' ', "0.1");
    TCLAP::ValueArg<std::string> db("d", "db", "database folder", true, "", "DB", cmd);
    TCLAP::ValueArg<std::string> ini("i", "ini", ".ini with a [place_index] section", false, "",
                                     "FILE", cmd);
    TCLAP::ValueArg<std::string> query("e", "evaluate",
                                       "query rawlog: score the index on its ceiling frames "
                                       "instead of building it",
                                       false, "", "Q.rawlog", cmd);
    TCLAP::ValueArg<std::string> gt("g", "gt", "ground truth of the query (with --evaluate)", false,
                                    "", "Q.GT.txt", cmd);
    TCLAP::ValueArg<int> every("n", "every", "evaluate every N-th ceiling frame", false, 1, "N",
                               cmd);
    TCLAP::ValueArg<std::string> json("j", "json", "write the evaluation as JSON", false, "",
                                      "FILE", cmd);
    TCLAP::SwitchArg quiet("q", "quiet", "no progress", cmd, false);
    common::OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    std::vector<const char*> args(argv, argv + argc);
    if (!cmd.parse(argc, args.data())) {
        exit_code_ = common::parseFailureExitCode(argc, argv, common::kExitUsage);
        return false;
    }
    try {
        db_dir_ = db.getValue();
        ini_file_ = ini.getValue();
        query_rawlog_ = query.getValue();
        gt_file_ = gt.getValue();
        json_file_ = json.getValue();
        every_ = std::max(1, every.getValue());
        quiet_ = quiet.getValue();
        if (!query_rawlog_.empty() && gt_file_.empty()) {
            throw common::ConfigError("--evaluate needs --gt");
        }
        if (!ini_file_.empty()) {
            const auto file = common::loadIniFile(ini_file_);
            common::rejectUnknownSections(*file, {"place_index"});
            common::loadAndCheck(options_, *file, "place_index");
        }
    } catch (const std::exception& e) {
        std::cerr << "lookup-place: " << common::errorText(e, false) << "\n";
        exit_code_ = common::exitCodeFor(e);
        return false;
    }
    return true;
}

int PlaceApp::run() {
    exit_code_ = query_rawlog_.empty() ? build() : evaluate();
    return exit_code_;
}

int PlaceApp::build() {
    std::cout << buildPlaceIndex(db_dir_, options_, !quiet_) << std::endl;
    return common::kExitOk;
}

namespace {

double percentile(std::vector<double> v, double p) {
    if (v.empty()) return 0;
    std::sort(v.begin(), v.end());
    return v[std::min(v.size() - 1, static_cast<std::size_t>(p * double(v.size())))];
}

// How well the index finds the truth, over the evaluated frames.
struct PlaceScore {
    // Right: within the SAD window of the truth; wrong: another place.
    static constexpr double kRightM = 1.0, kWrongM = 2.0;

    int frames = 0, scored = 0, top1_right = 0, top1_wrong = 0, any_right = 0, none = 0;
    std::vector<double> ms, top1_error;
    double features_ms = 0, search_ms = 0, geometry_ms = 0;

    void addQuery(double query_ms, const PlaceQueryTimes& t) {
        ms.push_back(query_ms);
        features_ms += t.features_ms;
        search_ms += t.search_ms;
        geometry_ms += t.geometry_ms;
    }

    // A frame with ground truth: its candidates' vehicle poses, best first.
    void addScored(const std::vector<mrpt::poses::CPose2D>& poses, const mrpt::poses::CPose3D& gt) {
        ++scored;
        if (poses.empty()) {
            ++none;
            return;
        }
        const auto err = [&](const mrpt::poses::CPose2D& p) {
            return std::hypot(p.x() - gt.x(), p.y() - gt.y());
        };
        top1_error.push_back(err(poses.front()));
        if (err(poses.front()) < kRightM) ++top1_right;
        if (err(poses.front()) > kWrongM) ++top1_wrong;
        if (std::any_of(poses.begin(), poses.end(), [&](auto& p) { return err(p) < kRightM; })) {
            ++any_right;
        }
    }

    double share(int n) const { return scored ? 100.0 * n / scored : 0.0; }
    double meanMs() const {
        return ms.empty() ? 0.0 : std::accumulate(ms.begin(), ms.end(), 0.0) / double(ms.size());
    }
};

// The ceiling image rectified to the database's camera, in grey.
cv::Mat ceilingGrey(const mrpt::obs::CObservationImage& img, const refine::Rectifier& rectifier) {
    if (img.image.isExternallyStored()) img.image.forceLoad();
    return common::greyOf(
        rectifier.rectify(img.image.asCvMat<cv::Mat>(mrpt::img::SHALLOW_COPY), img.cameraParams));
}

// The vehicle poses the index's candidates for one frame imply, best first.
std::vector<mrpt::poses::CPose2D> candidatePoses(const PlaceIndex& index,
                                                 const database::ReferenceDatabase& db,
                                                 const QueryCamera& camera, const cv::Mat& grey,
                                                 PlaceQueryTimes* t) {
    std::vector<mrpt::poses::CPose2D> poses;
    for (const auto& p : placeQuery(index, db, camera, grey, t)) poses.push_back(p.vehicle_pose);
    return poses;
}

std::string summaryLine(const PlaceScore& s, const std::string& rawlog, const PlaceIndex& index) {
    char line[512];
    std::snprintf(line, sizeof line,
                  "%s: %d frames, %d scored: top-1 within 1 m %.1f %%, beyond 2 m %.1f %%, any "
                  "candidate within 1 m %.1f %%, no candidate %.1f %%; top-1 error median %.3f m; "
                  "query %.1f ms mean, %.1f ms "
                  "p99; index %.1f MB, %zu features",
                  rawlog.c_str(), s.frames, s.scored, s.share(s.top1_right), s.share(s.top1_wrong),
                  s.share(s.any_right), s.share(s.none), percentile(s.top1_error, 0.5), s.meanMs(),
                  percentile(s.ms, 0.99), index.memoryBytes() / 1e6, index.featureCount());
    return line;
}

nlohmann::ordered_json scoreJson(const PlaceScore& s, double heap_mb) {
    return {{"frames", s.frames},
            {"scored", s.scored},
            {"top1_right_pct", s.share(s.top1_right)},
            {"top1_wrong_pct", s.share(s.top1_wrong)},
            {"any_right_pct", s.share(s.any_right)},
            {"none_pct", s.share(s.none)},
            {"query_ms_mean", s.meanMs()},
            {"query_ms_p99", percentile(s.ms, 0.99)},
            {"heap_mb", heap_mb}};
}

}  // namespace

int PlaceApp::evaluate() {
    const auto db = database::ReferenceDatabase::load(db_dir_, 8);
    // Heap bytes the loaded index holds, the blocks malloc maps on their own included (the
    // descriptor tables of a large index are such blocks).
    const auto heap = [] {
        const auto m = mallinfo2();
        return m.uordblks + m.hblkhd;
    };
    const std::size_t heap_before = heap();
    const PlaceIndex index = PlaceIndex::load(db_dir_ + "/" + kPlaceIndexFile, db, options_);
    const double heap_mb = double(heap() - heap_before) / 1e6;
    const auto truth = common::makeInterpolator(common::readPoseFile(gt_file_), 1.0);
    common::RawlogReader reader(query_rawlog_);
    const refine::Rectifier rectifier(db.info().ceiling_camera);
    PlaceScore score;
    mrpt::obs::CObservation::Ptr obs;
    std::size_t ceiling_seen = 0;
    while (reader.next(obs)) {
        const auto* img = dynamic_cast<const mrpt::obs::CObservationImage*>(obs.get());
        if (!img || img->sensorLabel != db.info().ceiling_camera_label) continue;
        if (ceiling_seen++ % static_cast<std::size_t>(every_) != 0) continue;
        ++score.frames;
        const cv::Mat grey = ceilingGrey(*img, rectifier);
        PlaceQueryTimes t;
        mrpt::system::CTicTac timer;
        const QueryCamera camera{rectifier.target(), img->cameraPose};
        const auto poses = candidatePoses(index, db, camera, grey, &t);
        score.addQuery(1e3 * timer.Tac(), t);
        mrpt::poses::CPose3D gt;
        bool valid = false;
        truth.interpolate(img->timestamp, gt, valid);
        if (valid) score.addScored(poses, gt);
    }
    std::cout << summaryLine(score, query_rawlog_, index) << std::endl;
    if (score.frames > 0) {
        std::printf(
            "per query: features %.2f ms, search %.2f ms, geometry %.2f ms; index heap "
            "%.1f MB\n",
            score.features_ms / score.frames, score.search_ms / score.frames,
            score.geometry_ms / score.frames, heap_mb);
    }
    if (!json_file_.empty()) {
        common::writeFileAtomically(json_file_, scoreJson(score, heap_mb).dump() + "\n");
    }
    return common::kExitOk;
}

}  // namespace lookup::place

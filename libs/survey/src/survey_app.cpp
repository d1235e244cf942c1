#include "lookup/survey/survey_app.h"

#include <mrpt/3rdparty/tclap/CmdLine.h>
#include <mrpt/config/CConfigFile.h>

#include <filesystem>
#include <fstream>
#include <iostream>
#include <sstream>

#include "lookup/common/cli.h"
#include "lookup/common/config.h"
#include "lookup/common/errors.h"
#include "lookup/common/options_table.h"
#include "lookup/common/share_dirs.h"
#include "lookup/place/place_app.h"

namespace lookup::survey {
namespace fs = std::filesystem;
namespace {

std::vector<std::string> splitList(const std::string& s) {
    std::vector<std::string> out;
    std::stringstream in(s);
    std::string item;
    while (std::getline(in, item, ',')) {
        const auto b = item.find_first_not_of(" \t");
        const auto e = item.find_last_not_of(" \t");
        if (b != std::string::npos) out.push_back(item.substr(b, e - b + 1));
    }
    return out;
}

std::string resolve(const fs::path& base, const std::string& p) {
    if (p.empty()) return p;
    return fs::path(p).is_absolute() ? p : (base / p).lexically_normal().string();
}

// Reads a lookup-sim dataset.ini (docs/dataset-format.md) into `inputs` and the labels of
// `options`.
void readDataset(const std::string& path, SurveyInputs& inputs, SurveyOptions& options) {
    if (!fs::is_regular_file(path)) throw common::ConfigError(path + ": no such dataset file");
    const auto file = common::loadIniFile(path);
    const auto& cfg = *file;
    const fs::path base = fs::absolute(path).parent_path();
    common::IniSection ds(cfg, "dataset", path);
    if (!ds.exists()) throw common::ConfigError(path + ": no [dataset] section");
    inputs.name = ds.getString("name", "");
    // Old lookup-sim output states the simulator's own ceiling height: the survey measures it
    // instead and uses this only when asked (use_dataset_ceiling_height).
    inputs.ceiling_height_m = ds.getDouble("ceiling_height_m", 0);
    options.ceiling_camera_label =
        ds.getString("ceiling_camera_label", options.ceiling_camera_label);
    options.forward_camera_label =
        ds.getString("forward_camera_label", options.forward_camera_label);
    options.lidar_label = ds.getString("lidar_label", options.lidar_label);
    options.odometry_label = ds.getString("odometry_label", options.odometry_label);
    options.imu_label = ds.getString("imu_label", options.imu_label);
    const int count = ds.requireInt("traverse_count");
    for (int i = 0; i < count; ++i) {
        common::IniSection t(cfg, "traverse_" + std::to_string(i), path);
        if (!t.exists()) {
            throw common::ConfigError(path + ": missing section [traverse_" + std::to_string(i) +
                                      "]");
        }
        TraverseSpec spec;
        spec.name = t.getString("name", "traverse_" + std::to_string(i));
        spec.rawlog = resolve(base, t.requireString("rawlog"));
        spec.ground_truth = resolve(base, t.getString("ground_truth", ""));
        const auto roles = splitList(t.getString("roles", "mapping,reference"));
        spec.mapping = std::find(roles.begin(), roles.end(), "mapping") != roles.end();
        spec.reference = std::find(roles.begin(), roles.end(), "reference") != roles.end();
        for (const auto& r : roles) {
            if (r != "mapping" && r != "reference" && r != "query" && r != "refresh") {
                throw common::ConfigError(t.where("roles") + "unknown role '" + r + "'");
            }
        }
        // The operator's start and end poses of the mapping traverse (the first one that has
        // them).
        const auto mark = [&](const char* key, std::string& into) {
            const std::string text = t.getString(key, "");
            if (text.empty()) return;
            if (!parseStartPose(text)) {
                throw common::ConfigError(t.where(key) + "expected three numbers: x y yaw_deg");
            }
            if (spec.mapping && into.empty()) into = text;
        };
        mark("start_pose", inputs.start_pose);
        mark("end_pose", inputs.end_pose);
        const std::string marks = t.getString("marks", "");
        if (!parseMarks(marks)) {
            throw common::ConfigError(t.where("marks") +
                                      "expected \"t x y yaw_deg\" groups separated by ';'");
        }
        if (spec.mapping && inputs.marks.empty()) inputs.marks = marks;
        if (spec.mapping || spec.reference) inputs.traverses.push_back(spec);
    }
}

}  // namespace

std::string defaultSurveyIni() {
    const std::string p = common::findShareFile("survey.ini");
    return fs::is_regular_file(p) ? p : "";
}

bool SurveyApp::initialize(int argc, const char* const* argv) {
    TCLAP::CmdLine cmd(std::string("lookup-survey: builds a LookUP reference database from survey "
                                   "rawlogs. ") +
                           common::kExitCodesHelp,
                       ' ', "0.1");
    lookup::common::OneLineOutput one_line_errors;
    cmd.setOutput(&one_line_errors);
    TCLAP::ValueArg<std::string> dataset("d", "dataset", "lookup-sim dataset.ini", false, "",
                                         "DATASET.ini", cmd);
    TCLAP::ValueArg<std::string> rawlogs("r", "rawlogs", "comma-separated survey rawlogs", false,
                                         "", "A.rawlog[,B.rawlog...]", cmd);
    TCLAP::ValueArg<std::string> ini("i", "ini",
                                     "survey .ini ([survey] and the MRPT ICP-SLAM / MCL sections)",
                                     false, "", "survey.ini", cmd);
    TCLAP::ValueArg<std::string> out("o", "out", "database folder to create", true, "", "DB", cmd);
    TCLAP::ValueArg<std::string> poses("p", "poses",
                                       "surveyed vehicle poses (MRPT .GT.txt or TUM) replacing "
                                       "the laser stage; 'ground-truth' = each traverse's own "
                                       "ground-truth file",
                                       false, "", "FILE", cmd);
    TCLAP::ValueArg<std::string> map("m", "map", "existing grid map replacing ICP-SLAM", false, "",
                                     "FILE.gridmap[.gz]", cmd);
    TCLAP::ValueArg<std::string> refresh(
        "", "refresh",
        "refresh this database from an operating drive (--rawlogs DRIVE, --run RUN): where the "
        "drive refined nothing between two fixes the ceiling has changed; its images there are "
        "added, posed by the fixes and the odometry, the survey's references there superseded; "
        "written to --out, DB left as it was",
        false, "", "DB", cmd);
    TCLAP::ValueArg<std::string> run_dir("", "run",
                                         "with --refresh: lookup-localize's run folder of the "
                                         "drive against DB",
                                         false, "", "RUN", cmd);
    TCLAP::SwitchArg no_index("", "no-place-index",
                              "do not build the ceiling place index (lookup-place builds it later)",
                              cmd, false);
    TCLAP::SwitchArg quiet("q", "quiet", "no progress bar", cmd, false);
    TCLAP::SwitchArg verbose("v", "verbose", "full error texts (MRPT call stacks)", cmd, false);
    std::vector<const char*> args(argv, argv + argc);
    if (!cmd.parse(argc, args.data())) {
        // TCLAP printed the help, the version or the error.
        exit_code_ = common::parseFailureExitCode(argc, argv, common::kExitUsage);
        return false;
    }
    try {
        if (dataset.isSet() == rawlogs.isSet()) {
            throw common::ConfigError("give exactly one of --dataset and --rawlogs");
        }
        if (refresh.isSet() != run_dir.isSet()) {
            throw common::ConfigError("--refresh and --run go together");
        }
        if (refresh.isSet() && (dataset.isSet() || splitList(rawlogs.getValue()).size() != 1 ||
                                poses.isSet() || map.isSet())) {
            throw common::ConfigError(
                "--refresh takes one drive (--rawlogs DRIVE.rawlog) and "
                "neither --dataset, --poses nor --map");
        }
        const std::string ini_path = ini.isSet() ? ini.getValue() : defaultSurveyIni();
        if (!ini_path.empty()) {
            const auto file = common::loadIniFile(ini_path);
            config_.setContent(file->getContent());
            config_.setFileName(ini_path);
            // The sections the Survey itself reads: [pose_graph] and MRPT's ICP-SLAM / MCL.
            common::rejectUnknownSections(
                config_, {"survey", "place_index", "pose_graph", "ICP", "PF_options", "KLD_options",
                          "LikelihoodOptions", "MappingApplication", "MappingApplication_*"});
            common::loadAndCheck(options_, config_, "survey");
            common::loadAndCheck(place_options_, config_, "place_index");
        }
        if (dataset.isSet()) {
            readDataset(dataset.getValue(), inputs_, options_);
        } else {
            for (const auto& r : splitList(rawlogs.getValue())) {
                TraverseSpec spec;
                spec.name = fs::path(r).stem().string();
                spec.rawlog = r;
                if (fs::is_regular_file(r + ".GT.txt")) spec.ground_truth = r + ".GT.txt";
                inputs_.traverses.push_back(spec);
            }
        }
        options_.check();
        inputs_.out_dir = out.getValue();
        inputs_.poses_file = poses.getValue();
        inputs_.map_file = map.getValue();
        inputs_.show_progress = !quiet.getValue();
        verbose_ = verbose.getValue();
        build_place_index_ = !no_index.getValue();
        if (refresh.isSet()) {
            refresh_ = RefreshInputs{refresh.getValue(), rawlogs.getValue(), run_dir.getValue(),
                                     out.getValue(), ""};
        }
    } catch (const std::exception& e) {
        std::cerr << "lookup-survey: " << common::errorText(e, verbose.getValue()) << "\n";
        exit_code_ = common::exitCodeFor(e);
        return false;
    }
    return true;
}

int SurveyApp::run() {
    if (refresh_) return runRefresh();
    try {
        const Survey survey(options_, config_);
        result_ = survey.run(inputs_);
    } catch (const std::exception& e) {
        // Options the Survey itself reads ([pose_graph], the MRPT sections).
        result_ = SurveyResult();
        result_.reason = common::errorLine(e);
        result_.detail = e.what();
        result_.exit_code = common::exitCodeFor(e);
    }
    for (const auto& w : result_.warnings) std::cerr << "lookup-survey: warning: " << w << "\n";
    if (result_.ok()) {
        std::cout << result_.summaryLine() << std::endl;
        if (!std::cout) {
            std::cerr << "lookup-survey: stdout: write error" << std::endl;
            return exit_code_ = common::kExitWriteError;
        }
        exit_code_ = common::kExitOk;
        buildIndex();
    } else {
        std::cerr << (verbose_ && !result_.detail.empty()
                          ? "lookup-survey: FAILED: " + result_.detail
                          : result_.summaryLine())
                  << std::endl;
        exit_code_ = result_.exit_code != 0 ? result_.exit_code : common::kExitBadInput;
    }
    return exit_code_;
}

int SurveyApp::runRefresh() {
    try {
        refresh_result_ = refreshDatabase(*refresh_, options_);
    } catch (const std::exception& e) {
        std::cerr << "lookup-survey: refresh FAILED: " << common::errorText(e, verbose_) << "\n";
        return exit_code_ = common::exitCodeFor(e);
    }
    for (const auto& w : refresh_result_.warnings) {
        std::cerr << "lookup-survey: warning: " << w << "\n";
    }
    std::cout << refresh_result_.summaryLine() << std::endl;
    exit_code_ = common::checkedStdout("lookup-survey", common::kExitOk);
    if (exit_code_ == common::kExitOk) buildIndex();
    return exit_code_;
}

void SurveyApp::buildIndex() {
    if (!build_place_index_) return;
    // The database is complete and in place: a failure here leaves it usable, without the
    // index (lookup-localize then starts from the forward camera, saying so).
    try {
        std::cout << place::buildPlaceIndex(inputs_.out_dir, place_options_, inputs_.show_progress)
                  << std::endl;
    } catch (const std::exception& e) {
        std::cerr << "lookup-survey: warning: the database is complete but its place index is "
                     "not: "
                  << common::errorLine(e) << " (retry: lookup-place --db " << inputs_.out_dir << ")"
                  << std::endl;
        if (common::exitCodeFor(e) == common::kExitWriteError) exit_code_ = common::kExitWriteError;
    }
}

}  // namespace lookup::survey

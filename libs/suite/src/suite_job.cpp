#include <mrpt/config/CConfigFile.h>

#include <chrono>
#include <filesystem>
#include <iostream>
#include <stdexcept>

#include "lookup/eval/evaluator.h"
#include "lookup/localize/localize_app.h"
#include "lookup/sim/simulator.h"
#include "lookup/suite/suite.h"
#include "lookup/survey/survey_app.h"
#include "suite_internal.h"

namespace lookup::suite {
namespace fs = std::filesystem;

namespace {

struct QueryTraverse {
    std::string name, rawlog, ground_truth;
    bool refresh = false;  ///< the database is refreshed from this drive for the later ones
};

void generate(const SuiteOptions& suite, const Condition& c, std::uint64_t seed,
              const std::string& data_dir) {
    sim::Simulator simulator(scenarioFor(c, seed, suite.source, suite.threads_per_job));
    for (const auto& w : simulator.warnings()) std::cerr << "lookup-sim: warning: " << w << "\n";
    const auto result = simulator.run(data_dir);
    if (result.status != sim::SimulationResult::Status::Ok) throw std::runtime_error(result.reason);
}

/// Laser-derived references, as a mine gets them: the ground truth is not handed over.
void survey(const std::string& dataset_ini, const std::string& db_dir,
            const std::string& survey_ini) {
    const char* argv[] = {"lookup-survey", "--dataset", dataset_ini.c_str(), "--out",
                          db_dir.c_str(),  "--ini",     survey_ini.c_str()};
    survey::SurveyApp app;
    if (!app.initialize(survey_ini.empty() ? 5 : 7, argv)) {
        throw std::runtime_error("lookup-survey refused its arguments (exit code " +
                                 std::to_string(app.exitCode()) + ")");
    }
    if (app.run() != 0) throw std::runtime_error(app.result().reason);
}

/// The database refreshed from a localised drive (lookup-survey --refresh), as a mine would
/// after a drive over a changed ceiling.
void refresh(const std::string& db_dir, const QueryTraverse& q, const std::string& run_dir,
             const std::string& out_dir, const std::string& survey_ini) {
    std::vector<const char*> argv = {"lookup-survey",  "--refresh", db_dir.c_str(),  "--rawlogs",
                                     q.rawlog.c_str(), "--run",     run_dir.c_str(), "--out",
                                     out_dir.c_str(),  "--quiet"};
    if (!survey_ini.empty()) argv.insert(argv.end(), {"--ini", survey_ini.c_str()});
    survey::SurveyApp app;
    if (!app.initialize(int(argv.size()), argv.data())) {
        throw std::runtime_error("lookup-survey --refresh refused its arguments (exit code " +
                                 std::to_string(app.exitCode()) + ")");
    }
    if (app.run() != 0) throw std::runtime_error("lookup-survey --refresh failed");
}

std::vector<QueryTraverse> queryTraverses(const std::string& dataset_ini) {
    mrpt::config::CConfigFile ini(dataset_ini);
    const fs::path dir = fs::path(dataset_ini).parent_path();
    std::vector<QueryTraverse> queries;
    std::vector<std::string> sections;
    ini.getAllSections(sections);
    for (const auto& section : sections) {
        if (section.rfind("traverse_", 0) != 0) continue;
        const std::string roles = ini.read_string(section, "roles", "", false);
        if (roles.find("query") == std::string::npos) continue;
        queries.push_back({ini.read_string(section, "name", section, false),
                           (dir / ini.read_string(section, "rawlog", "", true)).string(),
                           (dir / ini.read_string(section, "ground_truth", "", true)).string(),
                           roles.find("refresh") != std::string::npos});
    }
    if (queries.empty()) throw std::runtime_error(dataset_ini + ": no traverse with role query");
    return queries;
}

/// Localises one query traverse and scores it; appends the LookUP row and the coarse one.
void localiseAndScore(const SuiteOptions& suite, const Condition& c, const QueryTraverse& q,
                      const std::string& db_dir, const std::string& run_dir,
                      std::vector<eval::MethodResult>& rows) {
    localize::LocalizeRequest request;
    request.db_dir = db_dir;
    request.rawlog = q.rawlog;
    request.out_dir = run_dir;
    request.ini_file = c.localize_ini;
    request.sampling = "grid";
    request.max_frames = suite.max_frames;
    request.progress = false;
    localize::runLocalization(request);
    eval::MethodResult coarse;
    const eval::GroundTruth truth = eval::loadGroundTruth(q.ground_truth);
    rows.push_back(eval::scoreRun(eval::loadRun(run_dir), truth, eval::EvalOptions{}, &coarse));
    if (coarse.frames > 0) rows.push_back(coarse);
}

}  // namespace

JobResult runJob(const SuiteOptions& suite, const Condition& c, std::uint64_t seed,
                 const std::string& job_dir) {
    const auto t0 = std::chrono::steady_clock::now();
    JobResult r;
    r.condition = c.name;
    r.seed = seed;
    std::string step = "generate";
    try {
        const std::string data = job_dir + "/data", db = job_dir + "/db";
        generate(suite, c, seed, data);
        step = "survey";
        survey(data + "/dataset.ini", db, c.survey_ini);
        std::string db_now = db;
        for (const auto& q : queryTraverses(data + "/dataset.ini")) {
            step = "localise " + q.name;
            const std::string run = job_dir + "/runs/" + q.name;
            localiseAndScore(suite, c, q, db_now, run, r.rows);
            if (q.refresh) {
                step = "refresh from " + q.name;
                const std::string refreshed = job_dir + "/db-" + q.name;
                refresh(db_now, q, run, refreshed, c.survey_ini);
                db_now = refreshed;
            }
        }
        r.ok = true;
    } catch (const std::exception& e) {
        r.reason = step + ": " + e.what();
    }
    r.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return r;
}

}  // namespace lookup::suite

#pragma once
// The measuring stick: generate -> survey (laser-derived references) -> localise -> evaluate,
// over conditions x seeds, in one table (docs/suite.md). Every job runs in a child process, so
// a step that crashes or fails marks its row failed with the reason and the suite goes on.

#include <array>
#include <cstdint>
#include <iosfwd>
#include <string>
#include <vector>

#include "lookup/eval/evaluator.h"

namespace lookup::suite {

/// One row of the suite: a scenario preset with some of its keys overridden.
struct Condition {
    std::string name;           ///< from the section name [condition.NAME]
    std::string scenario_path;  ///< the preset's .ini file
    /// (section, key, value) written over the preset, from `SECTION.KEY = VALUE` lines.
    std::vector<std::array<std::string, 3>> overrides;
    std::string localize_ini;  ///< [localizer]/[refine.*]/[coarse] options; empty: defaults
    std::string survey_ini;    ///< lookup-survey --ini for this row; empty: share/lookup's
};

struct SuiteOptions {
    std::string name = "suite";
    std::string source;                ///< the suite file, for error messages
    std::vector<std::uint64_t> seeds;  ///< [suite] seeds, e.g. `6-10` or `1,3,5`
    std::size_t max_frames = 0;        ///< ceiling frames per query run (0: all)
    int threads_per_job = 1;           ///< render and survey threads of one job (not in the file)
    std::vector<Condition> conditions;

    /// Reads a suite file: [suite] name, seeds, localize_ini, max_frames; one
    /// [condition.NAME] section per row with `preset` (a name found in `scenario_dirs`, or a
    /// .ini path relative to the suite file), optional `localize_ini`, and SECTION.KEY
    /// overrides. Files named without a folder are looked up beside the suite file, then in
    /// `share_dirs`. Throws common::ConfigError naming the file, section and key.
    static SuiteOptions fromFile(const std::string& path,
                                 const std::vector<std::string>& share_dirs);
};

/// "1-5", "6,8,10", "1-3,7": ascending, without repeats. Throws std::invalid_argument.
std::vector<std::uint64_t> parseSeeds(const std::string& text);

/// One condition x seed.
struct JobResult {
    std::string condition;
    std::uint64_t seed = 0;
    bool ok = false;
    std::string reason;  ///< why the job failed (the step and its error)
    double wall_s = 0;
    /// Per query traverse, the LookUP row and (when the run has coarse poses) the coarse one.
    std::vector<eval::MethodResult> rows;
};

/// Runs one job in this process inside `job_dir` (data/, db/, runs/); failures are returned
/// as a failed JobResult naming the step, never thrown.
JobResult runJob(const SuiteOptions& suite, const Condition& condition, std::uint64_t seed,
                 const std::string& job_dir);

/// Every condition x seed, `parallel` jobs at a time, each in a forked child whose output goes
/// to OUT/jobs/CONDITION/seed-N/log.txt. suite.md and suite.json are rewritten (atomically)
/// after each finished job, so an interrupted suite keeps the rows it has. `log` gets one line
/// per finished job.
std::vector<JobResult> runSuite(const SuiteOptions& suite, const std::string& out_dir, int parallel,
                                std::ostream& log);

/// One line of the table: a condition over its seeds and query traverses.
struct ConditionSummary {
    std::string condition;
    std::size_t jobs = 0, failed = 0, runs = 0;  ///< runs: evaluated LookUP runs
    double refined_share = 0;                    ///< mean over runs
    double refined_after_first_fix_share = 0;    ///< mean over runs
    double first_fix_frame_median = -1;          ///< -1: some run never refined
    double first_fix_frame_max = -1;
    double first_fix_distance_m_max = -1;
    double mean_m = 0, median_m = 0, p95_m = 0;  ///< means over runs
    double max_m = 0;                            ///< over runs
    std::size_t confident_wrong = 0;             ///< summed over runs
    double inside_95_share = 0;                  ///< mean over runs
    double frames_per_s_min = 0;                 ///< slowest run
    double frame_ms_p99_max = 0;                 ///< worst run
    double coarse_mean_m = -1;                   ///< coarse stage alone, mean over runs
    std::vector<std::string> failures;           ///< "seed N: reason"
};

std::vector<ConditionSummary> summarizeConditions(const SuiteOptions& suite,
                                                  const std::vector<JobResult>& results);

/// suite.md (the table, then failures) and suite.json (summaries and every job's rows),
/// each written to a temporary beside it and renamed into place. Throws naming the file on a
/// write error.
void writeSuiteReport(const SuiteOptions& suite, const std::vector<JobResult>& results,
                      const std::string& out_dir);

}  // namespace lookup::suite

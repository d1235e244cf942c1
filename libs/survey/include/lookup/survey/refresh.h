#pragma once
// Refreshing a database from an operating drive (a changed ceiling: new shotcrete, mesh, pipes).
// Where the localiser refined no frame over a stretch bounded by refined fixes on both sides,
// the ceiling there no longer looks as surveyed. The drive's own images of that stretch become
// references, posed by the two fixes and the drive's odometry between them; the survey's
// references there are marked superseded (kept and shown, no longer used). The result is a new
// database folder; the one the drive was localised against stays as it was.

#include <string>
#include <vector>

#include "lookup/survey/survey_options.h"

namespace lookup::survey {

struct RefreshInputs {
    std::string db_dir;   ///< the database the drive was localised against
    std::string rawlog;   ///< the operating drive
    std::string run_dir;  ///< lookup-localize's run folder of that drive against db_dir
    std::string out_dir;  ///< the refreshed database (not db_dir)
    std::string name;     ///< traverse name of the added references ("" = the rawlog's stem)
};

/// One unrefined stretch between two refined fixes.
struct RefreshStretch {
    double from_s = 0, to_s = 0;  ///< times of the bounding fixes [s]
    double length_m = 0;          ///< odometry travel between them [m]
    double closure_m = 0;         ///< where the odometry from one fix met the other [m]
    std::size_t frames = 0;       ///< unrefined ceiling frames in it
    std::size_t added = 0;        ///< references added (the margins' included)
    std::size_t superseded = 0;   ///< survey references superseded
    std::string refused;          ///< why it was left alone ("" = refreshed)
};

struct RefreshResult {
    std::string db_dir, out_dir, rawlog, run_dir, name;
    std::size_t frames = 0;             ///< ceiling frames of the drive
    std::size_t refined = 0;            ///< ... refined by the run
    std::size_t references_before = 0;  ///< in db_dir
    std::size_t references_added = 0;   ///< from the drive
    std::size_t references_superseded = 0;
    std::vector<RefreshStretch> stretches;  ///< every stretch long enough to consider
    std::vector<std::string> warnings;

    std::string summaryLine() const;
    std::string toJson() const;  ///< refresh_report.json
};

inline constexpr const char* kRefreshReport = "refresh_report.json";

/// Writes the refreshed database to `in.out_dir` (atomically, as the survey does) with
/// refresh_report.json. Throws DatabaseError / RawlogError / eval::RunError / ConfigError naming
/// the file (and record or line) when an input is unusable: a run of another rawlog, a drive
/// without odometry, a run that did not finish.
RefreshResult refreshDatabase(const RefreshInputs& in, const SurveyOptions& options);

}  // namespace lookup::survey

#pragma once
// lookup-survey's command line over Survey (a thin main calls common::runApp).
//
//   lookup-survey --dataset DATASET/dataset.ini --out DB [--ini survey.ini] [--poses F] [--map F]
//   lookup-survey --rawlogs A.rawlog[,B.rawlog...] [--ini survey.ini] --out DB [--poses F]
//   lookup-survey --refresh DB --rawlogs DRIVE.rawlog --run RUN --out NEW_DB [--ini survey.ini]
//
// --refresh adds an operating drive's images where the ceiling changed (refresh.h).
//
// After the database, the ceiling place index (lookup::place) is built into it, unless
// --no-place-index.
//
// With --rawlogs every rawlog is a mapping and reference traverse (the first one builds the
// map) and `<rawlog>.GT.txt` is used for the report when it exists.

#include <optional>
#include <string>

#include "lookup/common/app.h"
#include "lookup/common/config.h"
#include "lookup/place/place_index.h"
#include "lookup/survey/refresh.h"
#include "lookup/survey/survey.h"

namespace lookup::survey {

class SurveyApp : public common::App {
  public:
    /// Parses the command line and the .ini files. Returns false (after printing help or the
    /// error to stderr) when the program should exit; `exitCode()` then tells how.
    bool initialize(int argc, const char* const* argv) override;
    /// Runs the survey, prints the summary line on stdout (on success) or the failure on stderr.
    /// Returns the process exit code (common::kExit*); never throws.
    int run() override;

    const SurveyResult& result() const { return result_; }
    const RefreshResult& refreshResult() const { return refresh_result_; }
    const SurveyInputs& inputs() const { return inputs_; }

  private:
    SurveyInputs inputs_;
    SurveyOptions options_;
    common::NamedConfigFile config_;  ///< the --ini file
    SurveyResult result_;
    place::PlaceIndexOptions place_options_;  ///< [place_index] of the --ini file
    bool build_place_index_ = true;
    std::optional<RefreshInputs> refresh_;  ///< --refresh: a refresh instead of a survey
    RefreshResult refresh_result_;
    int runRefresh();
    void buildIndex();
    bool verbose_ = false;
};

/// The default survey.ini: share/lookup/survey.ini from the source or install tree.
std::string defaultSurveyIni();

}  // namespace lookup::survey

#pragma once
// lookup-place's command line: builds the ceiling place index of an existing database, or
// measures how well the index finds the place of every frame of a query rawlog.
//
//   lookup-place --db DB [--ini FILE]                 build DB/place_index.bin
//   lookup-place --db DB --evaluate Q.rawlog --gt Q.GT.txt [--every N] [--json F]
//
// Ground truth is read only by --evaluate, to score the candidates.

#include <string>

#include "lookup/common/app.h"
#include "lookup/place/place_index.h"

namespace lookup::place {

class PlaceApp : public common::App {
  public:
    /// Parses the command line; false (help printed or an error) when the program should exit
    /// with exitCode().
    bool initialize(int argc, const char* const* argv) override;
    int run() override;

  private:
    int build();
    int evaluate();

    std::string db_dir_, ini_file_, query_rawlog_, gt_file_, json_file_;
    int every_ = 1;
    bool quiet_ = false;
    PlaceIndexOptions options_;
};

/// Builds `<db>/place_index.bin` for the database in `db_dir` (the references are only read).
/// Returns a one-line summary (references indexed, features, bytes, seconds).
std::string buildPlaceIndex(const std::string& db_dir, const PlaceIndexOptions& options,
                            bool show_progress);

}  // namespace lookup::place

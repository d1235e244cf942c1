#pragma once
// Heat maps stored with the database (paper Sec. III-B: "all the reference images are processed
// with it and corresponding sample quality heat maps are generated alongside the reference image
// database"), in the format of lookup/database/heat_maps.h: DB/<dir>/heat_<index:06>.png,
// 16-bit grey scaled to [0, 1] at the network's resolution (database::loadHeatMap resizes to the
// image), <dir> listed in db.ini [heatmaps] directory.
//
// Atomic: the maps are written into `<dir>.tmp`, renamed to a new folder `<dir>`, and only then
// is db.ini rewritten (temp file + rename) to point at it; the previous folder is removed last.
// Any failure before the db.ini rename leaves the database's heat maps and db.ini untouched.

#include <functional>
#include <string>

#include "lookup/database/reference_database.h"
#include "lookup/fcn/labels.h"
#include "lookup/fcn/model.h"

namespace lookup::fcn {

struct HeatMapsWritten {
    std::string directory;  ///< folder name inside the database (as written to db.ini)
    std::size_t count = 0;
    double seconds = 0;
};

/// Writes one heat map per reference of `db` and lists them in db.ini. Throws
/// std::runtime_error naming the file on failure (the database is then unchanged).
HeatMapsWritten writeHeatMaps(const database::ReferenceDatabase& db, const HeatMapModel& model,
                              const ProgressFn& progress = {});

/// Sets db.ini's [heatmaps] directory (adding the section if absent), keeping every other line,
/// via `<db.ini>.tmp` + rename. Throws std::runtime_error naming the file on failure.
void setHeatMapsDirectory(const std::string& db_ini_path, const std::string& directory);

}  // namespace lookup::fcn

namespace lookup::fcn {

/// A figure for people: the grey reference image beside its heat map (colour map, blue = low,
/// red = high) with the `points` the localiser would sample (refine::heatMapPoints) drawn on
/// both. CV_8UC3.
cv::Mat heatMapFigure(const cv::Mat& image, const cv::Mat& heat,
                      const std::vector<cv::Point2f>& points);

}  // namespace lookup::fcn

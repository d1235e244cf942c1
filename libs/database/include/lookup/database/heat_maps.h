#pragma once
// The database's heat-map files (paper Sec. III-B: sample quality heat maps "generated alongside
// the reference image database"): lookup-train writes them, the localiser reads them.
// DB/<db.ini [heatmaps] directory>/heat_<index:06>.png, 16-bit grey scaled to [0, 1], stored at
// the network's resolution or at the ceiling image's.

#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <string>

#include "lookup/database/reference_database.h"

namespace lookup::database {

/// The file name of reference `index`'s heat map inside the heat-map folder.
std::string heatMapFileName(std::size_t index);

/// Encodes a [0, 1] CV_32FC1 heat map as the stored 16-bit PNG image (saturating outside).
cv::Mat encodeHeatMap(const cv::Mat& heat);

/// The heat map of reference `index` as CV_32F in [0, 1] of the ceiling image's size (resized
/// bilinearly when stored smaller), or an empty Mat when the database has none. Throws
/// std::runtime_error naming the file when db.ini lists heat maps but one is missing, unreadable
/// or larger than the image.
cv::Mat loadHeatMap(const ReferenceDatabase& db, std::size_t index);

}  // namespace lookup::database

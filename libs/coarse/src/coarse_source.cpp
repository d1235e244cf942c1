#include <cmath>
#include <fstream>
#include <sstream>

#include "lookup/coarse/coarse_source.h"

namespace lookup::coarse {

MatchFileSource::MatchFileSource(const std::string& path, double max_time_gap_s,
                                 std::shared_ptr<const ReferenceDescriptors> references)
    : path_(path), max_time_gap_s_(max_time_gap_s), references_(std::move(references)) {
    std::ifstream in(path);
    if (!in) throw DescriptorFileError(path + ": cannot open the match file");
    std::string line;
    for (std::size_t line_no = 1; std::getline(in, line); ++line_no) {
        const auto first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos || line[first] == '#') continue;
        std::istringstream row(line);
        double q = 0, ref = 0;
        std::string extra;
        if (!(row >> q >> ref) || (row >> extra) || !std::isfinite(q) || !std::isfinite(ref)) {
            throw DescriptorFileError(path + ":" + std::to_string(line_no) +
                                      ": expected 'query_time reference_time', got '" + line + "'");
        }
        if (!rows_.empty() && q < rows_.back().first) {
            throw DescriptorFileError(path + ":" + std::to_string(line_no) +
                                      ": query times must not decrease");
        }
        rows_.emplace_back(q, ref);
    }
    if (rows_.empty()) throw DescriptorFileError(path + ": no rows");
}

CoarseResult MatchFileSource::locate(const CoarseQuery& query) {
    CoarseResult r;
    r.query_index = queries_++;
    r.query_time_s = query.time_s;
    const auto it = std::lower_bound(
        rows_.begin(), rows_.end(), query.time_s,
        [](const std::pair<double, double>& row, double t) { return row.first < t; });
    auto best = rows_.end();
    if (it != rows_.end()) best = it;
    if (it != rows_.begin() &&
        (best == rows_.end() || query.time_s - (it - 1)->first < best->first - query.time_s)) {
        best = it - 1;
    }
    if (std::abs(best->first - query.time_s) > max_time_gap_s_) {
        r.status = CoarseStatus::Lost;
        r.reason = "no row of " + path_ + " within " + std::to_string(max_time_gap_s_) +
                   " s of the query time";
        return r;
    }
    r.status = CoarseStatus::External;
    r.reference_time_s = best->second;
    if (references_ && !references_->empty()) {
        r.reference_index = references_->nearestInTime(best->second);
        if (references_->hasPoses()) r.coarse_pose = references_->pose(r.reference_index);
    }
    return r;
}

PoseFileSource::PoseFileSource(const std::string& path, double max_gap_s,
                               std::shared_ptr<const ReferenceDescriptors> references)
    : path_(path),
      max_gap_s_(max_gap_s),
      references_(std::move(references)),
      track_(common::readPoseFile(path)),
      interpolator_(common::makeInterpolator(track_, max_gap_s)) {}

CoarseResult PoseFileSource::locate(const CoarseQuery& query) {
    CoarseResult r;
    r.query_index = queries_++;
    r.query_time_s = query.time_s;
    mrpt::poses::CPose3D pose;
    bool valid = false;
    if (!track_.empty()) {
        interpolator_.interpolate(mrpt::Clock::fromDouble(query.time_s), pose, valid);
    }
    if (!valid) {
        r.status = CoarseStatus::Lost;
        r.reason = "query time outside the pose track of " + path_ + " or in a gap";
        return r;
    }
    r.status = CoarseStatus::External;
    r.coarse_pose = pose;
    if (references_ && references_->hasPoses()) {
        r.reference_index = references_->nearestInSpace(pose);
        r.reference_time_s = references_->time(r.reference_index);
    }
    return r;
}

std::optional<std::pair<double, double>> MatchFileSource::queryTimeSpan() const {
    return std::make_pair(rows_.front().first - max_time_gap_s_,
                          rows_.back().first + max_time_gap_s_);
}

std::optional<std::pair<double, double>> PoseFileSource::queryTimeSpan() const {
    return std::make_pair(track_.front().time_s, track_.back().time_s);
}

}  // namespace lookup::coarse

#include "lookup/common/pose_files.h"

#include <mrpt/math/CQuaternion.h>
#include <mrpt/system/datetime.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "lookup/common/config.h"
#include "lookup/common/rawlog_io.h"

namespace lookup::common {

namespace {

// Beyond these a value is a unit or format mistake, and times would overflow the 64-bit
// clock (mrpt::Clock ticks of 100 ns) when converted.
constexpr double kMaxTimeS = 1e10;       // year 2286
constexpr double kMaxCoordinateM = 1e8;  // beyond any UTM northing

PoseFileError rowError(const std::string& path, int line_no, const std::string& reason) {
    return PoseFileError(path + ":" + std::to_string(line_no) + ": " + reason);
}

// The numbers of one row, checked; the pose it describes.
StampedPose parseRow(const std::string& path, int line_no, const std::string& line,
                     std::size_t& columns_seen) {
    std::istringstream row(line);
    std::vector<double> v;
    double x;
    while (row >> x) v.push_back(x);
    if (!row.eof()) throw rowError(path, line_no, "not a number in row");
    if (v.size() != 7 && v.size() != 8) {
        throw rowError(path, line_no,
                       "expected 7 (MRPT) or 8 (TUM) columns, found " + std::to_string(v.size()));
    }
    if (columns_seen != 0 && v.size() != columns_seen) {
        throw rowError(path, line_no, "column count changes within the file");
    }
    columns_seen = v.size();
    for (double value : v) {
        if (!std::isfinite(value)) throw rowError(path, line_no, "value not finite");
    }
    if (std::abs(v[0]) > kMaxTimeS) throw rowError(path, line_no, "time stamp out of range");
    for (int i = 1; i <= 3; ++i) {
        if (std::abs(v[i]) > kMaxCoordinateM) {
            throw rowError(path, line_no, "coordinate out of range (|value| > 1e8 m)");
        }
    }
    StampedPose p;
    p.time_s = v[0];
    if (v.size() == 7) {
        p.pose = mrpt::poses::CPose3D(v[1], v[2], v[3], v[4], v[5], v[6]);
        return p;
    }
    if (std::hypot(std::hypot(v[4], v[5]), std::hypot(v[6], v[7])) < 1e-6) {
        throw rowError(path, line_no, "zero quaternion");
    }
    mrpt::math::CQuaternionDouble q(v[7], v[4], v[5], v[6]);  // w, x, y, z
    q.normalize();  // printed quaternions are unit only to their digits
    p.pose = mrpt::poses::CPose3D(q, v[1], v[2], v[3]);
    return p;
}

}  // namespace

PoseTrack readPoseFile(const std::string& path) {
    std::ifstream in(path);
    if (!in) throw PoseFileError(path + ": cannot open pose file");
    PoseTrack track;
    std::string line;
    int line_no = 0;
    std::size_t columns_seen = 0;
    while (std::getline(in, line)) {
        ++line_no;
        const auto first = line.find_first_not_of(" \t\r");
        if (first == std::string::npos || line[first] == '#' || line[first] == '%') continue;
        StampedPose p = parseRow(path, line_no, line, columns_seen);
        if (!track.empty() && p.time_s <= track.back().time_s) {
            throw rowError(path, line_no, "time stamps must increase");
        }
        track.push_back(p);
    }
    if (in.bad()) throw PoseFileError(path + ": read error");
    if (track.empty()) throw PoseFileError(path + ": no poses in file");
    return track;
}

void writeMrptPoseFile(const std::string& path, const PoseTrack& track) {
    OutputFile f(path);
    for (const auto& p : track) {
        f.printf("%.6f %.6f %.6f %.6f %.8f %.8f %.8f\n", p.time_s, p.pose.x(), p.pose.y(),
                 p.pose.z(), p.pose.yaw(), p.pose.pitch(), p.pose.roll());
    }
    f.close();
}

void writeTumPoseFile(const std::string& path, const PoseTrack& track) {
    OutputFile f(path);
    for (const auto& p : track) {
        mrpt::math::CQuaternionDouble q;
        p.pose.getAsQuaternion(q);
        f.printf("%.6f %.6f %.6f %.6f %.9f %.9f %.9f %.9f\n", p.time_s, p.pose.x(), p.pose.y(),
                 p.pose.z(), q.x(), q.y(), q.z(), q.r());
    }
    f.close();
}

mrpt::poses::CPose3DInterpolator makeInterpolator(const PoseTrack& track, double max_gap_s) {
    mrpt::poses::CPose3DInterpolator interp;
    interp.setInterpolationMethod(mrpt::poses::imLinearSlerp);
    interp.setMaxTimeInterpolation(
        std::chrono::microseconds(static_cast<int64_t>(max_gap_s * 1e6)));
    for (const auto& p : track) {
        interp.insert(mrpt::Clock::fromDouble(p.time_s), p.pose.asTPose());
    }
    return interp;
}

std::optional<mrpt::poses::CPose3D> poseAt(const mrpt::poses::CPose3DInterpolator& interp,
                                           double time_s) {
    mrpt::poses::CPose3D p;
    bool valid = false;
    interp.interpolate(mrpt::Clock::fromDouble(time_s), p, valid);
    if (!valid) return std::nullopt;
    return p;
}

}  // namespace lookup::common

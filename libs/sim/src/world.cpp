#include "lookup/sim/world.h"

#include "noise.h"

#include <lookup/common/config.h>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace lookup::sim {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using namespace detail;

constexpr double kPi = 3.14159265358979323846;
constexpr double kRouteStep = 0.25;  // spacing of route() points [m]
constexpr double kBumpCell = 0.2;    // sampling of the ceiling relief [m]
constexpr double kReliefCell = 0.1;  // sampling of the wall relief [m]
constexpr double kLevelStep = 0.25;  // sampling of the grade profile along the route [m]
constexpr double kLevelCell = 0.5;   // plan-view sampling of level() [m]
// Ducts and pipes on a grade are split into pieces this long, so they follow the roof.
constexpr double kGradedPiece = 2.0;

// Feature streams of the texture: each gets its own seed offset.
constexpr uint32_t kLayout = 11;
constexpr uint32_t kBump = 23;
constexpr uint32_t kFloor = 31;
constexpr uint32_t kRock = 41;
constexpr uint32_t kCrack = 53;
constexpr uint32_t kShotcrete = 61;
constexpr uint32_t kMesh = 71;
constexpr uint32_t kBolt = 83;
constexpr uint32_t kWall = 97;
constexpr uint32_t kSign = 101;
constexpr uint32_t kSide = 113;
constexpr uint32_t kDuctRib = 127;
constexpr uint32_t kWallRelief = 131;
constexpr uint32_t kNiche = 137;

// Wall relief: fractal noise from 4 m down to ~0.5 m (4 octaves, /2.03 each, gain 0.7: rock
// is rough at every scale), mapped through a tanh so that it stays within +-wall_roughness_m
// with a standard deviation of about half of it.
constexpr int kReliefOctaves = 4;
constexpr double kReliefWavelength = 4.0;
constexpr double kReliefGain = 0.7;
constexpr double kReliefStretch = 6.0;

Vector2d rot90(const Vector2d& v) { return {-v.y(), v.x()}; }

/// Arc-length resampling of a polyline at `step`.
std::vector<Vector2d> resample(const std::vector<Vector2d>& pts, double step) {
    std::vector<Vector2d> out;
    if (pts.empty()) return out;
    out.push_back(pts.front());
    double carry = 0;  // distance already walked past the last output point
    for (std::size_t i = 1; i < pts.size(); ++i) {
        const Vector2d a = pts[i - 1], b = pts[i];
        const double len = (b - a).norm();
        if (len < 1e-12) continue;
        double pos = step - carry;
        while (pos <= len + 1e-12) {
            out.push_back(a + (b - a) * (pos / len));
            pos += step;
        }
        carry = len - (pos - step);
    }
    return out;
}

/// A main tunnel: straight pieces of random length joined by small bends, heading pulled back
/// towards +x. The draws are sequential, so a shorter tunnel is the same tunnel cut short.
std::vector<Vector2d> mainLine(const WorldOptions& opt, uint32_t seed, uint32_t stream) {
    std::vector<Vector2d> pts{Vector2d(0, 0)};
    double heading = 0, s = 0;
    for (uint32_t k = 0; s < opt.length_m - 1e-6; ++k) {
        double len = opt.segment_length_m * (0.6 + 0.8 * unit(hash3(seed, stream, 2 * k)));
        len = std::min(len, opt.length_m - s);
        pts.push_back(pts.back() + len * Vector2d(std::cos(heading), std::sin(heading)));
        s += len;
        const double bend =
            (2 * unit(hash3(seed, stream, 2 * k + 1)) - 1) * opt.bend_max_deg * kPi / 180;
        heading = 0.6 * heading + bend;
    }
    return pts;
}

/// Point and direction at arc length s of a polyline.
Vector2d pointAt(const std::vector<Vector2d>& pts, double s, Vector2d* dir) {
    for (std::size_t i = 1; i < pts.size(); ++i) {
        const double len = (pts[i] - pts[i - 1]).norm();
        if (s <= len || i + 1 == pts.size()) {
            *dir = (pts[i] - pts[i - 1]) / len;
            return Vector2d(pts[i - 1] + *dir * std::min(s, len));
        }
        s -= len;
    }
    *dir = Vector2d(1, 0);
    return pts.front();
}

double polylineLength(const std::vector<Vector2d>& pts) {
    double length = 0;
    for (std::size_t i = 1; i < pts.size(); ++i) length += (pts[i] - pts[i - 1]).norm();
    return length;
}

}  // namespace

TunnelWorld::TunnelWorld(const WorldOptions& options, uint64_t seed)
    : opt_(options),
      seed_(mix32(static_cast<uint32_t>(seed) ^ mix32(static_cast<uint32_t>(seed >> 32)))) {
    if (!opt_.texture_image.empty()) {
        cv::Mat img = cv::imread(opt_.texture_image, cv::IMREAD_GRAYSCALE);
        if (img.empty()) {
            throw common::ConfigError("[world] texture_image: cannot read image '" +
                                      opt_.texture_image + "'");
        }
        img.convertTo(img, CV_32F, 1.0 / 255.0);
        tex_w_ = img.cols;
        tex_h_ = img.rows;
        tex_.assign(reinterpret_cast<float*>(img.data),
                    reinterpret_cast<float*>(img.data) + img.total());
    }
    buildLayout();
}

void TunnelWorld::addSegment(const Vector2d& a, const Vector2d& b, double half_width, double s0,
                             bool on_route) {
    TunnelSegment s;
    s.a = a;
    s.b = b;
    s.length = (b - a).norm();
    s.dir = s.length > 1e-9 ? Vector2d((b - a) / s.length) : Vector2d(1, 0);
    s.left = rot90(s.dir);
    s.half_width = half_width;
    s.s0 = s0;
    s.on_route = on_route;
    segments_.push_back(s);
}

void TunnelWorld::buildLayout() {
    double s_side = 1e5;  // texture coordinates of side openings, far from the main ones
    const std::vector<Vector2d> raw_route =
        opt_.layout == "twin" ? buildTwinTunnels(&s_side) : buildSingleTunnel(&s_side);
    computeBounds();
    buildBuckets();
    buildBumps();
    buildRelief();
    buildLevels(raw_route);
    buildRoute(raw_route);
    buildFurniture(raw_route);
}

std::vector<Vector2d> TunnelWorld::buildSingleTunnel(double* s_side) {
    std::vector<Vector2d> route = mainLine(opt_, seed_, kLayout);
    addLine(route, 0);
    addSides(route, kLayout + 1000, 1.0, s_side);
    return route;
}

std::vector<Vector2d> TunnelWorld::buildTwinTunnels(double* s_side) {
    // Mine A: two parallel tunnels joined by a crosscut near their far ends; the route goes
    // out along the first, through the crosscut and back along the second.
    const double hw = opt_.width_m / 2;
    const std::vector<Vector2d> t1 = mainLine(opt_, seed_, kLayout);
    std::vector<Vector2d> t2 = t1;
    for (auto& p : t2) p.y() += opt_.twin_separation_m;
    addLine(t1, 0);
    addLine(t2, 50000);
    // Both tunnels continue a little past the crosscut (dead ends, as in a real level).
    Vector2d dir = (t1.back() - t1[t1.size() - 2]).normalized();
    addSegment(t1.back(), t1.back() + dir * 10, hw, *s_side, false);
    addSegment(t2.back(), t2.back() + dir * 10, hw, *s_side + 1000, false);
    *s_side += 2000;
    addSegment(t1.back(), t2.back(), hw, 90000, true);
    addSides(t1, kLayout + 1000, -1.0, s_side);  // openings on the outer sides
    addSides(t2, kLayout + 2000, 1.0, s_side);
    std::vector<Vector2d> route = t1;
    route.insert(route.end(), t2.rbegin(), t2.rend());
    return route;
}

void TunnelWorld::addLine(const std::vector<Vector2d>& pts, double s0) {
    for (std::size_t i = 1; i < pts.size(); ++i) {
        addSegment(pts[i - 1], pts[i], opt_.width_m / 2, s0, true);
        s0 += (pts[i] - pts[i - 1]).norm();
    }
}

void TunnelWorld::addSides(const std::vector<Vector2d>& pts, uint32_t stream, double flip,
                           double* s_side) {
    const double length = polylineLength(pts);
    const std::vector<double> junctions = addJunctions(pts, length, s_side);
    std::vector<double> openings = junctions;  // where niches keep away from
    addDrawpoints(pts, length, stream, flip, junctions, &openings, s_side);
    addNiches(pts, stream + 500, openings, s_side);
}

std::vector<double> TunnelWorld::addJunctions(const std::vector<Vector2d>& pts, double length,
                                              double* s_side) {
    std::vector<double> junctions;
    if (opt_.junction_spacing_m <= 0) return junctions;
    const double hw = opt_.width_m / 2;
    for (double s = 0.5 * opt_.junction_spacing_m; s < length - 10; s += opt_.junction_spacing_m) {
        Vector2d dir;
        const Vector2d c = pointAt(pts, s, &dir);
        const Vector2d n = rot90(dir) * (hw + opt_.junction_length_m);
        addSegment(c - n, c + n, hw, *s_side, false);
        *s_side += 1000;
        junctions.push_back(s);
    }
    return junctions;
}

void TunnelWorld::addDrawpoints(const std::vector<Vector2d>& pts, double length, uint32_t stream,
                                double flip, const std::vector<double>& junctions,
                                std::vector<double>* openings, double* s_side) {
    if (opt_.drawpoint_spacing_m <= 0) return;
    const double hw = opt_.width_m / 2;
    uint32_t k = 0;
    for (double s = 0.5 * opt_.drawpoint_spacing_m; s < length - 5;
         s += opt_.drawpoint_spacing_m, ++k) {
        bool near_junction = false;
        for (double j : junctions) near_junction |= std::abs(j - s) < 10;
        if (near_junction) continue;
        Vector2d dir;
        const Vector2d c = pointAt(pts, s, &dir);
        const double side = (unit(hash3(seed_, stream, k)) < 0.5 ? 1.0 : -1.0) * flip;
        const double ang = side * opt_.drawpoint_angle_deg * kPi / 180;
        const Vector2d d(std::cos(ang) * dir.x() - std::sin(ang) * dir.y(),
                         std::sin(ang) * dir.x() + std::cos(ang) * dir.y());
        addSegment(c, c + d * (hw + opt_.drawpoint_length_m), opt_.drawpoint_width_m / 2, *s_side,
                   false);
        *s_side += 1000;
        openings->push_back(s);
    }
}

void TunnelWorld::computeBounds() {
    lo_ = Vector2d(1e18, 1e18);
    hi_ = -lo_;
    for (const auto& s : segments_) {
        for (const Vector2d& p : {s.a, s.b}) {
            lo_ = lo_.cwiseMin(p - Vector2d::Constant(s.half_width));
            hi_ = hi_.cwiseMax(p + Vector2d::Constant(s.half_width));
        }
    }
}

void TunnelWorld::addNiches(const std::vector<Vector2d>& pts, uint32_t stream,
                            const std::vector<double>& openings, double* s_side) {
    if (opt_.niche_spacing_m <= 0 || pts.size() < 2) return;
    const double hw = opt_.width_m / 2, r = opt_.niche_width_m / 2;
    // Sequential draws along the line, so a shorter tunnel keeps the same niches.
    double s = 0, offset = 0;
    std::size_t piece = 1;
    for (uint32_t k = 0;; ++k) {
        s += opt_.niche_spacing_m * (0.5 + unit(hash3(seed_, stream, 2 * k)));
        while (piece < pts.size() && s > offset + (pts[piece] - pts[piece - 1]).norm()) {
            offset += (pts[piece] - pts[piece - 1]).norm();
            ++piece;
        }
        if (piece >= pts.size() || s > offset + (pts[piece] - pts[piece - 1]).norm() - 3) break;
        bool near_opening = s < 5;
        for (double o : openings) near_opening |= std::abs(o - s) < 8;
        if (near_opening) continue;
        const Vector2d dir = (pts[piece] - pts[piece - 1]).normalized();
        const Vector2d c = pts[piece - 1] + dir * (s - offset);
        const double side = unit(hash3(seed_, stream, 2 * k + 1)) < 0.5 ? 1.0 : -1.0;
        const Vector2d n = rot90(dir) * side;
        // A rounded alcove: a capsule across the wall line whose mouth is niche_width_m wide.
        const double back = hw + opt_.niche_depth_m - r;
        addSegment(c + n * std::min(hw - 0.5, back), c + n * back, r, *s_side, false);
        *s_side += 1000;
    }
}

void TunnelWorld::buildBuckets() {
    // A margin around the tunnels, so points just inside the rock get their true distance.
    bucket_origin_ = lo_ - Vector2d(4, 4);
    bucket_nx_ = static_cast<int>(std::ceil((hi_.x() - lo_.x() + 8) / bucket_m_)) + 1;
    bucket_ny_ = static_cast<int>(std::ceil((hi_.y() - lo_.y() + 8) / bucket_m_)) + 1;
    buckets_.assign(static_cast<std::size_t>(bucket_nx_) * bucket_ny_, {});
    const double reach = bucket_m_ * 0.7072 + 3.0;  // half diagonal + margin for outside queries
    for (int si = 0; si < static_cast<int>(segments_.size()); ++si) {
        const TunnelSegment& s = segments_[si];
        const double r = s.half_width + reach;
        const Vector2d lo = s.a.cwiseMin(s.b) - Vector2d::Constant(r) - bucket_origin_;
        const Vector2d hi = s.a.cwiseMax(s.b) + Vector2d::Constant(r) - bucket_origin_;
        for (int by = std::max(0, int(lo.y() / bucket_m_));
             by <= std::min(bucket_ny_ - 1, int(hi.y() / bucket_m_)); ++by) {
            for (int bx = std::max(0, int(lo.x() / bucket_m_));
                 bx <= std::min(bucket_nx_ - 1, int(hi.x() / bucket_m_)); ++bx) {
                const Vector2d c = bucket_origin_ + bucket_m_ * Vector2d(bx + 0.5, by + 0.5);
                const double t = std::clamp((c - s.a).dot(s.dir), 0.0, s.length);
                if ((c - (s.a + t * s.dir)).norm() <= r) {
                    buckets_[by * bucket_nx_ + bx].push_back(si);
                }
            }
        }
    }
}

void TunnelWorld::buildBumps() {
    bump_origin_ = lo_ - Vector2d(2, 2);
    bump_nx_ = static_cast<int>(std::ceil((hi_.x() - lo_.x() + 4) / kBumpCell)) + 2;
    bump_ny_ = static_cast<int>(std::ceil((hi_.y() - lo_.y() + 4) / kBumpCell)) + 2;
    bump_.assign(static_cast<std::size_t>(bump_nx_) * bump_ny_, 0.0f);
    if (opt_.bump_amplitude_m <= 0) return;
    for (int j = 0; j < bump_ny_; ++j) {
        for (int i = 0; i < bump_nx_; ++i) {
            const double x = bump_origin_.x() + i * kBumpCell, y = bump_origin_.y() + j * kBumpCell;
            const NoiseSample n = fbm(x, y, seed_ + kBump, 2, opt_.bump_wavelength_m, 0.45, 0);
            bump_[j * bump_nx_ + i] = static_cast<float>(std::clamp(2.6 * (n.v - 0.5), -1.0, 1.0) *
                                                         opt_.bump_amplitude_m);
        }
    }
}

void TunnelWorld::buildRelief() {
    relief_.clear();
    if (opt_.wall_roughness_m <= 0) return;
    // Same origin as the bump samples (bounding box plus 2 m), finer cells.
    relief_nx_ = static_cast<int>(std::ceil((hi_.x() - lo_.x() + 4) / kReliefCell)) + 2;
    relief_ny_ = static_cast<int>(std::ceil((hi_.y() - lo_.y() + 4) / kReliefCell)) + 2;
    relief_.assign(static_cast<std::size_t>(relief_nx_) * relief_ny_, 0.0f);
    for (int j = 0; j < relief_ny_; ++j) {
        for (int i = 0; i < relief_nx_; ++i) {
            const double x = bump_origin_.x() + i * kReliefCell;
            const double y = bump_origin_.y() + j * kReliefCell;
            const NoiseSample n =
                fbm(x, y, seed_ + kWallRelief, kReliefOctaves, kReliefWavelength, kReliefGain, 0);
            relief_[j * relief_nx_ + i] =
                static_cast<float>(std::tanh(kReliefStretch * (n.v - 0.5)) * opt_.wall_roughness_m);
        }
    }
    // Steepest slope of the bilinear interpolant (bounds |grad| for sphere tracing).
    float steepest = 0;
    for (int j = 0; j + 1 < relief_ny_; ++j) {
        for (int i = 0; i + 1 < relief_nx_; ++i) {
            const float* r0 = &relief_[static_cast<std::size_t>(j) * relief_nx_ + i];
            const float* r1 = r0 + relief_nx_;
            steepest = std::max({steepest, std::abs(r0[1] - r0[0]), std::abs(r1[1] - r1[0]),
                                 std::abs(r1[0] - r0[0]), std::abs(r1[1] - r0[1])});
        }
    }
    relief_lipschitz_ = std::sqrt(2.0) * steepest / kReliefCell;
}

double TunnelWorld::wallRelief(double x, double y, double* gx, double* gy) const {
    if (gx) *gx = 0;
    if (gy) *gy = 0;
    if (relief_.empty()) return 0;
    const double u = (x - bump_origin_.x()) / kReliefCell, v = (y - bump_origin_.y()) / kReliefCell;
    const double fu = std::floor(u), fv = std::floor(v);
    const int i = static_cast<int>(fu), j = static_cast<int>(fv);
    if (i < 0 || j < 0 || i + 1 >= relief_nx_ || j + 1 >= relief_ny_) return 0;
    const double a = u - fu, b = v - fv;
    const float* r0 = &relief_[static_cast<std::size_t>(j) * relief_nx_ + i];
    const float* r1 = r0 + relief_nx_;
    if (gx) *gx = ((1 - b) * (r0[1] - r0[0]) + b * (r1[1] - r1[0])) / kReliefCell;
    if (gy) *gy = ((1 - a) * (r1[0] - r0[0]) + a * (r1[1] - r0[1])) / kReliefCell;
    return (1 - b) * ((1 - a) * r0[0] + a * r0[1]) + b * ((1 - a) * r1[0] + a * r1[1]);
}

double TunnelWorld::bumpAt(double x, double y, double* gx, double* gy) const {
    const double u = (x - bump_origin_.x()) / kBumpCell, v = (y - bump_origin_.y()) / kBumpCell;
    const double fu = std::floor(u), fv = std::floor(v);
    const int i = static_cast<int>(fu), j = static_cast<int>(fv);
    if (i < 0 || j < 0 || i + 1 >= bump_nx_ || j + 1 >= bump_ny_) {
        if (gx) *gx = *gy = 0;
        return 0;
    }
    const double a = u - fu, b = v - fv;
    const float* r0 = &bump_[j * bump_nx_ + i];
    const float* r1 = r0 + bump_nx_;
    if (gx) {
        *gx = ((1 - b) * (r0[1] - r0[0]) + b * (r1[1] - r1[0])) / kBumpCell;
        *gy = ((1 - a) * (r1[0] - r0[0]) + a * (r1[1] - r0[1])) / kBumpCell;
    }
    return (1 - b) * ((1 - a) * r0[0] + a * r0[1]) + b * ((1 - a) * r1[0] + a * r1[1]);
}

void TunnelWorld::buildLevels(const std::vector<Vector2d>& raw) {
    if (opt_.grade.empty() || raw.size() < 2) return;
    const std::vector<GradeRamp> ramps = parseGrade(opt_.grade);
    std::vector<double> arc{0.0};  // route distance at each raw point
    for (std::size_t i = 1; i < raw.size(); ++i)
        arc.push_back(arc.back() + (raw[i] - raw[i - 1]).norm());
    const int n = static_cast<int>(std::ceil(arc.back() / kLevelStep)) + 2;
    std::vector<double> g(n, 0.0);
    for (int i = 0; i < n; ++i) {
        for (const GradeRamp& r : ramps) {
            if (i * kLevelStep >= r.start_m && i * kLevelStep < r.end_m) g[i] += r.grade;
        }
    }
    // Vertical curves: the grade changes linearly over grade_transition_m (a box filter of the
    // grade, a parabola in height), as a road is built so the vehicle does not ground.
    const int half = static_cast<int>(std::lround(0.5 * opt_.grade_transition_m / kLevelStep));
    std::vector<double> sum(n + 1, 0.0);
    for (int i = 0; i < n; ++i) sum[i + 1] = sum[i] + g[i];
    profile_.assign(n, 0.0);
    double prev_g = 0;
    for (int i = 0; i < n; ++i) {
        const int lo = std::max(0, i - half), hi = std::min(n, i + half + 1);
        const double gi = (sum[hi] - sum[lo]) / (hi - lo);
        if (i > 0) profile_[i] = profile_[i - 1] + 0.5 * (prev_g + gi) * kLevelStep;
        max_grade_ = std::max(max_grade_, std::abs(gi));
        prev_g = gi;
    }
    max_grade_ = 1.05 * max_grade_ + 1e-3;  // margin for the bilinear plan-view samples
    level_nx_ = static_cast<int>(std::ceil((hi_.x() - lo_.x() + 4) / kLevelCell)) + 2;
    level_ny_ = static_cast<int>(std::ceil((hi_.y() - lo_.y() + 4) / kLevelCell)) + 2;
    level_.assign(static_cast<std::size_t>(level_nx_) * level_ny_, 0.0f);
    for (int j = 0; j < level_ny_; ++j) {
        for (int i = 0; i < level_nx_; ++i) {
            const Vector2d p = bump_origin_ + kLevelCell * Vector2d(i, j);
            double best = 1e18, s_best = 0;
            for (std::size_t k = 1; k < raw.size(); ++k) {
                const Vector2d ab = raw[k] - raw[k - 1];
                const double len = ab.norm();
                if (len < 1e-9) continue;
                const double t = std::clamp((p - raw[k - 1]).dot(ab) / len, 0.0, len);
                const double d = (p - raw[k - 1] - ab * (t / len)).squaredNorm();
                if (d < best) {
                    best = d;
                    s_best = arc[k - 1] + t;
                }
            }
            level_[static_cast<std::size_t>(j) * level_nx_ + i] =
                static_cast<float>(levelAtRoute(s_best));
        }
    }
}

double TunnelWorld::levelAtRoute(double s) const {
    if (profile_.empty()) return 0;
    const double f = std::clamp(s / kLevelStep, 0.0, double(profile_.size() - 1));
    const std::size_t i = std::min(static_cast<std::size_t>(f), profile_.size() - 2);
    const double a = f - i;
    return (1 - a) * profile_[i] + a * profile_[i + 1];
}

double TunnelWorld::level(double x, double y) const {
    if (level_.empty()) return 0;
    const double u = std::clamp((x - bump_origin_.x()) / kLevelCell, 0.0, level_nx_ - 1.001);
    const double v = std::clamp((y - bump_origin_.y()) / kLevelCell, 0.0, level_ny_ - 1.001);
    const int i = static_cast<int>(u), j = static_cast<int>(v);
    const double a = u - i, b = v - j;
    const float* r0 = &level_[static_cast<std::size_t>(j) * level_nx_ + i];
    const float* r1 = r0 + level_nx_;
    return (1 - b) * ((1 - a) * r0[0] + a * r0[1]) + b * ((1 - a) * r1[0] + a * r1[1]);
}

void TunnelWorld::buildRoute(const std::vector<Vector2d>& raw) {
    std::vector<Vector2d> pts = resample(raw, kRouteStep);
    // Two box-filter passes round the corners so the vehicle's heading is continuous.
    const int half = 16;  // 4 m
    for (int pass = 0; pass < 2; ++pass) {
        std::vector<Vector2d> out(pts.size());
        const int n = static_cast<int>(pts.size());
        for (int i = 0; i < n; ++i) {
            const int w = std::min({half, i, n - 1 - i});
            Vector2d sum = Vector2d::Zero();
            for (int k = -w; k <= w; ++k) sum += pts[i + k];
            out[i] = sum / (2 * w + 1);
        }
        pts.swap(out);
    }
    route_ = resample(pts, kRouteStep);
}

void TunnelWorld::addCylinder(const Vector3d& a, const Vector3d& b, double radius,
                              SurfaceKind kind) {
    Cylinder c;
    c.a = a;
    c.length = (b - a).norm();
    if (c.length < 1e-6) return;
    c.axis = (b - a) / c.length;
    c.radius = radius;
    c.kind = kind;
    c.lo = a.cwiseMin(b) - Vector3d::Constant(radius);
    c.hi = a.cwiseMax(b) + Vector3d::Constant(radius);
    cylinders_.push_back(c);
}

void TunnelWorld::buildServices(const std::vector<Vector2d>& raw) {
    const double h = opt_.ceiling_height_m;
    for (std::size_t i = 1; i < raw.size(); ++i) {
        const Vector2d left = rot90((raw[i] - raw[i - 1]).normalized());
        auto lift = [&](const Vector2d& p, double off, double z) {
            const Vector2d q = p + left * off;
            return Vector3d(q.x(), q.y(), graded() ? z + level(q.x(), q.y()) : z);
        };
        // On a grade, short pieces that follow the roof; a level mine keeps one per piece.
        const int pieces = graded() ? std::max(1, static_cast<int>(std::ceil(
                                                      (raw[i] - raw[i - 1]).norm() / kGradedPiece)))
                                    : 1;
        for (int k = 0; k < pieces; ++k) {
            const Vector2d a =
                k == 0 ? raw[i - 1]
                       : Vector2d(raw[i - 1] + (raw[i] - raw[i - 1]) * (double(k) / pieces));
            const Vector2d b =
                k + 1 == pieces
                    ? raw[i]
                    : Vector2d(raw[i - 1] + (raw[i] - raw[i - 1]) * (double(k + 1) / pieces));
            if (opt_.duct_radius_m > 0) {
                addCylinder(lift(a, opt_.duct_offset_m, h - opt_.duct_drop_m),
                            lift(b, opt_.duct_offset_m, h - opt_.duct_drop_m), opt_.duct_radius_m,
                            SurfaceKind::Duct);
            }
            if (opt_.pipe_radius_m > 0) {
                addCylinder(lift(a, opt_.pipe_offset_m, h - opt_.pipe_drop_m),
                            lift(b, opt_.pipe_offset_m, h - opt_.pipe_drop_m), opt_.pipe_radius_m,
                            SurfaceKind::Pipe);
            }
        }
    }
}

void TunnelWorld::buildFurniture(const std::vector<Vector2d>& raw) {
    const double h = opt_.ceiling_height_m;
    buildServices(raw);
    // Cable hangers and lamps follow the route's arc length.
    const std::vector<Vector2d> fine = resample(raw, kRouteStep);
    auto sample = [&](double s, Vector2d* left) {
        const std::size_t i =
            std::min(fine.size() - 2, static_cast<std::size_t>(std::max(0.0, s / kRouteStep)));
        *left = rot90((fine[i + 1] - fine[i]).normalized());
        return fine[i];
    };
    const double length = kRouteStep * (fine.size() - 1);
    if (opt_.cable_span_m > 0 && fine.size() > 2) {
        const double top = h - 0.15;
        const int pieces = 3;
        for (double s = 0; s + opt_.cable_span_m <= length; s += opt_.cable_span_m) {
            Vector2d l0, l1;
            const Vector2d p0 = sample(s, &l0) + 0.0 * l0;
            const Vector2d p1 = sample(s + opt_.cable_span_m, &l1);
            const Vector2d a = p0 + l0 * opt_.cable_offset_m, b = p1 + l1 * opt_.cable_offset_m;
            for (int k = 0; k < pieces; ++k) {
                const double u0 = double(k) / pieces, u1 = double(k + 1) / pieces;
                const Vector2d q0 = a + (b - a) * u0, q1 = a + (b - a) * u1;
                double z0 = top - 4 * opt_.cable_sag_m * u0 * (1 - u0);
                double z1 = top - 4 * opt_.cable_sag_m * u1 * (1 - u1);
                if (graded()) {
                    z0 += level(q0.x(), q0.y());
                    z1 += level(q1.x(), q1.y());
                }
                addCylinder({q0.x(), q0.y(), z0}, {q1.x(), q1.y(), z1}, 0.02, SurfaceKind::Cable);
            }
        }
    }
    if (opt_.light_spacing_m > 0 && fine.size() > 2) {
        for (double s = 0.5 * opt_.light_spacing_m; s < length; s += opt_.light_spacing_m) {
            Vector2d left;
            const Vector2d p = sample(s, &left) - left * 0.4;
            const double z = graded() ? h - 0.3 + level(p.x(), p.y()) : h - 0.3;
            lamps_.push_back({Vector3d(p.x(), p.y(), z), 0.12});
        }
    }
}

WallQuery TunnelWorld::query(double x, double y) const {
    WallQuery out;
    const int bx = static_cast<int>(std::floor((x - bucket_origin_.x()) / bucket_m_));
    const int by = static_cast<int>(std::floor((y - bucket_origin_.y()) / bucket_m_));
    if (bx < 0 || by < 0 || bx >= bucket_nx_ || by >= bucket_ny_) return out;
    const Vector2d p(x, y);
    for (int si : buckets_[by * bucket_nx_ + bx]) {
        const TunnelSegment& s = segments_[si];
        const Vector2d rel = p - s.a;
        const double along = rel.dot(s.dir);
        const double t = std::clamp(along, 0.0, s.length);
        const double sd = (rel - t * s.dir).norm() - s.half_width;
        if (sd < out.sdf) {
            out.sdf = sd;
            out.segment = si;
            out.s = s.s0 + along;
            out.d = rel.dot(s.left);
        }
    }
    // Rough walls. Far from every wall (where the roof no longer depends on the distance) the
    // relief is not evaluated; the distance is then understated by its bound so sphere tracing
    // stays safe.
    if (opt_.wall_roughness_m > 0 && out.segment >= 0) {
        out.relief = out.sdf > -(opt_.arch_radius_m + opt_.wall_roughness_m + 0.1)
                         ? wallRelief(x, y, nullptr, nullptr)
                         : -opt_.wall_roughness_m;
        out.sdf -= out.relief;
    }
    return out;
}

double TunnelWorld::roofHeight(double x, double y, double dw) const {
    const double h = opt_.ceiling_height_m, r = opt_.arch_radius_m;
    double z = h;
    if (dw < r) {
        const double u = r - std::max(dw, 0.0);
        z = h - r + std::sqrt(std::max(r * r - u * u, 0.0));
    }
    if (graded()) z += level(x, y);
    return z + bumpAt(x, y, nullptr, nullptr);
}

Vector2d TunnelWorld::awayFromWall(double x, double y, const WallQuery& q) const {
    if (q.segment < 0) return Vector2d(1, 0);
    const TunnelSegment& s = segments_[q.segment];
    const Vector2d p(x, y);
    const double t = std::clamp((p - s.a).dot(s.dir), 0.0, s.length);
    const Vector2d to_axis = s.a + t * s.dir - p;
    const double n = to_axis.norm();
    Vector2d away = n > 1e-9 ? Vector2d(to_axis / n) : s.left;
    // -grad sdf of the rough wall: the relief tilts the surface.
    if (opt_.wall_roughness_m > 0) {
        double gx, gy;
        wallRelief(x, y, &gx, &gy);
        away = (away + Vector2d(gx, gy)).normalized();
    }
    return away;
}

Vector2d TunnelWorld::roofSlope(double x, double y, const WallQuery& q) const {
    Vector2d g = Vector2d::Zero();
    const double r = opt_.arch_radius_m, dw = -q.sdf;
    if (dw < r && r > 0) {
        const double u = r - std::max(dw, 0.0);
        const double dz_ddw = u / std::sqrt(std::max(r * r - u * u, 1e-6));
        g += std::min(dz_ddw, 50.0) * awayFromWall(x, y, q);
    }
    double gx, gy;
    bumpAt(x, y, &gx, &gy);
    g += Vector2d(gx, gy);
    return g;
}

double TunnelWorld::floorHeight(double x, double y) const {
    const double base = graded() ? level(x, y) : 0.0;
    if (opt_.floor_roughness_m <= 0) return base;
    const NoiseSample n = fbm(x, y, seed_ + kFloor, 3, 3.0, 0.5, 0);
    const double relief = std::clamp(2.6 * (n.v - 0.5), -1.0, 1.0) * opt_.floor_roughness_m;
    return graded() ? base + relief : relief;
}

double TunnelWorld::roofAlbedo(double x, double y, const WallQuery& q, double fp, double* slope_x,
                               double* slope_y) const {
    const double min_wl = 2.0 * fp;
    double albedo;
    if (!tex_.empty()) {
        const double u = x / opt_.texture_image_size_m * tex_w_;
        const double v = y / opt_.texture_image_size_m * tex_w_;
        const double fu = std::floor(u), fv = std::floor(v);
        auto texel = [&](long iu, long iv) {
            iu %= tex_w_;
            iv %= tex_h_;
            if (iu < 0) iu += tex_w_;
            if (iv < 0) iv += tex_h_;
            return tex_[iv * tex_w_ + iu];
        };
        const long iu = static_cast<long>(fu), iv = static_cast<long>(fv);
        const double a = u - fu, b = v - fv;
        albedo = (1 - b) * ((1 - a) * texel(iu, iv) + a * texel(iu + 1, iv)) +
                 b * ((1 - a) * texel(iu, iv + 1) + a * texel(iu + 1, iv + 1));
    } else {
        // Multi-scale rock: 0.6 m blocks down to ~2 cm grain; its gradient is the micro-relief
        // that the vehicle light shades.
        const NoiseSample rock = fbm(x, y, seed_ + kRock, 6, 0.6, 0.75, min_wl);
        albedo = std::clamp(0.45 + opt_.rock_contrast * 3.0 * (rock.v - 0.5), 0.05, 0.95);
        *slope_x += 0.05 * opt_.rock_contrast * rock.dx;
        *slope_y += 0.05 * opt_.rock_contrast * rock.dy;
        // Dark joints along the ridges of a rotated, warped mid-scale noise.
        if (0.35 >= min_wl) {
            const double wx = 0.8 * x + 0.6 * y + 0.25 * rock.v, wy = -0.6 * x + 0.8 * y;
            const NoiseSample c = valueNoise(wx / 0.45, wy / 0.3, seed_ + kCrack);
            const double ridge = std::abs(2 * c.v - 1);
            albedo *= 1.0 - 0.3 * opt_.rock_contrast * smoothstep(0.04, 0.0, ridge);
        }
    }
    // Shotcrete patches: smoother and lighter, hiding the rock.
    if (opt_.shotcrete_fraction > 0) {
        const double m = valueNoise(x / 14.0, y / 14.0, seed_ + kShotcrete).v;
        const double th = 1.0 - opt_.shotcrete_fraction;
        const double w = smoothstep(th - 0.03, th + 0.03, m);
        if (w > 0) {
            const NoiseSample sc = fbm(x, y, seed_ + kShotcrete + 5, 4, 0.25, 0.5, min_wl);
            albedo = (1 - w) * albedo + w * (0.6 + 0.7 * (sc.v - 0.5));
            *slope_x *= 1 - 0.7 * w;
            *slope_y *= 1 - 0.7 * w;
        }
    }
    // Tunnel-aligned features use the piece's (along, across) coordinates.
    const double s = q.s, d = q.d;
    if (opt_.mesh_fraction > 0) {
        const double m = valueNoise(x / 17.0 + 3.7, y / 17.0, seed_ + kMesh).v;
        const double th = 1.0 - opt_.mesh_fraction;
        if (m > th) {
            const double pitch = opt_.mesh_pitch_m;
            const double ds = std::abs(s / pitch - std::floor(s / pitch + 0.5)) * pitch;
            const double dd = std::abs(d / pitch - std::floor(d / pitch + 0.5)) * pitch;
            const double wire = 0.003;
            const double he = wire + 0.5 * fp;
            const double cover = std::min(1.0, 2 * wire / std::max(fp, 1e-4));
            const double on = std::max(smoothstep(he, he * 0.4, ds), smoothstep(he, he * 0.4, dd));
            albedo = albedo + (0.72 - albedo) * on * cover * smoothstep(th, th + 0.02, m);
        }
    }
    if (opt_.bolt_spacing_m > 0 && -q.sdf > 0.5) {
        const double b = opt_.bolt_spacing_m;
        const double is = std::floor(s / b), id = std::floor(d / b + 0.5);
        const uint32_t hb = hash2(static_cast<int32_t>(is), static_cast<int32_t>(id),
                                  seed_ + kBolt + 7919 * static_cast<uint32_t>(q.segment));
        if (unit(hb) > 0.08) {  // a few bolts are missing
            const double cs = (is + 0.5) * b + 0.06 * (2 * unit(mix32(hb + 1)) - 1);
            const double cd = id * b + 0.06 * (2 * unit(mix32(hb + 2)) - 1);
            const double ang = unit(mix32(hb + 3)) * kPi / 2;
            const double ls = s - cs, ld = d - cd;
            const double u = std::cos(ang) * ls + std::sin(ang) * ld;
            const double v = -std::sin(ang) * ls + std::cos(ang) * ld;
            const double half = opt_.bolt_plate_m / 2;
            const double r = std::hypot(ls, ld);
            if (r < 0.022) {
                albedo = 0.22;  // bolt end and nut
            } else if (std::abs(u) < half && std::abs(v) < half) {
                const double edge = std::min(half - std::abs(u), half - std::abs(v));
                albedo = edge < 0.012 ? 0.5 : 0.78;  // steel plate with a pressed rim
            }
        }
    }
    for (const auto& m : markers_) {
        if ((x - m.x) * (x - m.x) + (y - m.y) * (y - m.y) <= m.radius * m.radius) albedo = m.albedo;
    }
    return std::max(albedo, 0.02);
}

double TunnelWorld::wallAlbedo(const WallQuery& q, double z, double fp) const {
    const double min_wl = 2.0 * fp;
    const uint32_t side = q.d >= 0 ? 1 : 2;
    const double s = q.s;
    const NoiseSample rock = fbm(s, z, seed_ + kWall * side, 5, 1.5, 0.6, min_wl);
    double albedo = 0.36 + 1.3 * opt_.rock_contrast * (rock.v - 0.5);
    // Blast-hole half barrels: vertical streaks repeating every ~1 m (places alias).
    if (0.25 > min_wl) {
        const double ph = s / 1.05 - std::floor(s / 1.05);
        albedo *= 0.8 + 0.2 * smoothstep(0.0, 0.12, std::min(ph, 1 - ph));
    }
    // Reflective signs: rare, bright, at eye height: what makes a sequence distinctive.
    if (opt_.sign_spacing_m > 0 && z > 1.6 && z < 2.2) {
        const double cell = std::floor(s / opt_.sign_spacing_m);
        const uint32_t hs =
            hash2(static_cast<int32_t>(cell), static_cast<int32_t>(side), seed_ + kSign);
        if (unit(hs) < 0.5) {
            const double c = (cell + 0.2 + 0.6 * unit(mix32(hs))) * opt_.sign_spacing_m;
            const double w = 0.3 + 0.5 * unit(mix32(hs + 1));
            if (std::abs(s - c) < w) albedo = (z > 1.8 && z < 2.0) ? 0.3 : 2.5;
        }
    }
    return std::max(albedo, 0.02);
}

double TunnelWorld::floorAlbedo(double x, double y, double fp) const {
    const NoiseSample n = fbm(x, y, seed_ + kFloor + 3, 4, 1.0, 0.55, 2 * fp);
    return 0.22 + 0.25 * (n.v - 0.5);
}

double TunnelWorld::objectAlbedo(const Cylinder& c, const Vector3d& p) const {
    switch (c.kind) {
        case SurfaceKind::Duct: {
            // Flexible duct: bright fabric with a dark spiral wire every 0.35 m.
            const double along = (p - c.a).dot(c.axis);
            const double ph = along / 0.35 - std::floor(along / 0.35);
            return ph < 0.12 ? 0.15 : 0.42;
        }
        case SurfaceKind::Pipe:
            return 0.55;
        case SurfaceKind::Cable:
            return 0.1;
        default:
            return 0.5;
    }
}

bool TunnelWorld::solid(const Vector3d& p, WallQuery* q) const {
    *q = query(p.x(), p.y());
    const double dw = -q->sdf;
    const double floor = graded() ? level(p.x(), p.y()) : 0.0;
    return dw <= 0 || p.z() <= floor || p.z() >= roofHeight(p.x(), p.y(), dw);
}

SurfaceHit TunnelWorld::traceStatic(const Vector3d& o, const Vector3d& d, double t_min,
                                    double t_max, double rad_per_px) const {
    if (graded()) return traceGraded(o, d, t_min, t_max, rad_per_px);
    // Bound on the roof slope (arches and relief) except within a few cm of a wall.
    constexpr double kSlope = 3.0;
    const double dxy = std::hypot(d.x(), d.y());
    const double roof_rate = std::max(d.z(), 0.0) + kSlope * dxy;
    double t_end = t_max;
    if (d.z() < -1e-9) t_end = std::min(t_end, -o.z() / d.z());
    SurfaceHit hit;
    double t = t_min, prev = t_min;
    WallQuery q;
    bool inside_hit = false;
    for (int it = 0; it < 300; ++it) {
        const Vector3d p = o + t * d;
        q = query(p.x(), p.y());
        const double dw = -q.sdf;
        const double gap = dw > 0 ? roofHeight(p.x(), p.y(), dw) - p.z() : -1;
        if (dw <= 0 || gap <= 0 || p.z() <= 0) {
            inside_hit = true;
            break;
        }
        if (t >= t_end) break;
        // Largest step that cannot pass through a wall (sphere tracing in plan view) or the
        // roof (vertical clearance over the rate at which it can close), but at least a fraction
        // of the pixel footprint so grazing rays terminate.
        // Two safe plan-view clearances: the smooth wall minus the largest relief, and the
        // rough wall's distance over its Lipschitz bound (better within the relief band).
        const double clear =
            std::max(dw + q.relief - opt_.wall_roughness_m, dw / (1 + relief_lipschitz_));
        const double step_wall = dxy > 1e-9 ? clear / dxy : 1e9;
        const double step_roof = roof_rate > 1e-9 ? gap / roof_rate : 1e9;
        const double step = std::max({std::min(step_wall, step_roof), 0.004, 0.8 * t * rad_per_px});
        prev = t;
        t = std::min(t + step, t_end);
    }
    if (!inside_hit) {
        if (t >= t_end && t_end < t_max) {  // reached the floor plane
            hit.t = t_end;
            hit.kind = SurfaceKind::Floor;
            hit.q = query(o.x() + t_end * d.x(), o.y() + t_end * d.y());
        }
        return hit;
    }
    // Bisection between the last free and the first solid point.
    double lo = prev, hi = t;
    for (int k = 0; k < 12 && hi - lo > 1e-4; ++k) {
        const double mid = 0.5 * (lo + hi);
        WallQuery qm;
        if (solid(o + mid * d, &qm)) {
            hi = mid;
        } else {
            lo = mid;
        }
    }
    const Vector3d p = o + hi * d;
    hit.t = hi;
    hit.q = query(p.x(), p.y());
    if (p.z() <= 1e-3) {
        hit.kind = SurfaceKind::Floor;
    } else if (-hit.q.sdf <= 0.003 && p.z() < opt_.ceiling_height_m - opt_.arch_radius_m + 0.02) {
        hit.kind = SurfaceKind::Wall;
    } else {
        hit.kind = SurfaceKind::Roof;
    }
    return hit;
}

SurfaceHit TunnelWorld::traceGraded(const Vector3d& o, const Vector3d& d, double t_min,
                                    double t_max, double rad_per_px) const {
    // As traceStatic(), with a floor that is no longer the plane z = 0: its clearance closes
    // at most at the rate the ray descends plus the steepest grade times its plan speed.
    constexpr double kSlope = 3.0;
    const double dxy = std::hypot(d.x(), d.y());
    const double roof_rate = std::max(d.z(), 0.0) + (kSlope + max_grade_) * dxy;
    const double floor_rate = std::max(-d.z(), 0.0) + max_grade_ * dxy;
    SurfaceHit hit;
    double t = t_min, prev = t_min;
    bool inside_hit = false;
    for (int it = 0; it < 400; ++it) {
        const Vector3d p = o + t * d;
        const WallQuery q = query(p.x(), p.y());
        const double dw = -q.sdf;
        const double gap = dw > 0 ? roofHeight(p.x(), p.y(), dw) - p.z() : -1;
        const double floor_gap = p.z() - level(p.x(), p.y());
        if (dw <= 0 || gap <= 0 || floor_gap <= 0) {
            inside_hit = true;
            break;
        }
        if (t >= t_max) break;
        const double clear =
            std::max(dw + q.relief - opt_.wall_roughness_m, dw / (1 + relief_lipschitz_));
        const double step_wall = dxy > 1e-9 ? clear / dxy : 1e9;
        const double step_roof = roof_rate > 1e-9 ? gap / roof_rate : 1e9;
        const double step_floor = floor_rate > 1e-9 ? floor_gap / floor_rate : 1e9;
        const double step =
            std::max({std::min({step_wall, step_roof, step_floor}), 0.004, 0.8 * t * rad_per_px});
        prev = t;
        t = std::min(t + step, t_max);
    }
    if (!inside_hit) return hit;
    double lo = prev, hi = t;
    for (int k = 0; k < 14 && hi - lo > 1e-4; ++k) {
        const double mid = 0.5 * (lo + hi);
        WallQuery qm;
        (solid(o + mid * d, &qm) ? hi : lo) = mid;
    }
    const Vector3d p = o + hi * d;
    const double above_floor = p.z() - level(p.x(), p.y());
    hit.t = hi;
    hit.q = query(p.x(), p.y());
    if (above_floor <= 1e-3) {
        hit.kind = SurfaceKind::Floor;
    } else if (-hit.q.sdf <= 0.003 &&
               above_floor < opt_.ceiling_height_m - opt_.arch_radius_m + 0.02) {
        hit.kind = SurfaceKind::Wall;
    } else {
        hit.kind = SurfaceKind::Roof;
    }
    return hit;
}

void TunnelWorld::fillGridMap(mrpt::maps::COccupancyGridMap2D& grid) const {
    const double res = opt_.grid_resolution_m;
    grid.setSize(static_cast<float>(lo_.x() - 2), static_cast<float>(hi_.x() + 2),
                 static_cast<float>(lo_.y() - 2), static_cast<float>(hi_.y() + 2),
                 static_cast<float>(res), 0.0f);
    for (unsigned cy = 0; cy < grid.getSizeY(); ++cy) {
        const double y = grid.idx2y(cy);
        for (unsigned cx = 0; cx < grid.getSizeX(); ++cx) {
            if (query(grid.idx2x(cx), y).sdf < 0) grid.setCell(cx, cy, 1.0f);
        }
    }
}

}  // namespace lookup::sim

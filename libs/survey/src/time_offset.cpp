#include "lookup/survey/time_offset.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>
#include <map>
#include <optional>
#include <stdexcept>

#include <Eigen/Core>
#include <opencv2/calib3d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>

#include "lookup/common/grey.h"
#include "lookup/common/pose_files.h"
#include "lookup/refine/geometry.h"
#include "lookup/survey/pose_audit.h"

namespace lookup::survey {
namespace {

using Motion = cv::Vec3d;  ///< vehicle motion between two times in the first one's frame: x, y, yaw

constexpr double kMaxPairGap_s = 3.0;   // a longer pair spans a stop: nothing to measure
constexpr double kYawWeight_m = 1.0;    // metres of residual per radian of heading residual
constexpr std::size_t kMinPoints = 25;  // tracked ceiling points for a measured pair

struct Pair {
    const CeilingTraverse* traverse = nullptr;
    std::size_t i = 0, j = 0;  ///< image indices
    double ti = 0, tj = 0;     ///< stamps [s]
    double info = 0;           ///< how much the track's motion changes with dt
    Motion measured;
};

Motion motionOf(const mrpt::poses::CPose3D& a_to_b) {
    return {a_to_b.x(), a_to_b.y(), a_to_b.yaw()};
}

// The track's vehicle motion from ti + dt to tj + dt.
std::optional<Motion> trackMotion(const Pair& p, double dt) {
    const auto a = common::poseAt(*p.traverse->poses, p.ti + dt);
    const auto b = common::poseAt(*p.traverse->poses, p.tj + dt);
    if (!a || !b) return std::nullopt;
    return motionOf(*b - *a);
}

double stampOf(const mrpt::obs::CObservationImage& obs) {
    return mrpt::Clock::toDouble(obs.timestamp);
}

// Pairs of images a baseline of travel apart whose track motion exists over the search range.
std::vector<Pair> candidatePairs(const CeilingTraverse& t, const SurveyOptions& o) {
    const auto& images = *t.ceiling;
    std::vector<std::size_t> index;
    std::vector<double> travel;
    for (std::size_t k = 0; k < images.size(); ++k) {
        const double s = stampOf(*images[k]);
        const auto p = common::poseAt(*t.poses, s);
        if (!p || !common::poseAt(*t.poses, s - o.time_offset_max_s) ||
            !common::poseAt(*t.poses, s + o.time_offset_max_s)) {
            continue;
        }
        double d = 0;
        if (!index.empty()) {
            const auto q = *common::poseAt(*t.poses, stampOf(*images[index.back()]));
            d = travel.back() + std::hypot(p->x() - q.x(), p->y() - q.y());
        }
        index.push_back(k);
        travel.push_back(d);
    }
    std::vector<Pair> out;
    std::size_t b = 0;
    for (std::size_t a = 0; a < index.size(); ++a) {
        b = std::max(b, a + 1);
        while (b < index.size() && travel[b] < travel[a] + o.time_offset_baseline_m) ++b;
        if (b == index.size()) break;
        Pair p;
        p.traverse = &t;
        p.i = index[a];
        p.j = index[b];
        p.ti = stampOf(*images[p.i]);
        p.tj = stampOf(*images[p.j]);
        if (p.tj - p.ti > kMaxPairGap_s) continue;
        const auto plus = trackMotion(p, 0.005), minus = trackMotion(p, -0.005);
        if (!plus || !minus) continue;
        p.info = cv::norm(*plus - *minus);
        out.push_back(p);
    }
    return out;
}

// The most informative half of `max` first, the rest spread evenly over the others.
std::vector<Pair> selectPairs(std::vector<Pair> all, std::size_t max) {
    if (all.size() <= max) return all;
    std::vector<std::size_t> order(all.size());
    for (std::size_t k = 0; k < order.size(); ++k) order[k] = k;
    std::sort(order.begin(), order.end(),
              [&](std::size_t a, std::size_t b) { return all[a].info > all[b].info; });
    std::vector<Pair> out;
    const std::size_t top = max / 2;
    for (std::size_t k = 0; k < top; ++k) out.push_back(all[order[k]]);
    const std::size_t rest = all.size() - top, want = max - top;
    for (std::size_t k = 0; k < want; ++k) out.push_back(all[order[top + k * rest / want]]);
    return out;
}

cv::Mat loadGrey(const mrpt::obs::CObservationImage& obs) {
    cv::Mat m;
    if (obs.image.isExternallyStored()) {
        m = cv::imread(obs.image.getExternalStorageFileAbsolutePath(), cv::IMREAD_GRAYSCALE);
        obs.image.unload();
        return m;
    }
    obs.image.asCvMat(m, mrpt::img::DEEP_COPY);
    try {
        m = common::greyOf(m);
    } catch (const std::invalid_argument&) {
        return cv::Mat();  // a layout greyOf refuses is skipped here; the database writer names it
    }
    return m.depth() == CV_8U ? m : cv::Mat();
}

// Pixels to the pinhole part of the camera (lens distortion removed).
std::vector<cv::Point2f> rectified(const std::vector<cv::Point2f>& px,
                                   const mrpt::img::TCamera& cam) {
    const auto out = refine::undistortPixels(px, cam);
    return {out.begin(), out.end()};
}

// Ceiling points of image a tracked into image b (forward-backward checked), `guess` the
// expected vehicle motion a -> b.
bool trackPoints(const cv::Mat& a, const cv::Mat& b, const refine::Pinhole& pin,
                 const mrpt::poses::CPose3D& mount, double h, const mrpt::poses::CPose3D& guess,
                 std::vector<cv::Point2f>& pa, std::vector<cv::Point2f>& pb) {
    std::vector<cv::Point2f> corners;
    cv::goodFeaturesToTrack(a, corners, 300, 0.01, 8);
    if (corners.size() < kMinPoints) return false;
    const mrpt::poses::CPose3D b_cam = guess + mount;
    std::vector<cv::Point2f> next;
    for (const auto& c : corners) {
        const auto p = refine::backProjectToCeiling(pin, mount, cv::Point2d(c.x, c.y), h);
        const auto q = p ? refine::projectToImage(pin, b_cam, *p) : std::nullopt;
        next.push_back(q ? cv::Point2f(float(q->x), float(q->y)) : c);
    }
    std::vector<uchar> ok, back_ok;
    std::vector<float> err;
    const cv::TermCriteria stop(cv::TermCriteria::COUNT | cv::TermCriteria::EPS, 30, 0.01);
    cv::calcOpticalFlowPyrLK(a, b, corners, next, ok, err, cv::Size(21, 21), 3, stop,
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    std::vector<cv::Point2f> back = corners;
    cv::calcOpticalFlowPyrLK(b, a, next, back, back_ok, err, cv::Size(21, 21), 3, stop,
                             cv::OPTFLOW_USE_INITIAL_FLOW);
    pa.clear();
    pb.clear();
    for (std::size_t k = 0; k < corners.size(); ++k) {
        if (ok[k] && back_ok[k] && cv::norm(back[k] - corners[k]) < 0.5) {
            pa.push_back(corners[k]);
            pb.push_back(next[k]);
        }
    }
    return pa.size() >= kMinPoints;
}

// The vehicle motion a -> b from the images: the tracked points of each image back-projected
// onto the ceiling plane in its own vehicle frame, and the planar motion that maps b's onto a's
// fitted robustly. A homography decomposed into camera motion and plane normal would tell
// pitching from travel on a flat ceiling, but on an arched, rough one it confuses the two and
// is several times noisier; here the pitch and roll changes between the two images (distance
// x angle on the ceiling) remain as the measurement's noise.
std::optional<Motion> imageMotion(const mrpt::obs::CObservationImage& ia,
                                  const mrpt::obs::CObservationImage& ib, double h,
                                  const mrpt::poses::CPose3D& guess) {
    refine::Pinhole pin;
    if (!refine::pinholeFrom(ia.cameraParams, pin, nullptr)) return std::nullopt;
    const cv::Mat a = loadGrey(ia), b = loadGrey(ib);
    if (a.empty() || b.empty() || a.size() != b.size()) return std::nullopt;
    const auto& mount = ia.cameraPose;
    const double distance_m = h - mount.z();
    if (!(distance_m > 0)) return std::nullopt;
    std::vector<cv::Point2f> pa, pb;
    if (!trackPoints(a, b, pin, mount, h, guess, pa, pb)) return std::nullopt;
    pa = rectified(pa, ia.cameraParams);
    pb = rectified(pb, ia.cameraParams);
    std::vector<cv::Point2f> on_a, on_b;
    for (std::size_t k = 0; k < pa.size(); ++k) {
        const auto qa = refine::backProjectToCeiling(pin, mount, cv::Point2d(pa[k]), h);
        const auto qb = refine::backProjectToCeiling(pin, mount, cv::Point2d(pb[k]), h);
        if (!qa || !qb) continue;
        on_a.emplace_back(float(qa->x), float(qa->y));
        on_b.emplace_back(float(qb->x), float(qb->y));
    }
    if (on_a.size() < kMinPoints) return std::nullopt;
    // Rotation, translation and a scale (the height change); inliers within the size of a
    // pixel at the ceiling straight above the camera.
    const double pixel_m = distance_m / pin.fx;
    std::vector<uchar> inlier;
    const cv::Mat M = cv::estimateAffinePartial2D(on_b, on_a, inlier, cv::RANSAC, pixel_m);
    if (M.empty() || std::size_t(cv::countNonZero(inlier)) < kMinPoints) return std::nullopt;
    return Motion(M.at<double>(0, 2), M.at<double>(1, 2),
                  std::atan2(M.at<double>(1, 0), M.at<double>(0, 0)));
}

struct FitAt {
    double cost = 0;
    double scale = 1;
    std::vector<double> norms;     ///< residual norm per pair [m]
    std::vector<double> residual;  ///< 3 per used pair
};

// Residuals at dt: image motion x scale - track motion (scale by least squares over the used
// pairs' translations), each squared norm clipped at clip^2 in the cost.
FitAt evaluate(const std::vector<Pair>& pairs, const std::vector<char>& use, double dt,
               double clip_m) {
    FitAt f;
    std::vector<std::optional<Motion>> track(pairs.size());
    double mp = 0, mm = 0;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
        track[k] = trackMotion(pairs[k], dt);
        if (!use[k] || !track[k]) continue;
        const Motion& m = pairs[k].measured;
        mp += m[0] * (*track[k])[0] + m[1] * (*track[k])[1];
        mm += m[0] * m[0] + m[1] * m[1];
    }
    f.scale = mm > 0 ? mp / mm : 1.0;
    for (std::size_t k = 0; k < pairs.size(); ++k) {
        const Motion& m = pairs[k].measured;
        cv::Vec3d r(clip_m, 0, 0);
        if (track[k]) {
            r = cv::Vec3d(f.scale * m[0] - (*track[k])[0], f.scale * m[1] - (*track[k])[1],
                          kYawWeight_m * mrpt::math::wrapToPi(m[2] - (*track[k])[2]));
        }
        const double n = cv::norm(r);
        f.norms.push_back(n);
        if (!use[k]) continue;
        f.cost += std::min(n * n, clip_m * clip_m);
        for (int c = 0; c < 3; ++c) f.residual.push_back(r[c]);
    }
    return f;
}

double median(std::vector<double> v) {
    if (v.empty()) return 0;
    std::nth_element(v.begin(), v.begin() + v.size() / 2, v.end());
    return v[v.size() / 2];
}

// The dt of least cost on a grid of `step` over [from, to], refined by a parabola.
double gridMinimum(const std::vector<Pair>& pairs, const std::vector<char>& use, double from,
                   double to, double step, double clip_m) {
    std::vector<double> dts, costs;
    for (double dt = from; dt <= to + 1e-12; dt += step) {
        dts.push_back(dt);
        costs.push_back(evaluate(pairs, use, dt, clip_m).cost);
    }
    const std::size_t k = std::min_element(costs.begin(), costs.end()) - costs.begin();
    if (k == 0 || k + 1 == costs.size()) return dts[k];
    const double c0 = costs[k - 1], c1 = costs[k], c2 = costs[k + 1];
    const double den = c0 - 2 * c1 + c2;
    return den > 0 ? dts[k] + 0.5 * step * (c0 - c2) / den : dts[k];
}

struct FitResult {
    double dt = 0, sigma = 0, scale = 1, rms = 0;
    std::size_t used = 0;
};

// Robust dt: a clipped-cost grid over the whole range, then the pairs within 3 robust
// deviations refitted by least squares (twice); sigma from the residuals' slope in dt.
FitResult fitOffset(const std::vector<Pair>& pairs, const SurveyOptions& o) {
    std::vector<char> use(pairs.size(), 1);
    const double range = o.time_offset_max_s;
    double dt = gridMinimum(pairs, use, -range, range, 0.002, 0.05);
    for (int pass = 0; pass < 2; ++pass) {
        const FitAt at = evaluate(pairs, std::vector<char>(pairs.size(), 1), dt, 1e9);
        const double gate = std::max(0.005, 3 * 1.4826 * median(at.norms));
        for (std::size_t k = 0; k < pairs.size(); ++k) use[k] = at.norms[k] <= gate;
        dt = gridMinimum(pairs, use, dt - 0.006, dt + 0.006, 0.0005, 1e9);
    }
    FitResult r;
    r.dt = dt;
    const FitAt at = evaluate(pairs, use, dt, 1e9);
    const FitAt plus = evaluate(pairs, use, dt + 0.001, 1e9);
    const FitAt minus = evaluate(pairs, use, dt - 0.001, 1e9);
    r.used = at.residual.size() / 3;
    r.scale = at.scale;
    double ss = 0, jj = 0;
    for (std::size_t k = 0; k < at.residual.size(); ++k) {
        ss += at.residual[k] * at.residual[k];
        const double j = (plus.residual[k] - minus.residual[k]) / 0.002;
        jj += j * j;
    }
    const double dof = std::max(1.0, double(at.residual.size()) - 2.0);
    r.rms = std::sqrt(ss / std::max<std::size_t>(1, r.used));
    // Pairs overlapping in time share track noise: inflate by how many overlap on average.
    double span = 0;
    for (std::size_t k = 0; k < pairs.size(); ++k)
        span += use[k] ? double(pairs[k].j - pairs[k].i) : 0;
    const double overlap = r.used ? std::max(1.0, span / r.used) : 1.0;
    r.sigma = jj > 0 ? std::sqrt(ss / dof / jj * overlap) : std::numeric_limits<double>::infinity();
    return r;
}

// The pairs split into groups that share no structure error: per traverse, its first and
// second half in time (a start and a stop each show the offset on their own).
std::vector<std::vector<Pair>> independentGroups(const std::vector<Pair>& pairs) {
    std::map<const CeilingTraverse*, std::vector<const Pair*>> by_traverse;
    for (const auto& p : pairs) by_traverse[p.traverse].push_back(&p);
    std::vector<std::vector<Pair>> groups;
    for (auto& [t, list] : by_traverse) {
        std::sort(list.begin(), list.end(), [](auto a, auto b) { return a->ti < b->ti; });
        const double mid = 0.5 * (list.front()->ti + list.back()->ti);
        std::vector<Pair> first, second;
        for (const Pair* p : list) (p->ti < mid ? first : second).push_back(*p);
        groups.push_back(std::move(first));
        groups.push_back(std::move(second));
    }
    return groups;
}

// The fit's sigma widened by the Birge ratio of the groups' own fits: residuals of the image
// motion that follow the place (ceiling relief, walls in view) are not independent per pair,
// and only fits of separate stretches show how far they move the offset.
double consistentSigma(const std::vector<Pair>& pairs, const FitResult& all,
                       const SurveyOptions& o) {
    double chi2 = 0;
    int k = 0;
    for (const auto& g : independentGroups(pairs)) {
        if (g.size() < std::size_t(std::max(5, o.time_offset_min_pairs / 4))) continue;
        const FitResult f = fitOffset(g, o);
        if (!std::isfinite(f.sigma) || f.sigma <= 0) continue;
        chi2 += std::pow((f.dt - all.dt) / f.sigma, 2);
        ++k;
    }
    if (k < 2) return all.sigma;
    return all.sigma * std::max(1.0, std::sqrt(chi2 / (k - 1)));
}

std::string notEstimated(const TimeOffsetEstimate& e, const std::string& why) {
    char buf[160];
    std::snprintf(buf, sizeof(buf),
                  "; the configured [survey] ceiling_time_offset_s = %.4f s is used",
                  e.configured_s);
    return e.label + " time offset not estimated: " + why + buf;
}

// A fit not trusted as the offset still bounds the configured one: that is off the fit by
// the distance between them, give or take twice the fit's deviation. Once is too tight where
// the traverses start and stop over the same floor: its bumps pitch every one of them alike
// there, an error the per-traverse consistency check cannot see.
double boundFromFit(const TimeOffsetEstimate& e) {
    constexpr double kBoundSigmas = 2.0;
    return std::hypot(e.fitted_s - e.configured_s, kBoundSigmas * e.sigma_s);
}

// Whether a fit not trusted as the offset still contradicts the configured one: farther from
// it than the fit's bias on a relief-rich ceiling and than the two deviations allow.
bool contradicts(const TimeOffsetEstimate& e, const SurveyOptions& o) {
    constexpr double kSigmas = 3.0;
    if (e.pairs_used == 0 || !std::isfinite(e.sigma_s)) return false;
    const double apart = std::abs(e.fitted_s - e.configured_s);
    return apart > o.time_offset_contradiction_s &&
           apart > kSigmas * std::hypot(e.sigma_s, o.ceiling_time_offset_sigma_s);
}

// The fit's deviation once estimated; else the configured one's, tightened to what the fit
// allows of it, or widened to it where the fit contradicts the configured offset.
double appliedSigma(const TimeOffsetEstimate& e, const SurveyOptions& o) {
    if (e.source == "estimated") return e.sigma_s;
    if (e.pairs_used == 0 || !std::isfinite(e.sigma_s)) return o.ceiling_time_offset_sigma_s;
    if (e.contradicted) return boundFromFit(e);
    return std::min(o.ceiling_time_offset_sigma_s, boundFromFit(e));
}

// The image motion of a pair is that of the rows' mean exposure, the middle row's; with a
// rolling shutter the stamp refers to ceiling_stamp_row, this much earlier [s].
double middleRowLag(const SurveyOptions& o) {
    return o.ceiling_stamp_row == common::StampRow::First ? 0.5e-3 * o.ceiling_readout_ms : 0.0;
}

// The fit becomes the offset unless `refusal` says why not (then the configured one stays).
void decide(TimeOffsetEstimate& e, const std::string& refusal, const SurveyOptions& o) {
    if (refusal.empty()) {
        e.source = "estimated";
        e.offset_s = e.fitted_s;
    } else {
        e.warning = notEstimated(e, refusal);
    }
    e.contradicted = e.source != "estimated" && contradicts(e, o);
    e.applied_sigma_s = appliedSigma(e, o);
    if (e.contradicted) {
        char buf[200];
        std::snprintf(buf, sizeof(buf),
                      "; the fit contradicts it (more than time_offset_contradiction_s = %.3f s "
                      "and 3 sigmas away): its sigma widened to %.4f s",
                      o.time_offset_contradiction_s, e.applied_sigma_s);
        e.warning += buf;
    }
}

}  // namespace

TimeOffsetEstimate estimateTimeOffset(const std::vector<CeilingTraverse>& traverses,
                                      double ceiling_height_m, const SurveyOptions& o) {
    const auto started = std::chrono::steady_clock::now();
    TimeOffsetEstimate e;
    e.label = o.ceiling_camera_label;
    e.source = "configured";
    e.configured_s = e.offset_s = o.ceiling_time_offset_s;
    e.applied_sigma_s = o.ceiling_time_offset_sigma_s;
    e.tried = true;
    std::vector<Pair> all;
    for (const auto& t : traverses) {
        auto p = candidatePairs(t, o);
        all.insert(all.end(), p.begin(), p.end());
    }
    std::vector<Pair> pairs;
    for (auto& p : selectPairs(std::move(all), std::size_t(o.time_offset_max_pairs))) {
        ++e.pairs_tried;
        const auto& images = *p.traverse->ceiling;
        const auto a = common::poseAt(*p.traverse->poses, p.ti),
                   b = common::poseAt(*p.traverse->poses, p.tj);
        if (!a || !b) continue;
        std::optional<Motion> m;
        try {
            m = imageMotion(*images[p.i], *images[p.j], ceiling_height_m, *b - *a);
        } catch (const std::exception&) {
            m.reset();  // an unreadable image: the pair is not measured
        }
        if (!m) continue;
        p.measured = *m;
        pairs.push_back(p);
    }
    e.pairs_measured = pairs.size();
    const auto finish = [&] {
        e.time_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        return e;
    };
    if (pairs.size() < std::size_t(o.time_offset_min_pairs)) {
        e.warning =
            notEstimated(e, std::to_string(pairs.size()) + " of " + std::to_string(e.pairs_tried) +
                                " image pairs had enough tracked ceiling texture "
                                "(time_offset_min_pairs = " +
                                std::to_string(o.time_offset_min_pairs) + ")");
        return finish();
    }
    FitResult fit = fitOffset(pairs, o);
    fit.sigma = consistentSigma(pairs, fit, o);
    e.fitted_s = e.configured_s + fit.dt - middleRowLag(o);
    e.sigma_s = fit.sigma;
    e.scale = fit.scale;
    e.rms_m = fit.rms;
    e.pairs_used = fit.used;
    char buf[320] = "";
    if (!(fit.sigma <= o.time_offset_max_sigma_s)) {
        std::snprintf(buf, sizeof(buf),
                      "the image motion does not pin it down (too little acceleration or "
                      "turning for its noise, rms %.3f m): fit %.4f s +- %.4f s over %zu pairs, "
                      "more uncertain than time_offset_max_sigma_s = %.4f s",
                      fit.rms, e.fitted_s, fit.sigma, fit.used, o.time_offset_max_sigma_s);
    } else if (std::abs(fit.dt) > o.time_offset_max_s - 0.01) {
        std::snprintf(buf, sizeof(buf),
                      "fit %.4f s at the edge of the search range (time_offset_max_s = %.3f s)",
                      e.fitted_s, o.time_offset_max_s);
    }
    decide(e, buf, o);
    return finish();
}

namespace {

// A fix of the audit with the two traverses' velocities (map frame) at its images' times.
struct CrossFix {
    Eigen::Vector2d dv;  ///< other traverse's velocity - the frame's own [m/s]
    Eigen::Vector2d r;   ///< fix - laser pose [m]
    std::string group;   ///< the traverse pair
};

std::optional<Eigen::Vector2d> velocityAt(const mrpt::poses::CPose3DInterpolator& track, double t) {
    constexpr double kSpan_s = 0.05;
    const auto a = common::poseAt(track, t - kSpan_s), b = common::poseAt(track, t + kSpan_s);
    if (!a || !b) return std::nullopt;
    return Eigen::Vector2d(b->x() - a->x(), b->y() - a->y()) / (2 * kSpan_s);
}

struct CrossFit {
    double late_s = 0;  ///< the stamps' lateness the fixes show [s]
    double sigma_s = std::numeric_limits<double>::infinity();
    double rms_m = 0;
    std::size_t used = 0;
};

// r = dv * late, least squares; once more without the fixes beyond 3 robust deviations (a
// stretch whose poses are wrong, not late).
CrossFit fitLateness(const std::vector<CrossFix>& fixes) {
    CrossFit f;
    const auto solve = [&](const std::vector<bool>& use) {
        double num = 0, den = 0;
        for (std::size_t i = 0; i < fixes.size(); ++i) {
            if (!use[i]) continue;
            num += fixes[i].dv.dot(fixes[i].r);
            den += fixes[i].dv.squaredNorm();
        }
        return std::make_pair(den > 0 ? num / den : 0.0, den);
    };
    std::vector<bool> use(fixes.size(), true);
    auto [late, den] = solve(use);
    std::vector<double> dev;
    for (const auto& x : fixes) dev.push_back((x.r - x.dv * late).norm());
    std::vector<double> sorted = dev;
    std::sort(sorted.begin(), sorted.end());
    const double gate = sorted.empty() ? 0 : std::max(0.1, 3 * 1.4826 * sorted[sorted.size() / 2]);
    for (std::size_t i = 0; i < fixes.size(); ++i) use[i] = dev[i] <= gate;
    std::tie(late, den) = solve(use);
    double ss = 0;
    for (std::size_t i = 0; i < fixes.size(); ++i) {
        if (!use[i]) continue;
        ss += (fixes[i].r - fixes[i].dv * late).squaredNorm();
        ++f.used;
    }
    if (f.used < 2 || !(den > 0)) return f;
    f.late_s = late;
    f.rms_m = std::sqrt(ss / double(2 * f.used - 1));
    f.sigma_s = f.rms_m / std::sqrt(den);
    return f;
}

// Widened by the Birge ratio of each traverse pair's own fit, as for the image motion.
double consistentCrossSigma(const std::vector<CrossFix>& fixes, const CrossFit& all) {
    std::map<std::string, std::vector<CrossFix>> groups;
    for (const auto& x : fixes) groups[x.group].push_back(x);
    double chi2 = 0;
    int k = 0;
    for (const auto& [name, g] : groups) {
        const CrossFit f = fitLateness(g);
        if (!std::isfinite(f.sigma_s) || f.sigma_s <= 0) continue;
        chi2 += std::pow((f.late_s - all.late_s) / f.sigma_s, 2);
        ++k;
    }
    if (k < 2) return all.sigma_s;
    return all.sigma_s * std::max(1.0, std::sqrt(chi2 / (k - 1)));
}

}  // namespace

TimeOffsetEstimate estimateTimeOffsetAcrossTraverses(const PoseAudit& audit,
                                                     const std::vector<CeilingTraverse>& traverses,
                                                     double applied_s, const SurveyOptions& o) {
    const auto started = std::chrono::steady_clock::now();
    TimeOffsetEstimate e;
    e.label = o.ceiling_camera_label;
    e.method = "across traverses";
    e.source = "configured";
    e.configured_s = o.ceiling_time_offset_s;
    e.offset_s = applied_s;
    e.applied_sigma_s = o.ceiling_time_offset_sigma_s;
    e.tried = true;
    std::map<std::string, const mrpt::poses::CPose3DInterpolator*> tracks;
    for (const auto& t : traverses) tracks[t.name] = t.poses;
    std::vector<CrossFix> fixes;
    for (const auto& f : audit.fixes) {
        ++e.pairs_tried;
        const auto own = tracks.find(f.traverse), other = tracks.find(f.other);
        if (own == tracks.end() || other == tracks.end()) continue;
        const auto v = velocityAt(*own->second, f.time_s);
        const auto w = velocityAt(*other->second, f.other_time_s);
        if (!v || !w) continue;
        ++e.pairs_measured;
        // Where the velocities differ little, the laser poses' own relative error of a few
        // centimetres would pass for lateness: only velocities that differ clearly count.
        if ((*w - *v).norm() < o.time_offset_min_velocity_difference_mps) continue;
        fixes.push_back({*w - *v, {f.dx_m, f.dy_m}, f.traverse + "|" + f.other});
    }
    const auto finish = [&] {
        e.time_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        return e;
    };
    if (fixes.size() < std::size_t(o.time_offset_min_pairs)) {
        char why[240];
        std::snprintf(why, sizeof(why),
                      "%zu fixes across traverses whose velocities differ by %.1f m/s or more "
                      "(time_offset_min_velocity_difference_mps), fewer than "
                      "time_offset_min_pairs = %d",
                      fixes.size(), o.time_offset_min_velocity_difference_mps,
                      o.time_offset_min_pairs);
        e.warning = notEstimated(e, why);
        return finish();
    }
    const CrossFit fit = fitLateness(fixes);
    e.fitted_s = applied_s - fit.late_s - middleRowLag(o);
    e.sigma_s = consistentCrossSigma(fixes, fit);
    e.rms_m = fit.rms_m;
    e.pairs_used = fit.used;
    char buf[320] = "";
    if (!(e.sigma_s <= o.time_offset_max_sigma_s)) {
        std::snprintf(
            buf, sizeof(buf),
            "the fixes across traverses scatter too much for their velocity "
            "differences (rms %.3f m): fit %.4f s +- %.4f s over %zu fixes across traverses, more "
            "uncertain than time_offset_max_sigma_s = %.4f s",
            fit.rms_m, e.fitted_s, e.sigma_s, fit.used, o.time_offset_max_sigma_s);
    } else if (std::abs(e.fitted_s - e.configured_s) > o.time_offset_max_s) {
        std::snprintf(buf, sizeof(buf),
                      "fit %.4f s beyond the search range (time_offset_max_s = %.3f s)", e.fitted_s,
                      o.time_offset_max_s);
    }
    decide(e, buf, o);
    return finish();
}

void shiftStamps(std::vector<mrpt::obs::CObservationImage::Ptr>& images, double offset_s) {
    if (offset_s == 0) return;
    for (auto& im : images) {
        im->timestamp = mrpt::Clock::fromDouble(mrpt::Clock::toDouble(im->timestamp) + offset_s);
    }
}

nlohmann::ordered_json timeOffsetJson(const TimeOffsetEstimate& e) {
    // The fit's figures are null when nothing was fitted (or they are not finite).
    const bool fitted = e.pairs_used > 0;
    const auto fit = [&](double v) {
        return fitted && std::isfinite(v) ? nlohmann::ordered_json(v) : nlohmann::ordered_json();
    };
    return {{"label", e.label},
            {"source", e.source},
            {"method", e.method},
            {"offset_s", e.offset_s},
            {"configured_s", e.configured_s},
            {"estimated", e.source == "estimated"},
            {"fitted_s", fit(e.fitted_s)},
            {"sigma_s", fit(e.sigma_s)},
            {"applied_sigma_s", e.applied_sigma_s},
            {"contradicted", e.contradicted},
            {"scale", fit(e.scale)},
            {"rms_m", fit(e.rms_m)},
            {"pairs_tried", e.pairs_tried},
            {"pairs_measured", e.pairs_measured},
            {"pairs_used", e.pairs_used},
            {"time_s", e.time_s},
            {"warning", e.warning}};
}

}  // namespace lookup::survey

#include "lookup/survey/ceiling_distance.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <optional>

#include "ceiling_frames.h"
#include "lookup/common/camera_params.h"
#include "lookup/refine/refiner.h"

namespace lookup::survey {
namespace {

using Frame = detail::PosedCeilingFrame;
using detail::nearestTravel;

// h from frame j refined against the frames `baseline_m` behind and ahead (nullopt when the
// neighbours are missing or the refiner refuses the triple).
std::optional<double> estimateAt(const refine::Refiner& refiner, const refine::Rectifier* rectifier,
                                 const CeilingTraverse& t, const std::vector<Frame>& f,
                                 std::size_t j, double baseline_m, double prior_m) {
    const std::size_t a = nearestTravel(f, f[j].travel_m - baseline_m);
    const std::size_t b = nearestTravel(f, f[j].travel_m + baseline_m);
    const auto near = [&](std::size_t k) {
        return std::abs(std::abs(f[k].travel_m - f[j].travel_m) - baseline_m) < 0.3 * baseline_m;
    };
    if (!near(a) || !near(b)) return std::nullopt;
    const auto& images = *t.ceiling;
    std::optional<double> h;
    try {
        std::vector<refine::ReferenceImage> refs;
        // Measured on rectified images, as the localiser matches (pinhole geometry).
        const auto rectified = [&](std::size_t k) {
            const auto& obs = *images[f[k].index];
            return rectifier ? rectifier->rectify(obs) : obs;
        };
        refs.push_back(refine::ReferenceImage::fromObservation(0, rectified(a), f[a].pose));
        refs.push_back(refine::ReferenceImage::fromObservation(1, rectified(b), f[b].pose));
        refine::CoarseHint hint;
        hint.vehicle_pose = f[j].pose;
        hint.ceiling_height_m = prior_m;
        const auto r = refiner.refine(rectified(j), hint, refs);
        if (r.accepted() && r.estimate.ok && std::isfinite(r.estimate.ceiling_height_m)) {
            h = r.estimate.ceiling_height_m;
        }
    } catch (const std::exception&) {
        // An unreadable image: this triple is rejected.
    }
    // External images are loaded on access; the survey keeps only headers in memory.
    for (std::size_t k : {a, j, b}) images[f[k].index]->image.unload();
    return h;
}

double median(std::vector<double> v) {
    std::sort(v.begin(), v.end());
    const std::size_t n = v.size();
    return n % 2 ? v[n / 2] : 0.5 * (v[n / 2 - 1] + v[n / 2]);
}

// One pass over every traverse at one baseline: the accepted values, with counts in `out`.
std::vector<double> onePass(const std::vector<CeilingTraverse>& traverses, const SurveyOptions& o,
                            const refine::Rectifier* rectifier, double baseline_m, double prior_m,
                            CeilingDistanceEstimate& out) {
    refine::RefinerOptions ro;
    ro.estimator.ceiling_height_m = prior_m;
    ro.estimator.ceiling_height_sigma_m = o.ceiling_prior_sigma_m;
    const refine::Refiner refiner(ro);
    std::vector<double> hs;
    out.tried = out.rejected = 0;
    for (const auto& t : traverses) {
        const auto f = detail::posedCeilingFrames(t);
        if (f.size() < 3) continue;
        for (double s = baseline_m; s <= f.back().travel_m - baseline_m;
             s += o.ceiling_sample_spacing_m) {
            const std::size_t j = nearestTravel(f, s);
            ++out.tried;
            if (auto h = estimateAt(refiner, rectifier, t, f, j, baseline_m, prior_m)) {
                hs.push_back(*h);
            } else {
                ++out.rejected;
            }
        }
    }
    return hs;
}

// Median and spread of `hs`, outliers (beyond 3 spreads, at least 0.1 m) dropped.
void summarise(std::vector<double> hs, CeilingDistanceEstimate& out) {
    const double m0 = median(hs);
    std::vector<double> dev;
    for (double h : hs) dev.push_back(std::abs(h - m0));
    const double gate = std::max(0.1, 3.0 * 1.4826 * median(dev));
    std::vector<double> kept;
    for (double h : hs) {
        if (std::abs(h - m0) <= gate) kept.push_back(h);
    }
    out.rejected += hs.size() - kept.size();
    out.used = kept.size();
    out.ceiling_height_m = median(kept);
    dev.clear();
    for (double h : kept) dev.push_back(std::abs(h - out.ceiling_height_m));
    out.spread_m = 1.4826 * median(dev);
}

// Two passes from the prior h: a short baseline first (the matcher searches around where the
// prior predicts each point, and a wrong h shifts that prediction in proportion to the
// baseline), its median the prior of the full-baseline pass; the last pass that accepted
// enough triples, if any.
std::optional<CeilingDistanceEstimate> passesFrom(double prior,
                                                  const std::vector<CeilingTraverse>& traverses,
                                                  const SurveyOptions& o,
                                                  const std::optional<refine::Rectifier>& rectifier,
                                                  const CeilingDistanceEstimate& start) {
    std::optional<CeilingDistanceEstimate> found;
    for (double baseline : {0.5 * o.ceiling_baseline_m, o.ceiling_baseline_m}) {
        CeilingDistanceEstimate pass = start;
        const auto hs =
            onePass(traverses, o, rectifier ? &*rectifier : nullptr, baseline, prior, pass);
        if (hs.size() < std::size_t(o.ceiling_min_pairs)) continue;
        summarise(hs, pass);
        if (pass.used < std::size_t(o.ceiling_min_pairs)) continue;
        pass.estimated = true;
        prior = pass.ceiling_height_m;
        found = pass;
    }
    return found;
}

}  // namespace

CeilingDistanceEstimate estimateCeilingDistance(const std::vector<CeilingTraverse>& traverses,
                                                const SurveyOptions& o) {
    const auto started = std::chrono::steady_clock::now();
    CeilingDistanceEstimate out;
    out.prior_m = o.ceiling_height_m;
    for (const auto& t : traverses) {
        if (!t.ceiling->empty()) {
            out.camera_z_m = t.ceiling->front()->cameraPose.z();
            break;
        }
    }
    // Measured as the localiser will match: rectified, at the stored width.
    const std::optional<refine::Rectifier> rectifier = detail::storedCameraRectifier(traverses, o);
    const auto finish = [&] {
        out.camera_to_ceiling_m = out.ceiling_height_m - out.camera_z_m;
        out.time_s =
            std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
        return out;
    };
    // Far off, the prior predicts every point beyond the matcher's search window (a camera half
    // as far from the ceiling as configured): other camera distances are tried, nearest the
    // configured one first, until one gives enough triples.
    auto found = passesFrom(o.ceiling_height_m, traverses, o, rectifier, out);
    const double configured_m = o.ceiling_height_m - out.camera_z_m;
    for (double factor : {1 / 1.5, 1.5, 1 / 2.25, 2.25, 1 / 3.375, 3.375}) {
        if (found || !(configured_m > 0)) break;
        found = passesFrom(out.camera_z_m + factor * configured_m, traverses, o, rectifier, out);
    }
    if (found) {
        const double z = out.camera_z_m;
        out = *found;
        out.camera_z_m = z;
        return finish();
    }
    out.ceiling_height_m = o.ceiling_height_m;
    char buf[300];
    std::snprintf(buf, sizeof(buf),
                  "ceiling height not estimated: fewer than %d image triples accepted (ceiling_"
                  "min_pairs); the configured [survey] ceiling_height_m = %.3f m is used",
                  o.ceiling_min_pairs, o.ceiling_height_m);
    out.warning = buf;
    return finish();
}

nlohmann::ordered_json ceilingJson(const CeilingDistanceEstimate& e, const std::string& source) {
    return {{"source", source},
            {"ceiling_height_m", e.ceiling_height_m},
            {"camera_to_ceiling_m", e.camera_to_ceiling_m},
            {"camera_z_m", e.camera_z_m},
            {"spread_m", e.spread_m},
            {"prior_m", e.prior_m},
            {"triples_tried", e.tried},
            {"triples_used", e.used},
            {"triples_rejected", e.rejected},
            {"estimated", e.estimated},
            {"time_s", e.time_s}};
}

namespace detail {

std::vector<PosedCeilingFrame> posedCeilingFrames(const CeilingTraverse& t) {
    std::vector<PosedCeilingFrame> out;
    for (std::size_t i = 0; i < t.ceiling->size(); ++i) {
        mrpt::math::TPose3D p;
        bool valid = false;
        t.poses->interpolate((*t.ceiling)[i]->timestamp, p, valid);
        if (!valid) continue;
        PosedCeilingFrame f{0, mrpt::poses::CPose3D(p), i};
        if (!out.empty()) {
            const auto& q = out.back().pose;
            f.travel_m = out.back().travel_m + std::hypot(f.pose.x() - q.x(), f.pose.y() - q.y());
        }
        out.push_back(f);
    }
    return out;
}

std::size_t nearestTravel(const std::vector<PosedCeilingFrame>& f, double target_m) {
    const auto it =
        std::lower_bound(f.begin(), f.end(), target_m,
                         [](const PosedCeilingFrame& a, double t) { return a.travel_m < t; });
    if (it == f.end()) return f.size() - 1;
    if (it == f.begin()) return 0;
    const auto hi = static_cast<std::size_t>(it - f.begin());
    return (target_m - f[hi - 1].travel_m <= f[hi].travel_m - target_m) ? hi - 1 : hi;
}

std::optional<refine::Rectifier> storedCameraRectifier(
    const std::vector<CeilingTraverse>& traverses, const SurveyOptions& o) {
    for (const auto& t : traverses) {
        for (const auto& image : *t.ceiling) {
            const auto& c = image->cameraParams;
            if (c.ncols > 0 && c.nrows > 0 && common::cameraProblem(c).empty()) {
                const auto size =
                    common::cappedSize(int(c.ncols), int(c.nrows), o.ceiling_max_width_px);
                return refine::Rectifier(common::resizedCamera(c, size.x, size.y));
            }
        }
    }
    return std::nullopt;
}

}  // namespace detail

}  // namespace lookup::survey

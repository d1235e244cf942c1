// Refinement benchmarks (issue 3): the SAD matcher in pairs/s with Mine A and Mine B
// parameters, the whole Refiner in queries/s with 1, 3 and 5 references, and the OpenCV
// baselines a user would reach for (ORB + RANSAC homography, ECC, phase correlation) on the
// same synthetic pairs, with their error against the known motion. One core: OpenCV threads
// are set to 1 while these run.
#include <benchmark/benchmark.h>

#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>
#include <opencv2/video/tracking.hpp>
#include <vector>

#include "lookup/refine/geometry.h"
#include "lookup/refine/homography.h"
#include "lookup/refine/matcher.h"
#include "lookup/refine/patch_warp.h"
#include "lookup/refine/refiner.h"
#include "lookup/refine/sampler.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

namespace {

using namespace lookup::refine;
using mrpt::poses::CPose3D;

constexpr int kPairs = 16;

// 640 x 480, f = 400 px, camera 3.5 m below a 5 m ceiling: 114 px per metre.
struct World {
    synthetic::SyntheticCeiling ceiling = synthetic::SyntheticCeiling::make(5.0, 14.0, 0.008, 11);
    mrpt::img::TCamera camera = synthetic::makeCamera(640, 480, 400);
    Pinhole pinhole{400, 400, 319.5, 239.5};
    CPose3D on_vehicle = synthetic::ceilingCameraOnVehicle();

    struct Pair {
        ReferenceImage reference;
        cv::Mat query;
        CPose3D query_vehicle;
        cv::Matx33d H;  // true reference -> query pixels
        ImagePyramid ref_pyramid, query_pyramid;
    };
    std::vector<Pair> pairs;

    World() {
        cv::RNG rng(5);
        for (int i = 0; i < kPairs; ++i) {
            // References every 0.5 m along a tunnel; queries within +-0.12 m (14 px) and +-2 deg of
            // them.
            const CPose3D ref_vehicle(0.5 * i - 4.0, rng.uniform(-0.3, 0.3), 0,
                                      rng.uniform(-0.03, 0.03), 0, 0);
            const CPose3D query_vehicle =
                ref_vehicle + CPose3D(rng.uniform(-0.12, 0.12), rng.uniform(-0.12, 0.12), 0,
                                      rng.uniform(-0.035, 0.035), 0, 0);
            Pair p{ceiling.reference(i, camera, on_vehicle, ref_vehicle),
                   ceiling.render(camera, query_vehicle + on_vehicle),
                   query_vehicle,
                   ceilingHomography(pinhole, ref_vehicle + on_vehicle, pinhole,
                                     query_vehicle + on_vehicle, ceiling.height_m),
                   {},
                   {}};
            p.ref_pyramid = ImagePyramid::build(p.reference.image, 2);
            p.query_pyramid = ImagePyramid::build(p.query, 2);
            p.reference.prepare(MatcherOptions{});
            pairs.push_back(std::move(p));
        }
    }
};

const World& world() {
    static const World w;
    return w;
}

class OneCore {
  public:
    OneCore() : previous_(cv::getNumThreads()) { cv::setNumThreads(1); }
    ~OneCore() { cv::setNumThreads(previous_); }

  private:
    int previous_;
};

cv::Point2d apply(const cv::Matx33d& H, const cv::Point2d& p) {
    const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1.0);
    return {v[0] / v[2], v[1] / v[2]};
}

// Mean transfer error [px] of an estimated homography over a 5 x 4 grid of the image.
double transferError(const cv::Matx33d& estimated, const cv::Matx33d& truth) {
    double sum = 0;
    int n = 0;
    for (int y = 60; y < 480; y += 120) {
        for (int x = 64; x < 640; x += 128) {
            sum += cv::norm(apply(estimated, {double(x), double(y)}) -
                            apply(truth, {double(x), double(y)}));
            ++n;
        }
    }
    return sum / n;
}

MatcherOptions mineA() { return MatcherOptions(); }
MatcherOptions mineB() { return RefinerOptions::mineB().matcher; }

// ---------------------------------------------------------------- matcher
// Mean distance of matched points from where the true homography puts them, and matched share.
struct MatchErrors {
    double error_sum = 0;
    long matched = 0, total = 0;
    void add(const std::vector<PointMatch>& matches, const cv::Matx33d& H) {
        for (const auto& x : matches) {
            ++total;
            if (!x.matched()) continue;
            ++matched;
            error_sum += cv::norm(cv::Point2d(x.query_px) - apply(H, cv::Point2d(x.reference_px)));
        }
    }
    void report(benchmark::State& state) const {
        state.counters["err_px"] = matched ? error_sum / matched : -1;
        state.counters["matched"] = total ? double(matched) / total : 0;
    }
};

// The timed loop of the matcher benchmarks: `match(pair, sample points)` over the world's
// pairs in turn on one core, with the match errors against the true homography as counters.
template <class Match>
void timeMatching(benchmark::State& state, const MatcherOptions& o, int points, Match&& match) {
    OneCore one_core;
    const World& w = world();
    // Window margin so every point's full window lies in the image (the border is not what
    // these measure).
    const auto sample =
        gridPoints(cv::Size(640, 480), points, o.patch_px / 2 + o.search_range_px / 2);
    MatchErrors errors;
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& p = w.pairs[i++ % w.pairs.size()];
        const std::vector<PointMatch> m = match(p, sample);
        benchmark::DoNotOptimize(m.data());
        errors.add(m, p.H);
    }
    state.SetItemsProcessed(state.iterations());
    errors.report(state);
}

void matcherBench(benchmark::State& state, MatcherOptions o, int points, SimdLevel simd,
                  bool include_query_pyramid) {
    timeMatching(state, o, points, [&](const World::Pair& p, const auto& sample) {
        if (!include_query_pyramid) {
            return matchPoints(p.ref_pyramid, p.query_pyramid, sample, {}, o, simd);
        }
        const ImagePyramid q = ImagePyramid::build(p.query, effectivePyramidLevels(o));
        return matchPoints(p.ref_pyramid, q, sample, {}, o, simd);
    });
    state.SetLabel(std::string(toString(simd)) +
                   (o.pyramid_levels ? " coarse-to-fine" : " exhaustive"));
}

MatcherOptions exhaustive(MatcherOptions o) {
    o.pyramid_levels = 0;
    return o;
}

BENCHMARK_CAPTURE(matcherBench, MineA_12pts, mineA(), 12, bestSimdLevel(), false);
BENCHMARK_CAPTURE(matcherBench, MineA_24pts, mineA(), 24, bestSimdLevel(), false);
BENCHMARK_CAPTURE(matcherBench, MineB_12pts, mineB(), 12, bestSimdLevel(), false);
BENCHMARK_CAPTURE(matcherBench, MineB_24pts, mineB(), 24, bestSimdLevel(), false);
BENCHMARK_CAPTURE(matcherBench, MineB_12pts_with_query_pyramid, mineB(), 12, bestSimdLevel(), true);
BENCHMARK_CAPTURE(matcherBench, MineB_24pts_sse2, mineB(), 24, SimdLevel::Sse2, false);
BENCHMARK_CAPTURE(matcherBench, MineB_12pts_scalar, mineB(), 12, SimdLevel::Scalar, false);
BENCHMARK_CAPTURE(matcherBench, MineB_12pts_exhaustive, exhaustive(mineB()), 12, bestSimdLevel(),
                  false);
BENCHMARK_CAPTURE(matcherBench, MineB_12pts_exhaustive_scalar, exhaustive(mineB()), 12,
                  SimdLevel::Scalar, false)
    ->Iterations(8);

// Motion-compensated matching (what the localiser runs): the reference warped into the query
// frame by the predicted ceiling homography (here the true one), then the SAD search. The
// warp is done per sample point and pyramid level, so the cost follows the number of points.
// `simd` picks the SAD kernel and the patch warp (hand-written with AVX2, cv::warpPerspective
// otherwise).
void compensatedMatcherBench(benchmark::State& state, MatcherOptions o, int points,
                             SimdLevel simd) {
    timeMatching(state, o, points, [&](const World::Pair& p, const auto& sample) {
        return matchPointsCompensated(p.ref_pyramid, p.query_pyramid, sample, p.H, o, simd);
    });
    state.SetLabel(std::string(toString(simd)) + " SAD, " +
                   (simd == SimdLevel::Avx2 ? "AVX2 warp" : "cv::warpPerspective"));
}
BENCHMARK_CAPTURE(compensatedMatcherBench, Compensated_MineA_12pts, mineA(), 12, bestSimdLevel());
BENCHMARK_CAPTURE(compensatedMatcherBench, Compensated_MineA_24pts, mineA(), 24, bestSimdLevel());
BENCHMARK_CAPTURE(compensatedMatcherBench, Compensated_MineB_24pts, mineB(), 24, bestSimdLevel());
BENCHMARK_CAPTURE(compensatedMatcherBench, Compensated_MineB_24pts_opencv_warp, mineB(), 24,
                  SimdLevel::Sse2);

// One Mine B level-0 patch (60 px and the bilinear taps' pixel each side) warped by a ceiling
// homography: the hand-written AVX2 warp against cv::warpPerspective.
void patchWarpBench(benchmark::State& state, SimdLevel simd) {
    OneCore one_core;
    const World& w = world();
    const int side = mineB().patch_px + 2;
    cv::Mat patch(side, side, CV_8UC1);
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& p = w.pairs[i++ % w.pairs.size()];
        const cv::Matx33d patch_to_ref =
            p.H.inv() * cv::Matx33d(1, 0, 320 - side / 2, 0, 1, 240 - side / 2, 0, 0, 1);
        warpPatch(simd, p.ref_pyramid.levels[0], patch_to_ref, patch);
        benchmark::DoNotOptimize(patch.data);
    }
    state.SetItemsProcessed(state.iterations());
    state.SetLabel(simd == SimdLevel::Avx2 ? "AVX2" : "cv::warpPerspective");
}
BENCHMARK_CAPTURE(patchWarpBench, PatchWarp_62px, bestSimdLevel());
BENCHMARK_CAPTURE(patchWarpBench, PatchWarp_62px_opencv, SimdLevel::Sse2);

// The OpenCV way to do the same search: cv::matchTemplate (no SAD there; TM_SQDIFF), exhaustive
// over the Mine B window, integer peak. Shows what the hand-written SAD path buys.
void matchTemplateBench(benchmark::State& state, int points) {
    OneCore one_core;
    const World& w = world();
    const MatcherOptions o = mineB();
    const int r = o.search_range_px / 2, half = o.patch_px / 2;
    const auto sample = gridPoints(cv::Size(640, 480), points, half + r);
    double error_sum = 0;
    long n = 0;
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& p = w.pairs[i++ % w.pairs.size()];
        for (const auto& pt : sample) {
            const cv::Point c(int(pt.x), int(pt.y));
            const cv::Mat patch =
                p.reference.image(cv::Rect(c.x - half, c.y - half, o.patch_px, o.patch_px));
            const cv::Mat window = p.query(
                cv::Rect(c.x - half - r, c.y - half - r, o.patch_px + 2 * r, o.patch_px + 2 * r));
            cv::Mat score;
            cv::matchTemplate(window, patch, score, cv::TM_SQDIFF);
            cv::Point best;
            cv::minMaxLoc(score, nullptr, nullptr, &best);
            const cv::Point2d q(c.x + best.x - r, c.y + best.y - r);
            error_sum += cv::norm(q - apply(p.H, cv::Point2d(pt)));
            ++n;
        }
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["err_px"] = n ? error_sum / n : -1;
    state.SetLabel("integer peak");
}
BENCHMARK_CAPTURE(matchTemplateBench, Baseline_matchTemplate_SQDIFF_MineB_12pts, 12);

// ---------------------------------------------------------------- matcher + homography vs OpenCV
void lookupHomography(benchmark::State& state, int points) {
    OneCore one_core;
    const World& w = world();
    const MatcherOptions o = mineB();
    const auto sample = gridPoints(cv::Size(640, 480), points, 30);
    double err = 0;
    long n = 0, failed = 0;
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& p = w.pairs[i++ % w.pairs.size()];
        auto m = matchPoints(p.ref_pyramid, p.query_pyramid, sample, {}, o);
        const auto h = estimateHomography(m, HomographyOptions());
        if (h.ok) {
            err += transferError(h.H, p.H);
            ++n;
        } else {
            ++failed;
        }
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["err_px"] = n ? err / n : -1;
    state.counters["failed"] = double(failed);
}
BENCHMARK_CAPTURE(lookupHomography, LookUP_SAD_MineB_24pts_RANSAC, 24);

void orbHomography(benchmark::State& state) {
    OneCore one_core;
    const World& w = world();
    auto orb = cv::ORB::create(500);
    cv::BFMatcher matcher(cv::NORM_HAMMING, true);
    double err = 0;
    long n = 0, failed = 0;
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& p = w.pairs[i++ % w.pairs.size()];
        std::vector<cv::KeyPoint> k1, k2;
        cv::Mat d1, d2;
        orb->detectAndCompute(p.reference.image, cv::noArray(), k1, d1);
        orb->detectAndCompute(p.query, cv::noArray(), k2, d2);
        std::vector<cv::DMatch> matches;
        if (!d1.empty() && !d2.empty()) matcher.match(d1, d2, matches);
        std::vector<cv::Point2f> a, b;
        for (const auto& m : matches) {
            a.push_back(k1[m.queryIdx].pt);
            b.push_back(k2[m.trainIdx].pt);
        }
        cv::Mat H;
        if (a.size() >= 4) H = cv::findHomography(a, b, cv::RANSAC, 2.0);
        if (!H.empty()) {
            err += transferError(cv::Matx33d(H), p.H);
            ++n;
        } else {
            ++failed;
        }
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["err_px"] = n ? err / n : -1;
    state.counters["failed"] = double(failed);
}
BENCHMARK(orbHomography)->Name("Baseline_ORB500_findHomography_RANSAC");

void eccEuclidean(benchmark::State& state) {
    OneCore one_core;
    const World& w = world();
    double err = 0;
    long n = 0, failed = 0;
    std::size_t i = 0;
    for (auto _ : state) {
        const auto& p = w.pairs[i++ % w.pairs.size()];
        cv::Mat warp = cv::Mat::eye(2, 3, CV_32F);
        try {
            cv::findTransformECC(
                p.reference.image, p.query, warp, cv::MOTION_EUCLIDEAN,
                cv::TermCriteria(cv::TermCriteria::COUNT + cv::TermCriteria::EPS, 50, 1e-4),
                cv::noArray(), 5);
            cv::Matx33d H = cv::Matx33d::eye();
            for (int r = 0; r < 2; ++r)
                for (int c = 0; c < 3; ++c) H(r, c) = warp.at<float>(r, c);
            // ECC's warp maps template (reference) coordinates to input (query) coordinates.
            err += transferError(H, p.H);
            ++n;
        } catch (const cv::Exception&) {
            ++failed;
        }
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["err_px"] = n ? err / n : -1;
    state.counters["failed"] = double(failed);
}
BENCHMARK(eccEuclidean)->Name("Baseline_findTransformECC_EUCLIDEAN");

void phaseCorrelation(benchmark::State& state) {
    OneCore one_core;
    const World& w = world();
    std::vector<cv::Mat> refs, queries;
    for (const auto& p : w.pairs) {
        cv::Mat a, b;
        p.reference.image.convertTo(a, CV_64F);
        p.query.convertTo(b, CV_64F);
        refs.push_back(a);
        queries.push_back(b);
    }
    const cv::Mat window = [] {
        cv::Mat h;
        cv::createHanningWindow(h, cv::Size(640, 480), CV_64F);
        return h;
    }();
    double err = 0;
    long n = 0;
    std::size_t i = 0;
    for (auto _ : state) {
        const std::size_t k = i++ % w.pairs.size();
        const cv::Point2d shift = cv::phaseCorrelate(refs[k], queries[k], window);
        const cv::Matx33d H(1, 0, shift.x, 0, 1, shift.y, 0, 0, 1);
        err += transferError(H, w.pairs[k].H);
        ++n;
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["err_px"] = n ? err / n : -1;
    state.SetLabel("translation only; 8-bit to double conversion excluded");
}
BENCHMARK(phaseCorrelation)->Name("Baseline_phaseCorrelate");

// ---------------------------------------------------------------- whole Refiner
void refinerBench(benchmark::State& state) {
    OneCore one_core;
    const World& w = world();
    const int n_refs = int(state.range(0));
    const Refiner refiner(RefinerOptions::mineB());
    double err = 0;
    long accepted = 0, queries = 0;
    std::size_t i = 0;
    for (auto _ : state) {
        // The query of pair k against references k .. k + n_refs - 1 (0.5 m apart).
        const std::size_t k = i++ % (w.pairs.size() - 5);
        std::vector<ReferenceImage> refs;
        for (int j = 0; j < n_refs; ++j) refs.push_back(w.pairs[k + j].reference);
        CoarseHint hint;
        hint.vehicle_pose = w.pairs[k].reference.vehicle_in_map;
        const auto r = refiner.refine(w.pairs[k].query, w.camera, w.on_vehicle, hint, refs);
        ++queries;
        if (r.accepted()) {
            ++accepted;
            err += std::hypot(r.pose.mean.x() - w.pairs[k].query_vehicle.x(),
                              r.pose.mean.y() - w.pairs[k].query_vehicle.y());
        }
    }
    state.SetItemsProcessed(state.iterations());
    state.counters["err_m"] = accepted ? err / accepted : -1;
    state.counters["accepted"] = queries ? double(accepted) / queries : 0;
}
BENCHMARK(refinerBench)
    ->Name("Refiner_MineB_grid24/refs")
    ->Arg(1)
    ->Arg(3)
    ->Arg(5)
    ->Unit(benchmark::kMillisecond);

// ---------------------------------------------------------------- heat-map point selection
/// 12 points from a 640x480 heat map (a reference of a heat-map run; every newly loaded
/// reference pays it): the greedy search with per-tile maxima (heatMapPoints) against the
/// same greedy search by cv::minMaxLoc over the whole map per point, as it was first written.
void heatMapSelection(benchmark::State& state, bool whole_map) {
    cv::Mat small(120, 160, CV_32F), heat;
    cv::RNG(3).fill(small, cv::RNG::UNIFORM, 0.0, 1.0);
    cv::GaussianBlur(small, small, cv::Size(0, 0), 2.0);
    cv::resize(small, heat, cv::Size(640, 480), 0, 0,
               cv::INTER_LINEAR);  // as the localiser loads it
    const int count = 12, side = 60, margin = 30;
    const double ratio = 0.5;
    std::size_t chosen = 0;
    for (auto _ : state) {
        if (!whole_map) {
            chosen = heatMapPoints(heat, count, ratio, side, margin).size();
            continue;
        }
        if (!cv::checkRange(heat)) continue;
        cv::Mat map = heat(cv::Rect(margin, margin, 640 - 2 * margin, 480 - 2 * margin)).clone();
        std::vector<cv::Point> points;
        for (int i = 0; i < count; ++i) {
            cv::Point best;
            double value = 0.0;
            cv::minMaxLoc(map, nullptr, &value, nullptr, &best);
            points.push_back(best);
            map(cv::Rect(best.x - side / 2, best.y - side / 2, side, side) &
                cv::Rect(0, 0, map.cols, map.rows)) *= ratio;
            map.at<float>(best) = -1.0f;
        }
        chosen = points.size();
    }
    state.counters["points"] = double(chosen);
}
BENCHMARK_CAPTURE(heatMapSelection, HeatMapPoints_640x480_12pts, false)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(heatMapSelection, HeatMapPoints_640x480_12pts_wholeMapSearch, true)
    ->Unit(benchmark::kMicrosecond);

}  // namespace

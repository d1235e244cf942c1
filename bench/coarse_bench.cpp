// Coarse stage benchmarks: descriptor extraction and one online frame while tracking, for a
// reference database 10x longer, to show that the work per frame does not grow with it.
#include <benchmark/benchmark.h>
#include <mrpt/poses/CPose3D.h>

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <memory>
#include <optional>
#include <random>
#include <vector>

#include "lookup/coarse/coarse_localizer.h"

namespace {

using lookup::coarse::CoarseLocalizer;
using lookup::coarse::CoarseOptions;
using lookup::coarse::Descriptor;
using lookup::coarse::ReferenceDescriptors;

/// An aliased route: place i looks like one of 3 textures; views cross-fade between places.
class Route {
  public:
    explicit Route(int places) {
        cv::theRNG().state = 42;
        for (int k = 0; k < 3; ++k) {
            cv::Mat t(48, 64, CV_32F);
            cv::randn(t, 0, 1);
            cv::GaussianBlur(t, t, cv::Size(0, 0), 2.5);
            cv::normalize(t, t, 40, 215, cv::NORM_MINMAX);
            tiles_.push_back(t);
        }
        std::mt19937 rng(1);
        for (int i = 0; i < places + 2; ++i) type_.push_back(static_cast<int>(rng() % 3));
    }
    Descriptor descriptor(double x, const CoarseOptions& o) const {
        const int i = static_cast<int>(x);
        const double f = x - i;
        cv::Mat v = tiles_[type_[i]] * (1 - f) + tiles_[type_[i + 1]] * f, n(48, 64, CV_32F), u8;
        cv::randn(n, 0, 6);
        v += n;
        v.convertTo(u8, CV_8U);
        return lookup::coarse::computeDescriptor(mrpt::img::CImage(u8, mrpt::img::SHALLOW_COPY), o);
    }

  private:
    std::vector<cv::Mat> tiles_;
    std::vector<int> type_;
};

void BM_CoarseDescriptor640x480(benchmark::State& state) {
    cv::Mat img(480, 640, CV_8U);
    cv::randu(img, 0, 255);
    const mrpt::img::CImage image(img, mrpt::img::SHALLOW_COPY);
    const CoarseOptions o;
    for (auto _ : state) benchmark::DoNotOptimize(lookup::coarse::computeDescriptor(image, o));
}
BENCHMARK(BM_CoarseDescriptor640x480)->Unit(benchmark::kMicrosecond);

/// One tracking frame (sequence search only; descriptor precomputed) against a database of
/// state.range(0) references. Counters: references evaluated and candidates scored per frame.
/// With odometry (as the localiser runs it), references 1 m apart and 1 m travelled per frame:
/// paths follow the travelled distance instead of a range of speeds. No track audit (the
/// localiser skips it while LookUP refines; it is a global search, see coarseGlobalFrame).
void coarseTrackingFrame(benchmark::State& state, bool odometry) {
    const int n = static_cast<int>(state.range(0));
    CoarseOptions o;
    // Global searches over every reference: this route's 3 textures make single thumbnails
    // useless to the descriptor index (a third of all places match each), so an indexed
    // acquisition would be a coin toss here and tracking frames are what this measures.
    o.global_index_min_references = n + 1;
    const Route route(n);
    auto refs = std::make_shared<ReferenceDescriptors>(o);
    for (int i = 0; i < n; ++i) {
        if (odometry) {
            refs->add(i, route.descriptor(i, o), mrpt::poses::CPose3D(i, 0, 0, 0, 0, 0));
        } else {
            refs->add(i, route.descriptor(i, o));
        }
    }
    const std::optional<double> travelled = odometry ? std::optional<double>(1.0) : std::nullopt;
    std::vector<Descriptor> queries;
    for (int t = 0; t < 600; ++t) queries.push_back(route.descriptor(100.3 + t, o));

    auto loc = std::make_unique<CoarseLocalizer>(refs, o);
    std::size_t next = 0, evaluated = 0, candidates = 0, frames = 0, tracking = 0;
    auto warmUp = [&] {  // fill the buffer and lock on (global searches, not timed)
        loc = std::make_unique<CoarseLocalizer>(refs, o);
        for (next = 0; next < 40; ++next) loc->processDescriptor(queries[next], next, travelled);
    };
    warmUp();
    for (auto _ : state) {
        if (next == queries.size()) {
            state.PauseTiming();
            warmUp();
            state.ResumeTiming();
        }
        const auto r = loc->processDescriptor(queries[next], static_cast<double>(next), travelled,
                                              /*search=*/true, /*audit=*/false);
        ++next;
        ++frames;
        evaluated += r.evaluated_references;
        candidates += r.searched_candidates;
        tracking += r.status == lookup::coarse::CoarseStatus::Tracking;
    }
    state.counters["evaluated_per_frame"] = static_cast<double>(evaluated) / frames;
    state.counters["candidates_per_frame"] = static_cast<double>(candidates) / frames;
    state.counters["tracking_share"] = static_cast<double>(tracking) / frames;
}
BENCHMARK_CAPTURE(coarseTrackingFrame, CoarseTrackingFrame, false)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMicrosecond);
BENCHMARK_CAPTURE(coarseTrackingFrame, CoarseTrackingFrame_odometry, true)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMicrosecond);

/// One thumbnail difference (64x48 bytes), the inner loop of a global search: the hand-written
/// psadbw loop against OpenCV's cv::norm(NORM_L1) on the same bytes.
void BM_CoarseDescriptorDifference(benchmark::State& state) {
    const CoarseOptions o;
    const Route route(100);
    const Descriptor a = route.descriptor(10.0, o), b = route.descriptor(50.0, o);
    const bool opencv = state.range(0) == 1;
    const cv::Mat ma(1, static_cast<int>(a.size()), CV_8U, const_cast<std::uint8_t*>(a.data()));
    const cv::Mat mb(1, static_cast<int>(b.size()), CV_8U, const_cast<std::uint8_t*>(b.data()));
    for (auto _ : state) {
        benchmark::DoNotOptimize(opencv ? static_cast<float>(cv::norm(ma, mb, cv::NORM_L1) /
                                                             static_cast<double>(a.size()))
                                        : lookup::coarse::descriptorDifference(a, b));
    }
    state.SetLabel(opencv ? "cv::norm NORM_L1" : "descriptorDifference (psadbw)");
}
BENCHMARK(BM_CoarseDescriptorDifference)->Arg(0)->Arg(1)->Unit(benchmark::kNanosecond);

/// A global search (start-up, kidnapping, lost) on every frame: scoring every reference is
/// linear in the database length; through the descriptor index (global_index_*) only windows
/// around the places it finds are scored.
void coarseGlobalFrame(benchmark::State& state, bool indexed) {
    const int n = static_cast<int>(state.range(0));
    CoarseOptions o;
    o.min_confidence = 1e9;  // never confident: every frame searches globally
    o.global_index_min_references = indexed ? 0 : n + 1;
    const Route route(n);
    auto refs = std::make_shared<ReferenceDescriptors>(o);
    for (int i = 0; i < n; ++i) refs->add(i, route.descriptor(i, o));
    std::vector<Descriptor> queries;
    for (int t = 0; t < 400; ++t) queries.push_back(route.descriptor(100.3 + t * 0.5, o));
    CoarseLocalizer loc(refs, o);
    std::size_t t = 0, evaluated = 0, candidates = 0;
    for (auto _ : state) {
        const auto r = loc.processDescriptor(queries[t % queries.size()], static_cast<double>(t));
        evaluated += r.evaluated_references;
        candidates += r.searched_candidates;
        ++t;
    }
    state.counters["evaluated_per_frame"] = static_cast<double>(evaluated) / t;
    state.counters["candidates_per_frame"] = static_cast<double>(candidates) / t;
}
BENCHMARK_CAPTURE(coarseGlobalFrame, CoarseGlobalFrame_exhaustive, false)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(coarseGlobalFrame, CoarseGlobalFrame_indexed, true)
    ->Arg(1000)
    ->Arg(10000)
    ->Unit(benchmark::kMillisecond);

}  // namespace

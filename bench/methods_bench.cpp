// Baseline matchers inside the Refiner (issue 6, deliverable 3): the whole refinement with the
// paper's SAD, with ORB + RANSAC homography and with ECC in place of SAD, on the same
// synthetic pairs as refine_bench.cpp (640 x 480, f = 400 px, 114 px per metre; queries within
// +-0.12 m and +-2 deg of their reference), Mine B parameters, 24 grid points, a coarse pose
// equal to the reference's. An item is one query-reference pair (a query with 3 references is
// 3 items), so pairs/s compare across methods. One core: OpenCV runs with one thread.
#include <benchmark/benchmark.h>

#include <cmath>
#include <vector>

#include "lookup/refine/correspondence_methods.h"
#include "lookup/refine/geometry.h"
#include "lookup/refine/refiner.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

namespace {

using namespace lookup::refine;
using mrpt::poses::CPose3D;

struct MethodsWorld {
    synthetic::SyntheticCeiling ceiling = synthetic::SyntheticCeiling::make(5.0, 14.0, 0.008, 11);
    mrpt::img::TCamera camera = synthetic::makeCamera(640, 480, 400);
    CPose3D on_vehicle = synthetic::ceilingCameraOnVehicle();
    std::vector<ReferenceImage> references;  // every 0.5 m along the tunnel
    std::vector<cv::Mat> queries;            // one near each reference
    std::vector<CPose3D> query_vehicles;

    MethodsWorld() {
        cv::RNG rng(5);
        for (int i = 0; i < 16; ++i) {
            const CPose3D ref_vehicle(0.5 * i - 4.0, rng.uniform(-0.3, 0.3), 0,
                                      rng.uniform(-0.03, 0.03), 0, 0);
            const CPose3D query_vehicle =
                ref_vehicle + CPose3D(rng.uniform(-0.12, 0.12), rng.uniform(-0.12, 0.12), 0,
                                      rng.uniform(-0.035, 0.035), 0, 0);
            references.push_back(ceiling.reference(i, camera, on_vehicle, ref_vehicle));
            references.back().prepare(lookup::refine::MatcherOptions{});
            queries.push_back(ceiling.render(camera, query_vehicle + on_vehicle));
            query_vehicles.push_back(query_vehicle);
        }
    }
};

const MethodsWorld& methodsWorld() {
    static const MethodsWorld w;
    return w;
}

void refinerMethodBench(benchmark::State& state, CorrespondenceMethod method) {
    const int previous_threads = cv::getNumThreads();
    cv::setNumThreads(1);
    const MethodsWorld& w = methodsWorld();
    const int n_refs = int(state.range(0));
    RefinerOptions o = RefinerOptions::mineB();
    o.sampler.mode = SamplingMode::Grid;
    o.correspondence.method = method;
    const Refiner refiner(o);
    double err = 0;
    long accepted = 0, queries = 0;
    std::size_t i = 0;
    for (auto _ : state) {
        const std::size_t k = i++ % (w.queries.size() - 5);
        const std::vector<ReferenceImage> refs(w.references.begin() + long(k),
                                               w.references.begin() + long(k) + n_refs);
        CoarseHint hint;
        hint.vehicle_pose = w.references[k].vehicle_in_map;
        const auto r = refiner.refine(w.queries[k], w.camera, w.on_vehicle, hint, refs);
        ++queries;
        if (r.accepted()) {
            ++accepted;
            err += std::hypot(r.pose.mean.x() - w.query_vehicles[k].x(),
                              r.pose.mean.y() - w.query_vehicles[k].y());
        }
    }
    cv::setNumThreads(previous_threads);
    state.SetItemsProcessed(state.iterations() * n_refs);
    state.counters["err_m"] = accepted ? err / accepted : -1;
    state.counters["accepted"] = queries ? double(accepted) / queries : 0;
    state.SetLabel(std::string(toString(method)) + ", items = pairs");
}

BENCHMARK_CAPTURE(refinerMethodBench, Methods_MineB_grid24_sad, CorrespondenceMethod::Sad)
    ->ArgName("refs")
    ->Arg(1)
    ->Arg(3)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(refinerMethodBench, Methods_MineB_grid24_orb, CorrespondenceMethod::Orb)
    ->ArgName("refs")
    ->Arg(1)
    ->Arg(3)
    ->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(refinerMethodBench, Methods_MineB_grid24_ecc, CorrespondenceMethod::Ecc)
    ->ArgName("refs")
    ->Arg(1)
    ->Arg(3)
    ->Unit(benchmark::kMillisecond);

}  // namespace

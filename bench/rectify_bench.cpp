// Rectification cost (lookup::refine::Rectifier): one cv::remap per query frame of the
// simulator's 320 x 240 ceiling camera, strong barrel (plumb_bob) and fisheye (kannala_brandt),
// with the maps cached; building the maps once per camera; and the pixels of a frame's inliers
// undistorted for the estimator (lookup::refine::undistortPixels). One core.
#include <benchmark/benchmark.h>

#include <opencv2/core.hpp>

#include "lookup/refine/geometry.h"
#include "lookup/refine/rectifier.h"

namespace {

mrpt::img::TCamera camera(bool fisheye) {
    mrpt::img::TCamera c;
    c.ncols = 320;
    c.nrows = 240;
    c.setIntrinsicParamsFromValues(fisheye ? 131.0 : 146.6, fisheye ? 131.0 : 146.6, 159.5, 119.5);
    if (fisheye) {
        c.setDistortionKannalaBrandt(0.01, -0.005, 0.002, -0.001);
    } else {
        c.setDistortionPlumbBob(-0.40, 0.12, 0.0005, -0.0005);
    }
    return c;
}

void rectifyFrame(benchmark::State& state) {
    cv::setNumThreads(1);
    const auto cam = camera(state.range(0) == 1);
    const lookup::refine::Rectifier rectifier(cam);
    cv::Mat image(240, 320, CV_8UC1);
    cv::randu(image, 0, 255);
    rectifier.rectify(image, cam);  // maps built here, once
    for (auto _ : state) benchmark::DoNotOptimize(rectifier.rectify(image, cam));
}
BENCHMARK(rectifyFrame)
    ->Name("Rectify_320x240_remap")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond);

void buildMaps(benchmark::State& state) {
    cv::setNumThreads(1);
    const auto cam = camera(state.range(0) == 1);
    cv::Mat image(240, 320, CV_8UC1, cv::Scalar(0));
    for (auto _ : state) {
        const lookup::refine::Rectifier rectifier(cam);  // a fresh cache each time
        benchmark::DoNotOptimize(rectifier.rectify(image, cam));
    }
}
BENCHMARK(buildMaps)
    ->Name("Rectify_320x240_build_maps")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMillisecond);

// 150 inliers spread over the image: three references' worth of a tracked frame.
void undistortInliers(benchmark::State& state) {
    cv::setNumThreads(1);
    const auto cam = camera(state.range(0) == 1);
    std::vector<cv::Point2f> px;
    cv::RNG rng(1);
    for (int i = 0; i < 150; ++i) px.emplace_back(rng.uniform(0.f, 319.f), rng.uniform(0.f, 239.f));
    for (auto _ : state) benchmark::DoNotOptimize(lookup::refine::undistortPixels(px, cam));
}
BENCHMARK(undistortInliers)
    ->Name("Undistort_150_inliers")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMicrosecond);

}  // namespace

// Reading a reference's ceiling image from the database (lookup::database::ImageCache, a miss
// every time): the simulator's 320 x 240 grey ceiling image stored as PNG (what the survey
// copied before) and as uncompressed PGM (what it stores now). A lost frame reads dozens of
// references. One core.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "lookup/database/image_cache.h"

namespace {

// Rock-like texture: random noise blurred at several scales (compresses like the simulator's).
cv::Mat ceilingTexture(int seed) {
    cv::RNG rng(seed);
    cv::Mat sum(240, 320, CV_32F, cv::Scalar(0));
    for (double sigma : {1.0, 3.0, 9.0}) {
        cv::Mat noise(240, 320, CV_32F);
        rng.fill(noise, cv::RNG::NORMAL, 0, 1);
        cv::GaussianBlur(noise, noise, cv::Size(0, 0), sigma);
        sum += noise * (40.0 * std::sqrt(sigma));
    }
    cv::Mat out;
    sum.convertTo(out, CV_8U, 1.0, 128.0);
    return out;
}

void readReference(benchmark::State& state) {
    cv::setNumThreads(1);
    const std::string ext = state.range(0) == 0 ? ".png" : ".pgm";
    const auto dir = std::filesystem::temp_directory_path() / "lookup_bench_reference_read";
    std::filesystem::create_directories(dir);
    std::string paths[2];
    for (int i = 0; i < 2; ++i) {
        paths[i] = (dir / ("ceiling_" + std::to_string(i) + ext)).string();
        cv::imwrite(paths[i], ceilingTexture(i));
    }
    state.counters["KB"] = static_cast<double>(std::filesystem::file_size(paths[0])) / 1024.0;
    lookup::database::ImageCache cache(1);  // two images alternating: every get reads the file
    int k = 0;
    for (auto _ : state) benchmark::DoNotOptimize(cache.get(paths[k++ % 2]));
    std::filesystem::remove_all(dir);
}
BENCHMARK(readReference)
    ->Name("ReferenceImageRead_png_pgm")
    ->Arg(0)
    ->Arg(1)
    ->Unit(benchmark::kMicrosecond);

}  // namespace

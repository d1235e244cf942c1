// Reading a reference's ceiling image from the database (lookup::database::ImageCache, a miss
// every time): the simulator's 320 x 240 grey ceiling image stored as PNG (what the survey
// copied before) and as uncompressed PGM (what it stores now). A lost frame reads dozens of
// references. And the localiser's online refresh adding one stretch's references to a database
// of 10k (the full mine-b survey) and 100k references (ten of them): the indices are rebuilt on
// the frame that closes the stretch. One core.
#include <benchmark/benchmark.h>

#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>

#include "lookup/database/database_writer.h"
#include "lookup/database/image_cache.h"
#include "lookup/database/reference_database.h"

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

// A database of `n` references along a 1.5 km line (one on disk, the rest in memory).
lookup::database::ReferenceDatabase lineDatabase(const std::filesystem::path& dir, int n) {
    using namespace lookup::database;
    std::filesystem::remove_all(dir);
    {
        DatabaseWriter w(dir.string());
        ReferenceInput in;
        in.ceiling = mrpt::obs::CObservationImage::Create();
        in.ceiling->sensorLabel = "CEILING_CAM";
        in.ceiling->cameraParams.ncols = 16;
        in.ceiling->cameraParams.nrows = 12;
        in.ceiling->cameraParams.fx(300);
        in.ceiling->cameraParams.fy(300);
        in.ceiling->image.resize(16, 12, mrpt::img::CH_GRAY);
        in.vehicle_cov.setIdentity();
        w.add(in);
        DatabaseInfo info;
        info.ceiling_camera = in.ceiling->cameraParams;
        w.commit(info);
    }
    auto db = ReferenceDatabase::load(dir.string());
    std::vector<std::pair<Reference, cv::Mat>> refs;
    const cv::Mat image(12, 16, CV_8UC1, cv::Scalar(100));
    for (int i = 1; i < n; ++i) {
        Reference r = db.reference(0);
        r.time_s = 0.1 * i;
        r.vehicle_pose = mrpt::poses::CPose3D(1500.0 * i / n, 0.3 * (i % 3), 0, 0, 0, 0);
        r.ceiling_camera_pose = r.vehicle_pose;
        refs.emplace_back(r, image);
    }
    db.addInMemory(std::move(refs), {}, "");
    return db;
}

void onlineRefreshStretch(benchmark::State& state) {
    using namespace lookup::database;
    const auto dir = std::filesystem::temp_directory_path() / "lookup_bench_online_refresh";
    auto db = lineDatabase(dir, int(state.range(0)));
    const cv::Mat image(12, 16, CV_8UC1, cv::Scalar(50));
    double x = 0;
    for (auto _ : state) {
        // A 10 m stretch at 0.25 m: 40 references, superseding the 40 nearest.
        std::vector<std::pair<Reference, cv::Mat>> added;
        std::vector<std::size_t> superseded;
        for (int k = 0; k < 40; ++k, x += 0.25) {
            Reference r = db.reference(0);
            r.vehicle_pose = r.ceiling_camera_pose = mrpt::poses::CPose3D(x, 0, 0, 0, 0, 0);
            added.emplace_back(r, image);
            for (const auto& n : db.nearestCameras(mrpt::math::TPoint2D(x, 0), 1))
                superseded.push_back(n.index);
        }
        db.addInMemory(std::move(added), superseded, "bench");
    }
    state.counters["references"] = double(db.size());
    std::filesystem::remove_all(dir);
}
BENCHMARK(onlineRefreshStretch)
    ->Name("OnlineRefreshAddStretch_10k_100k")
    ->Arg(10000)
    ->Arg(100000)
    ->Unit(benchmark::kMillisecond);

}  // namespace

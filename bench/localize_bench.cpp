// The pose stream's cost against a frame's: one tracking frame of the Localizer on a small
// synthetic ceiling (320 x 240, a cheap frame, so the share below is an upper bound), and
// publishing one frame's result: what the frame loop pays (message + enqueue) and what the
// sender thread pays besides (serialise + send to a TCP client that reads).
#include <arpa/inet.h>
#include <benchmark/benchmark.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <atomic>
#include <cmath>
#include <filesystem>
#include <memory>
#include <thread>

#include "lookup/database/database_writer.h"
#include "lookup/database/reference_database.h"
#include "lookup/localize/camera_clock.h"
#include "lookup/localize/localizer.h"
#include "lookup/localize/pose_stream.h"
#include "lookup/localize/readout_estimator.h"
#include "lookup/localize/vehicle_link.h"
#include "lookup/refine/testing/synthetic_ceiling.h"

namespace {

namespace fs = std::filesystem;
namespace synthetic = lookup::refine::synthetic;

struct TrackingScene {
    synthetic::SyntheticCeiling ceiling = synthetic::SyntheticCeiling::make(5.0, 40.0, 0.01, 7);
    mrpt::img::TCamera camera = synthetic::makeCamera(320, 240, 160);
    mrpt::poses::CPose3D mount = synthetic::ceilingCameraOnVehicle();
    fs::path dir = fs::temp_directory_path() / "lookup_bench_localize";
    std::unique_ptr<lookup::database::ReferenceDatabase> db;
    std::vector<mrpt::obs::CObservationImage::Ptr> frames;  ///< 0.05 m apart along y = 0.1

    mrpt::obs::CObservationImage::Ptr image(const mrpt::poses::CPose3D& vehicle) const {
        auto obs = mrpt::obs::CObservationImage::Create();
        obs->sensorLabel = "CEILING_CAM";
        obs->cameraParams = camera;
        obs->cameraPose = mount;
        obs->image =
            mrpt::img::CImage(ceiling.render(camera, vehicle + mount), mrpt::img::DEEP_COPY);
        return obs;
    }

    TrackingScene() {
        fs::remove_all(dir);
        {
            lookup::database::DatabaseWriter writer((dir / "db").string());
            for (int k = 0; k < 65; ++k) {
                lookup::database::ReferenceInput in;
                in.traverse = "survey";
                in.vehicle_pose = mrpt::poses::CPose3D(-8 + 0.25 * k, 0, 0, 0, 0, 0);
                in.vehicle_cov.setIdentity();
                in.vehicle_cov *= 1e-4;
                in.ceiling = image(in.vehicle_pose);
                in.ceiling->timestamp = mrpt::Clock::fromDouble(100.0 + 0.1 * k);
                in.travelled_m = 0.25 * k;
                writer.add(in);
            }
            lookup::database::DatabaseInfo info;
            info.name = "bench";
            info.ceiling_camera = camera;
            info.ceiling_height_m = 5.0;
            info.pose_source = "bench";
            writer.commit(info);
        }
        db = std::make_unique<lookup::database::ReferenceDatabase>(
            lookup::database::ReferenceDatabase::load((dir / "db").string()));
        for (int k = 0; k < 100; ++k) frames.push_back(image(start(k)));
    }
    static mrpt::poses::CPose3D start(int k) { return {-5 + 0.05 * k, 0.1, 0, 0.02, 0, 0}; }
};

void BM_LocalizerTrackingFrame(benchmark::State& state) {
    TrackingScene scene;
    lookup::refine::RefinerOptions refiner_options;
    refiner_options.sampler.mode = lookup::refine::SamplingMode::Grid;
    lookup::localize::Localizer localizer(*scene.db, {}, refiner_options, nullptr, false);
    double t = 1000;
    std::size_t k = 0, refined = 0, frames = 0;
    for (auto _ : state) {
        if (k % scene.frames.size() == 0) {
            const auto p = TrackingScene::start(0);
            localizer.setInitialPose(t - 0.05, mrpt::poses::CPose2D(p.x(), p.y(), p.yaw()));
        }
        auto& frame = scene.frames[k++ % scene.frames.size()];
        frame->timestamp = mrpt::Clock::fromDouble(t += 0.05);
        const auto result = localizer.process(frame);
        refined += result && result->status == lookup::localize::FrameStatus::Refined;
        ++frames;
    }
    state.counters["refined_share"] = double(refined) / double(std::max<std::size_t>(1, frames));
}
BENCHMARK(BM_LocalizerTrackingFrame)->Unit(benchmark::kMillisecond);

/// A refined frame's result, as the stream sees it.
lookup::localize::FrameResult typicalFrame() {
    lookup::localize::FrameResult f;
    f.time_s = 1.7e9 + 12.345;
    f.status = lookup::localize::FrameStatus::Refined;
    f.has_pose = true;
    f.pose.mean = mrpt::poses::CPose2D(123.456, -7.89, 0.1234);
    f.pose.cov.setIdentity();
    f.pose.cov *= 1.6e-4;
    f.pose_source = "refined";
    f.inlier_share = 0.93;
    f.times.total_ms = 4.2;
    return f;
}

/// A TCP client on the stream's port that reads everything, counting lines.
struct ReadingClient {
    std::atomic<std::size_t> lines{0};
    std::atomic<bool> stop{false};
    std::thread thread;
    explicit ReadingClient(int port) {
        thread = std::thread([this, port] {
            const int fd = socket(AF_INET, SOCK_STREAM, 0);
            sockaddr_in a{};
            a.sin_family = AF_INET;
            a.sin_port = htons(static_cast<uint16_t>(port));
            a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
            if (connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) != 0) return;
            char buf[65536];
            for (ssize_t n; !stop && (n = recv(fd, buf, sizeof buf, 0)) > 0;) {
                for (ssize_t i = 0; i < n; ++i) lines += buf[i] == '\n';
            }
            close(fd);
        });
    }
    ~ReadingClient() {
        stop = true;
        thread.join();
    }
};

/// What the frame loop pays per frame: the message and the enqueue.
void BM_PublishFrameLoopCost(benchmark::State& state) {
    lookup::localize::PoseStream stream("tcp://127.0.0.1:0", 4096);
    ReadingClient client(stream.port());
    stream.waitForClient(5);
    const auto frame = typicalFrame();
    std::size_t k = 0;
    for (auto _ : state) {
        stream.push(lookup::localize::poseMessage(frame, k++),
                    lookup::localize::PoseStream::unixTime());
        // Let the sender keep up, outside the timing: this measures the cost, not a backlog.
        if (k % 256 == 0) {
            state.PauseTiming();
            while (client.lines + 256 < k) std::this_thread::yield();
            state.ResumeTiming();
        }
    }
    stream.close();
    state.counters["dropped"] = double(stream.stats().dropped_queue_full);
}
BENCHMARK(BM_PublishFrameLoopCost)->Unit(benchmark::kMicrosecond);

/// Everything publishing costs per frame, both threads: message, enqueue, serialisation,
/// send, until the client has the line (wall time per message, one at a time).
void BM_PublishFrameDelivered(benchmark::State& state) {
    lookup::localize::PoseStream stream("tcp://127.0.0.1:0", 4096);
    ReadingClient client(stream.port());
    stream.waitForClient(5);
    const auto frame = typicalFrame();
    std::size_t k = 0;
    for (auto _ : state) {
        stream.push(lookup::localize::poseMessage(frame, k++),
                    lookup::localize::PoseStream::unixTime());
        while (client.lines < k) std::this_thread::yield();
    }
    stream.close();
}
BENCHMARK(BM_PublishFrameDelivered)->Unit(benchmark::kMicrosecond)->UseRealTime();

/// The sender thread's serialisation alone.
void BM_PoseMessageSerialise(benchmark::State& state) {
    const auto frame = typicalFrame();
    std::size_t k = 0;
    for (auto _ : state) {
        auto m = lookup::localize::poseMessage(frame, k++);
        m["t_sent"] = 1.7e9;
        m["latency_ms"] = 4.3;
        benchmark::DoNotOptimize(m.dump());
    }
}
BENCHMARK(BM_PoseMessageSerialise)->Unit(benchmark::kMicrosecond);

// What the camera clock costs a refined frame once its window is full: one fix paired and the
// robust fits over the newest max_pairs pairs, the heading's and the speed changes' (a weaving
// drive at 7 m/s, odometry at 50 Hz, 14 frames/s).
void BM_CameraClockFixAndFit(benchmark::State& state) {
    lookup::common::OdometryTrack odometry;
    lookup::localize::CameraClock clock;
    const auto yaw = [](double t) { return 0.19 * std::sin(2 * M_PI * t / 5.0); };
    double t_odo = 0, t_frame = 0.5;
    const auto frame = [&] {
        for (; t_odo <= t_frame + 0.1; t_odo += 0.02)
            odometry.add(t_odo, mrpt::poses::CPose2D(7 * t_odo, 0, yaw(t_odo)));
        odometry.forgetBefore(t_frame - 3.0);
        clock.update(odometry);
        clock.addFix(t_frame, mrpt::poses::CPose2D(7 * (t_frame - 0.02), 0, yaw(t_frame - 0.02)));
        t_frame += 1 / 14.0;
    };
    for (int i = 0; i < 1200; ++i) frame();  // the window full
    for (auto _ : state) frame();
    state.counters["pairs"] = clock.estimate() ? double(clock.estimate()->pairs) : 0.0;
}
BENCHMARK(BM_CameraClockFixAndFit)->Unit(benchmark::kMicrosecond);

// What the readout estimate costs a refined frame once its window is full: one frame added
// and the robust fit over the newest max_frames frames (a drive speeding up and braking over
// references driven at about 5 m/s, a 30 ms readout nobody configured).
void BM_ReadoutEstimatorFrame(benchmark::State& state) {
    lookup::localize::ReadoutEstimator estimator({}, 0.0, 0.0);
    int k = 0;
    const auto frame = [&] {
        const double speed = 6 + 5 * std::sin(0.05 * k), survey_speed = 5 + std::sin(0.3 * k);
        const double travel =
            0.030 * speed - estimator.queryReadout() * speed + 0.005 * std::sin(1.7 * k);
        estimator.addFrame(speed, survey_speed, {travel, 0.01});
        ++k;
    };
    for (int i = 0; i < 1200; ++i) frame();  // the window full
    for (auto _ : state) frame();
    state.counters["frames"] = estimator.estimate() ? double(estimator.estimate()->frames) : 0.0;
}
BENCHMARK(BM_ReadoutEstimatorFrame)->Unit(benchmark::kMicrosecond);

}  // namespace

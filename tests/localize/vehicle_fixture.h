#pragma once
// Small synthetic runs for the vehicle-side tests (pose stream, health, restarts): a planar
// ceiling, a survey database along y = 0, query rawlogs, a loopback client, frames.csv rows.

#include <arpa/inet.h>
#include <gtest/gtest.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <nlohmann/json.hpp>
#include <opencv2/imgproc.hpp>
#include <sstream>
#include <string>
#include <vector>

#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"
#include "lookup/refine/testing/synthetic_ceiling.h"
#include "lookup/test/support.h"

namespace lookup::vehicle_test {

namespace fs = std::filesystem;

constexpr double kCeilingHeight = 5.0;
constexpr double kT0 = 1.7e9;

struct Scene {
    refine::synthetic::SyntheticCeiling ceiling;
    mrpt::img::TCamera camera = refine::synthetic::makeCamera(320, 240, 160);
    mrpt::poses::CPose3D mount = refine::synthetic::ceilingCameraOnVehicle();

    explicit Scene(int seed = 7)
        : ceiling(refine::synthetic::SyntheticCeiling::make(kCeilingHeight, 40.0, 0.01, seed)) {}

    mrpt::obs::CObservationImage::Ptr image(const mrpt::poses::CPose3D& vehicle, double t) const {
        auto obs = mrpt::obs::CObservationImage::Create();
        obs->sensorLabel = "CEILING_CAM";
        obs->timestamp = mrpt::Clock::fromDouble(t);
        obs->cameraParams = camera;
        obs->cameraPose = mount;
        obs->image =
            mrpt::img::CImage(ceiling.render(camera, vehicle + mount), mrpt::img::DEEP_COPY);
        return obs;
    }
};

/// Forward view of survey frame k: smooth random texture, distinct per frame.
inline mrpt::obs::CObservationImage::Ptr forwardView(int k, double t) {
    cv::Mat img(96, 128, CV_8UC1);
    cv::RNG rng(1000 + k);
    rng.fill(img, cv::RNG::UNIFORM, 0, 255);
    cv::GaussianBlur(img, img, cv::Size(0, 0), 3.0);
    auto obs = mrpt::obs::CObservationImage::Create();
    obs->sensorLabel = "FORWARD_CAM";
    obs->timestamp = mrpt::Clock::fromDouble(t);
    obs->image = mrpt::img::CImage(img, mrpt::img::DEEP_COPY);
    return obs;
}

/// Survey of `references` every 0.25 m along y = 0 from x = -8, with forward views.
inline void writeDatabase(const Scene& scene, const std::string& dir, int references = 65) {
    database::DatabaseWriter writer(dir);
    for (int k = 0; k < references; ++k) {
        database::ReferenceInput in;
        in.traverse = "survey";
        in.vehicle_pose = mrpt::poses::CPose3D(-8 + 0.25 * k, 0, 0, 0, 0, 0);
        in.vehicle_cov.setIdentity();
        in.vehicle_cov *= 1e-4;
        in.ceiling = scene.image(in.vehicle_pose, 100.0 + 0.1 * k);
        in.forward = forwardView(k, 100.0 + 0.1 * k);
        in.forward_vehicle_pose = in.vehicle_pose;
        in.travelled_m = 0.25 * k;
        writer.add(in);
    }
    database::DatabaseInfo info;
    info.name = "synthetic";
    info.ceiling_camera = scene.camera;
    info.ceiling_height_m = kCeilingHeight;
    info.pose_source = "test";
    writer.commit(info);
}

/// The query vehicle at query frame k: re-driving the survey line 0.1 m to its left from
/// reference 10 on, one reference per frame.
inline mrpt::poses::CPose3D queryPose(int k) {
    return mrpt::poses::CPose3D(-8 + 0.25 * (k + 10), 0.1, 0, 0, 0, 0);
}

/// Query frames [first, first + count): forward then ceiling image (period_s / 10 later),
/// stamped kT0 + time_shift_s + period_s k; optionally odometry. `jump_at`/`jump_s`: from frame
/// jump_at on every stamp is jump_s earlier (a clock that jumps back).
struct QuerySpec {
    int first = 0, count = 20;
    double time_shift_s = 0;
    bool odometry = false;
    int jump_at = -1;
    double jump_s = 0;
    double period_s = 0.1;  ///< between frames (the vehicle still moves 0.25 m per frame)

    double stamp(int k) const {
        const double t = kT0 + time_shift_s + period_s * k;
        return jump_at >= 0 && k >= jump_at ? t - jump_s : t;
    }
};

inline void writeQuery(const Scene& scene, const fs::path& path, const QuerySpec& q) {
    common::RawlogWriter rawlog(path.string());
    for (int k = q.first; k < q.first + q.count; ++k) {
        const double t = q.stamp(k);
        auto forward = forwardView(k + 10, t);
        rawlog.writeWithExternalImage(*forward, "forward_" + std::to_string(k) + ".png");
        auto img = scene.image(queryPose(k), t + q.period_s / 10);
        rawlog.writeWithExternalImage(*img, "ceiling_" + std::to_string(k) + ".png");
        if (q.odometry) {
            mrpt::obs::CObservationOdometry odo;
            odo.sensorLabel = "ODOMETRY";
            odo.timestamp = img->timestamp;
            const auto p = queryPose(k);
            odo.odometry = mrpt::poses::CPose2D(p.x(), p.y(), p.yaw());
            rawlog.write(odo);
        }
    }
    rawlog.close();
}

/// One row of frames.csv (docs/run-format.md).
struct CsvFrame {
    double t = 0;
    std::string status;
    bool has_pose = false;
    double x = 0, y = 0, yaw = 0, cov_xx = 0, cov_xy = 0, cov_yy = 0, cov_tt = 0;
};

inline std::vector<CsvFrame> readFramesCsv(const fs::path& run) {
    std::ifstream in(run / "frames.csv");
    std::string line;
    std::getline(in, line);  // header
    std::vector<CsvFrame> rows;
    while (std::getline(in, line)) {
        std::vector<std::string> f;
        std::stringstream s(line);
        std::string field;
        while (std::getline(s, field, ',')) f.push_back(field);
        CsvFrame r;
        r.t = std::stod(f.at(0));
        r.status = f.at(1);
        r.has_pose = f.size() > 3 && !f.at(3).empty();
        if (r.has_pose) {
            r.x = std::stod(f.at(3)), r.y = std::stod(f.at(4)), r.yaw = std::stod(f.at(5));
            r.cov_xx = std::stod(f.at(6)), r.cov_xy = std::stod(f.at(7));
            r.cov_yy = std::stod(f.at(8)), r.cov_tt = std::stod(f.at(9));
        }
        rows.push_back(r);
    }
    return rows;
}

/// A loopback port free at the time of the call.
inline int freePort(int type = SOCK_STREAM) {
    const int fd = socket(AF_INET, type, 0);
    sockaddr_in a{};
    a.sin_family = AF_INET;
    a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    bind(fd, reinterpret_cast<sockaddr*>(&a), sizeof a);
    socklen_t len = sizeof a;
    getsockname(fd, reinterpret_cast<sockaddr*>(&a), &len);
    close(fd);
    return ntohs(a.sin_port);
}

/// Connects to 127.0.0.1:port, retrying for up to `timeout_s`. Returns the socket or -1.
inline int connectLoopback(int port, double timeout_s = 20) {
    for (double waited = 0; waited < timeout_s; waited += 0.005) {
        const int fd = socket(AF_INET, SOCK_STREAM, 0);
        sockaddr_in a{};
        a.sin_family = AF_INET;
        a.sin_port = htons(static_cast<uint16_t>(port));
        a.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
        if (connect(fd, reinterpret_cast<sockaddr*>(&a), sizeof a) == 0) return fd;
        close(fd);
        usleep(5000);
    }
    return -1;
}

/// Reads newline-separated JSON objects from `fd` until the peer closes it.
inline std::vector<nlohmann::json> readJsonLines(int fd) {
    std::string buffer;
    char chunk[4096];
    for (ssize_t n; (n = recv(fd, chunk, sizeof chunk, 0)) > 0;) buffer.append(chunk, n);
    close(fd);
    std::vector<nlohmann::json> out;
    std::stringstream s(buffer);
    for (std::string line; std::getline(s, line);) out.push_back(nlohmann::json::parse(line));
    return out;
}

/// Asserts that pose message `m` reports frames.csv row `r` (the CSV rounds).
inline void expectSameFrame(const nlohmann::json& m, const CsvFrame& r) {
    EXPECT_NEAR(m.at("t_image").get<double>(), r.t, 1e-6);
    EXPECT_EQ(m.at("status").get<std::string>(), r.status);
    ASSERT_EQ(!m.at("x").is_null(), r.has_pose);
    if (!r.has_pose) return;
    EXPECT_NEAR(m.at("x").get<double>(), r.x, 1e-5);
    EXPECT_NEAR(m.at("y").get<double>(), r.y, 1e-5);
    EXPECT_NEAR(m.at("yaw").get<double>(), r.yaw, 1e-6);
    const auto& cov = m.at("cov");
    ASSERT_EQ(cov.size(), 9u);
    const auto near = [](double a, double b) {
        return std::abs(a - b) <= 1e-3 * std::abs(b) + 1e-12;
    };
    EXPECT_TRUE(near(cov[0].get<double>(), r.cov_xx)) << cov[0] << " vs " << r.cov_xx;
    EXPECT_TRUE(near(cov[1].get<double>(), r.cov_xy)) << cov[1] << " vs " << r.cov_xy;
    EXPECT_TRUE(near(cov[4].get<double>(), r.cov_yy)) << cov[4] << " vs " << r.cov_yy;
    EXPECT_TRUE(near(cov[8].get<double>(), r.cov_tt)) << cov[8] << " vs " << r.cov_tt;
    EXPECT_TRUE(near(cov[1].get<double>(), cov[3].get<double>()));  // symmetric
}

}  // namespace lookup::vehicle_test

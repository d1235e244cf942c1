#include "fixture.h"

#include <mrpt/obs/CObservationImage.h>

#include <cmath>
#include <opencv2/imgproc.hpp>

#include "lookup/common/rawlog_io.h"
#include "lookup/database/database_writer.h"

namespace fs = std::filesystem;

namespace lookup::fcn::fixture {

PipeScene::PipeScene() {
    using refine::synthetic::SyntheticCeiling;
    ceiling = SyntheticCeiling::make(kCeilingHeight, 24.0, 0.02, 7);
    pipes = SyntheticCeiling::make(kPipeHeight, 24.0, 0.02, 11);
    mask = pipes;
    // Pipes: 0.6 m wide bands across the tunnel (constant x) every 2 m, bright with stripes
    // along x plus fine noise, so they are matchable but move with their own parallax.
    const int n = pipes.texture.cols;
    mask.texture = cv::Mat::zeros(n, n, CV_8UC1);
    cv::Mat stripes(n, n, CV_8UC1);
    for (int r = 0; r < n; ++r) {
        for (int c = 0; c < n; ++c) {
            const double x_m = pipes.x0_m + c * pipes.metres_per_px;
            const double in_band = std::fmod(x_m + 100.0, 2.0);
            mask.texture.at<uchar>(r, c) = in_band < 0.6 ? 255 : 0;
            const double s = 180 + 50 * std::sin(2 * M_PI * x_m / 0.09);
            stripes.at<uchar>(r, c) =
                cv::saturate_cast<uchar>(s + 0.25 * (pipes.texture.at<uchar>(r, c) - 128));
        }
    }
    pipes.texture = stripes;
    camera = refine::synthetic::makeCamera(160, 120, 80);
    mount = refine::synthetic::ceilingCameraOnVehicle();
}

cv::Mat PipeScene::render(const mrpt::poses::CPose3D& vehicle) const {
    const auto cam = vehicle + mount;
    cv::Mat image = ceiling.render(camera, cam);
    pipes.render(camera, cam).copyTo(image, pipeMask(vehicle));
    return image;
}

cv::Mat PipeScene::pipeMask(const mrpt::poses::CPose3D& vehicle) const {
    cv::Mat m = mask.render(camera, vehicle + mount);
    cv::threshold(m, m, 127, 255, cv::THRESH_BINARY);
    return m;
}

const PipeScene& scene() {
    static const PipeScene s;
    return s;
}

namespace {
mrpt::obs::CObservationImage::Ptr observation(const mrpt::poses::CPose3D& vehicle, double t) {
    auto obs = mrpt::obs::CObservationImage::Create();
    obs->sensorLabel = "CEILING_CAM";
    obs->timestamp = mrpt::Clock::fromDouble(t);
    obs->cameraParams = scene().camera;
    obs->cameraPose = scene().mount;
    obs->image = mrpt::img::CImage(scene().render(vehicle), mrpt::img::DEEP_COPY);
    return obs;
}
}  // namespace

void writeDatabase(const std::string& dir, const std::vector<double>& xs) {
    database::DatabaseWriter writer(dir);
    for (std::size_t k = 0; k < xs.size(); ++k) {
        database::ReferenceInput in;
        in.traverse = "survey";
        in.vehicle_pose = mrpt::poses::CPose3D(xs[k], 0, 0, 0, 0, 0);
        in.vehicle_cov.setIdentity();
        in.vehicle_cov *= 1e-4;
        in.ceiling = observation(in.vehicle_pose, 100.0 + 0.1 * k);
        writer.add(in);
    }
    database::DatabaseInfo info;
    info.name = "fcn-fixture";
    info.ceiling_camera = scene().camera;
    info.ceiling_height_m = kCeilingHeight;
    info.pose_source = "test";
    writer.commit(info);
}

void writeQuery(const std::string& rawlog, const common::PoseTrack& track) {
    common::RawlogWriter writer(rawlog);
    for (std::size_t i = 0; i < track.size(); ++i) {
        auto obs = observation(track[i].pose, track[i].time_s);
        writer.writeWithExternalImage(*obs, "ceiling_" + std::to_string(i) + ".png");
    }
    writer.close();
    common::writeMrptPoseFile(posesFile(rawlog), track);
}

std::string posesFile(const std::string& rawlog) { return rawlog + ".poses.txt"; }

common::PoseTrack drive(double x0, double x1, double step, double y) {
    common::PoseTrack track;
    int i = 0;
    for (double x = x0; x <= x1 + 1e-9; x += step, ++i) {
        track.push_back({kT0 + 0.1 * i, mrpt::poses::CPose3D(x, y, 0, 0.02 * std::sin(x), 0, 0)});
    }
    return track;
}

TrainOptions smallOptions() {
    TrainOptions o;
    o.network.base_channels = 8;
    o.network.max_channels = 32;
    o.network.depth = 3;
    o.network.input_scale = 0.5;
    o.labels.grid_step_px = 8;
    o.labels.references_per_query = 2;
    o.labels.query_stride = 1;
    o.labels.held_out_share = 0.25;
    o.labels.min_time_gap_s = 1.0;
    o.labels.matcher.patch_px = 20;
    o.labels.matcher.search_range_px = 24;
    o.labels.matcher.pyramid_levels = 1;
    o.training.epochs = 25;
    o.training.batch_size = 4;
    o.training.learning_rate = 3e-3;
    o.training.threads = 1;  // tiny tensors: a second thread only adds OpenMP overhead
    return o;
}

}  // namespace lookup::fcn::fixture

#include "lookup/refine/testing/synthetic_ceiling.h"

#include <opencv2/imgproc.hpp>

namespace lookup::refine::synthetic {

cv::Mat makeNoiseTexture(cv::Size size, std::uint64_t seed, int octaves) {
    cv::RNG rng(seed);
    cv::Mat sum = cv::Mat::zeros(size, CV_32F);
    double weight = 1.0;
    for (int k = 0; k < octaves; ++k) {
        // Finest octave: noise at 1/2 resolution so the texture stays smooth at pixel scale.
        const int div = 2 << (octaves - 1 - k);
        const cv::Size small(std::max(2, size.width / div), std::max(2, size.height / div));
        cv::Mat noise(small, CV_32F);
        rng.fill(noise, cv::RNG::UNIFORM, 0.0, 1.0);
        cv::Mat up;
        cv::resize(noise, up, size, 0, 0, cv::INTER_CUBIC);
        sum += up * weight;
        weight *= 0.8;
    }
    cv::Mat out;
    cv::normalize(sum, sum, 0, 255, cv::NORM_MINMAX);
    sum.convertTo(out, CV_8U);
    return out;
}

mrpt::img::TCamera makeCamera(int width, int height, double focal_px) {
    mrpt::img::TCamera c;
    c.ncols = width;
    c.nrows = height;
    c.setIntrinsicParamsFromValues(focal_px, focal_px, (width - 1) / 2.0, (height - 1) / 2.0);
    return c;
}

mrpt::poses::CPose3D ceilingCameraOnVehicle() { return mrpt::poses::CPose3D(0, 0, 1.5, 0, 0, 0); }

SyntheticCeiling SyntheticCeiling::make(double height_m, double size_m, double metres_per_px,
                                        std::uint64_t seed) {
    SyntheticCeiling c;
    const int n = int(size_m / metres_per_px);
    c.texture = makeNoiseTexture(cv::Size(n, n), seed);
    c.height_m = height_m;
    c.metres_per_px = metres_per_px;
    c.x0_m = c.y0_m = -size_m / 2;
    return c;
}

namespace {

// Texture pixel -> image pixel of a camera at `camera_in_map`: K R^T [e1 e2 (0, 0, h) - t] T.
cv::Matx33d textureToPixel(const SyntheticCeiling& c, const mrpt::img::TCamera& camera,
                           const mrpt::poses::CPose3D& camera_in_map) {
    const auto R = camera_in_map.getRotationMatrix();
    cv::Matx33d Rt;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Rt(i, j) = R(j, i);
    const cv::Matx33d M(1, 0, -camera_in_map.x(), 0, 1, -camera_in_map.y(), 0, 0,
                        c.height_m - camera_in_map.z());
    const cv::Matx33d T(c.metres_per_px, 0, c.x0_m, 0, c.metres_per_px, c.y0_m, 0, 0, 1);
    const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
    return K * Rt * M * T;
}

}  // namespace

cv::Mat SyntheticCeiling::renderRollingShutter(const mrpt::img::TCamera& camera,
                                               const mrpt::poses::CPose3D& camera_on_vehicle,
                                               const mrpt::poses::CPose3D& vehicle_in_map,
                                               RowTiming timing) const {
    const cv::Size size(int(camera.ncols), int(camera.nrows));
    if (timing.rows == 0) timing.rows = size.height;
    const mrpt::poses::CPose3D camera_in_map = vehicle_in_map + camera_on_vehicle;
    cv::Mat map_x(size, CV_32F), map_y(size, CV_32F);
    for (int v = 0; v < size.height; ++v) {
        const cv::Matx33d to_texture =
            textureToPixel(*this, camera, timing.cameraAtRow(camera_in_map, camera_on_vehicle, v))
                .inv();
        for (int u = 0; u < size.width; ++u) {
            const cv::Vec3d t = to_texture * cv::Vec3d(u, v, 1.0);
            map_x.at<float>(v, u) = float(t[0] / t[2]);
            map_y.at<float>(v, u) = float(t[1] / t[2]);
        }
    }
    cv::Mat out;
    cv::remap(texture, out, map_x, map_y, cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    return out;
}

cv::Mat SyntheticCeiling::render(const mrpt::img::TCamera& camera,
                                 const mrpt::poses::CPose3D& camera_in_map) const {
    // texture px -> plane (x, y, 1) -> camera: K R^T [e1 e2 (0, 0, h) - t].
    const auto R = camera_in_map.getRotationMatrix();
    cv::Matx33d Rt;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) Rt(i, j) = R(j, i);
    const cv::Matx33d M(1, 0, -camera_in_map.x(), 0, 1, -camera_in_map.y(), 0, 0,
                        height_m - camera_in_map.z());
    const cv::Matx33d T(metres_per_px, 0, x0_m, 0, metres_per_px, y0_m, 0, 0, 1);
    const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
    const cv::Matx33d H = K * Rt * M * T;
    cv::Mat out;
    cv::warpPerspective(texture, out, H, cv::Size(int(camera.ncols), int(camera.nrows)),
                        cv::INTER_LINEAR, cv::BORDER_CONSTANT, cv::Scalar(0));
    return out;
}

ReferenceImage SyntheticCeiling::reference(std::int64_t id, const mrpt::img::TCamera& camera,
                                           const mrpt::poses::CPose3D& camera_on_vehicle,
                                           const mrpt::poses::CPose3D& vehicle_in_map) const {
    ReferenceImage r;
    r.id = id;
    r.camera = camera;
    r.camera_on_vehicle = camera_on_vehicle;
    r.vehicle_in_map = vehicle_in_map;
    r.image = render(camera, vehicle_in_map + camera_on_vehicle);
    return r;
}

}  // namespace lookup::refine::synthetic

#include "lookup/refine/geometry.h"

#include "lookup/refine/rolling_shutter.h"

#include <Eigen/Dense>

#include <cmath>
#include <numeric>
#include <opencv2/calib3d.hpp>

namespace lookup::refine {

bool pinholeFrom(const mrpt::img::TCamera& camera, Pinhole& out, std::string* why) {
    out = {camera.fx(), camera.fy(), camera.cx(), camera.cy()};
    const bool finite = std::isfinite(out.fx) && std::isfinite(out.fy) && std::isfinite(out.cx) &&
                        std::isfinite(out.cy);
    if (!finite || out.fx <= 0.0 || out.fy <= 0.0) {
        if (why) {
            *why = "invalid intrinsics (fx=" + std::to_string(out.fx) +
                   ", fy=" + std::to_string(out.fy) + ", cx=" + std::to_string(out.cx) +
                   ", cy=" + std::to_string(out.cy) + ")";
        }
        return false;
    }
    return true;
}

bool hasDistortion(const mrpt::img::TCamera& camera) {
    for (double d : camera.dist) {
        if (d != 0.0) return true;
    }
    return false;
}

namespace {

// OpenCV's undistortPoints iterates a fixed point that converges slowly, or not at all, towards
// the rim of a strong barrel lens (docs/benchmarks.md, "Pixels undistorted to convergence").
// Newton's method on OpenCV's own lens model (projectPoints, whose Jacobian in the translation
// is the one in the point for a point at depth 1) converges on the whole image of a lens whose
// radius grows monotonically.
std::vector<cv::Point2d> newtonUndistort(const std::vector<cv::Point2f>& px, const cv::Matx33d& K,
                                         const std::vector<double>& dist) {
    constexpr int kMaxIterations = 20;
    constexpr double kTolerancePx = 1e-6;
    std::vector<cv::Point3d> rays;  // pixels at depth 1, starting from where they were recorded
    for (const auto& p : px) {
        rays.emplace_back((p.x - K(0, 2)) / K(0, 0), (p.y - K(1, 2)) / K(1, 1), 1);
    }
    std::vector<std::size_t> pending(px.size());
    std::iota(pending.begin(), pending.end(), 0);
    std::vector<cv::Point3d> now;
    std::vector<cv::Point2d> at;
    cv::Mat jacobian;
    for (int it = 0; it < kMaxIterations && !pending.empty(); ++it) {
        now.clear();
        for (std::size_t i : pending) now.push_back(rays[i]);
        cv::projectPoints(now, cv::Vec3d::zeros(), cv::Vec3d::zeros(), K, dist, at, jacobian);
        std::vector<std::size_t> still;
        for (std::size_t k = 0; k < pending.size(); ++k) {
            const std::size_t i = pending[k];
            const Eigen::Vector2d e(at[k].x - px[i].x, at[k].y - px[i].y);
            if (e.norm() < kTolerancePx) continue;
            Eigen::Matrix2d J;  // d pixel / d (x, y) of the ray: the translation's columns 3, 4
            J << jacobian.at<double>(2 * k, 3), jacobian.at<double>(2 * k, 4),
                jacobian.at<double>(2 * k + 1, 3), jacobian.at<double>(2 * k + 1, 4);
            if (!(std::abs(J.determinant()) > 1e-12)) continue;  // past the lens's fold
            const Eigen::Vector2d step = J.partialPivLu().solve(e);
            rays[i].x -= step.x();
            rays[i].y -= step.y();
            still.push_back(i);
        }
        pending.swap(still);
    }
    std::vector<cv::Point2d> out;
    out.reserve(rays.size());
    for (const auto& r : rays) out.emplace_back(K(0, 0) * r.x + K(0, 2), K(1, 1) * r.y + K(1, 2));
    return out;
}

}  // namespace

std::vector<cv::Point2d> undistortPixels(const std::vector<cv::Point2f>& px,
                                         const mrpt::img::TCamera& camera) {
    std::vector<cv::Point2d> out(px.begin(), px.end());
    if (px.empty() || !hasDistortion(camera)) return out;
    const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
    if (camera.distortion == mrpt::img::DistortionModel::kannala_brandt) {
        std::vector<cv::Point2f> undistorted;
        const cv::Vec4d d(camera.k1(), camera.k2(), camera.k3(), camera.k4());
        cv::fisheye::undistortPoints(px, undistorted, K, d, cv::noArray(), K);
        return {undistorted.begin(), undistorted.end()};
    }
    return newtonUndistort(px, K, std::vector<double>(camera.dist.begin(), camera.dist.end()));
}

std::vector<cv::Point2d> distortPixels(const std::vector<cv::Point2f>& px,
                                       const mrpt::img::TCamera& camera) {
    std::vector<cv::Point2d> out(px.begin(), px.end());
    if (px.empty() || !hasDistortion(camera)) return out;
    const cv::Matx33d K(camera.fx(), 0, camera.cx(), 0, camera.fy(), camera.cy(), 0, 0, 1);
    std::vector<cv::Point2d> distorted;
    if (camera.distortion == mrpt::img::DistortionModel::kannala_brandt) {
        std::vector<cv::Point2d> normalised;
        for (const auto& p : px) {
            normalised.emplace_back((p.x - camera.cx()) / camera.fx(),
                                    (p.y - camera.cy()) / camera.fy());
        }
        const cv::Vec4d d(camera.k1(), camera.k2(), camera.k3(), camera.k4());
        cv::fisheye::distortPoints(normalised, distorted, K, d);
    } else {
        std::vector<cv::Point3d> rays;
        for (const auto& p : px) {
            rays.emplace_back((p.x - camera.cx()) / camera.fx(), (p.y - camera.cy()) / camera.fy(),
                              1.0);
        }
        const std::vector<double> d(camera.dist.begin(), camera.dist.end());
        cv::projectPoints(rays, cv::Vec3d(0, 0, 0), cv::Vec3d(0, 0, 0), K, d, distorted);
    }
    return distorted;
}

std::optional<cv::Point3d> backProjectToCeiling(const Pinhole& c,
                                                const mrpt::poses::CPose3D& camera_in_map,
                                                const cv::Point2d& px, double h) {
    const auto R = camera_in_map.getRotationMatrix();
    const double rx = (px.x - c.cx) / c.fx, ry = (px.y - c.cy) / c.fy;
    const double d[3] = {R(0, 0) * rx + R(0, 1) * ry + R(0, 2),
                         R(1, 0) * rx + R(1, 1) * ry + R(1, 2),
                         R(2, 0) * rx + R(2, 1) * ry + R(2, 2)};
    if (std::abs(d[2]) < 1e-12) return std::nullopt;
    const double lambda = (h - camera_in_map.z()) / d[2];
    if (!(lambda > 0.0)) return std::nullopt;
    return cv::Point3d(camera_in_map.x() + lambda * d[0], camera_in_map.y() + lambda * d[1], h);
}

std::optional<cv::Point2d> projectToImage(const Pinhole& c,
                                          const mrpt::poses::CPose3D& camera_in_map,
                                          const cv::Point3d& p) {
    double lx = 0, ly = 0, lz = 0;
    camera_in_map.inverseComposePoint(p.x, p.y, p.z, lx, ly, lz);
    if (!(lz > 1e-9)) return std::nullopt;
    return cv::Point2d(c.fx * lx / lz + c.cx, c.fy * ly / lz + c.cy);
}

namespace {
bool planar(const mrpt::poses::CPose3D& p) {
    return p.z() == 0.0 && p.pitch() == 0.0 && p.roll() == 0.0;
}
}  // namespace

std::optional<mrpt::poses::CPose3D> floorFrame(const std::vector<mrpt::poses::CPose3D>& vehicles) {
    Eigen::Vector3d mean = Eigen::Vector3d::Zero(), up = Eigen::Vector3d::Zero();
    const mrpt::poses::CPose3D* first = nullptr;
    int n = 0;
    for (const auto& p : vehicles) {
        if (planar(p)) continue;
        first = first ? first : &p;
        mean += Eigen::Vector3d(p.x(), p.y(), p.z());
        up += p.getRotationMatrix().asEigen().col(2);
        ++n;
    }
    if (n == 0) return std::nullopt;
    mean /= double(n);
    up.normalize();
    Eigen::Vector3d x(std::cos(first->yaw()), std::sin(first->yaw()), 0.0);
    x = (x - x.dot(up) * up).normalized();
    mrpt::math::CMatrixDouble33 R;
    R.asEigen() << x, up.cross(x), up;
    return mrpt::poses::CPose3D::FromRotationAndTranslation(R, mean);
}

double floorHeightAt(const mrpt::poses::CPose3D& floor, double x, double y) {
    const Eigen::Vector3d up = floor.getRotationMatrix().asEigen().col(2);
    return floor.z() - (up.x() * (x - floor.x()) + up.y() * (y - floor.y())) / up.z();
}

mrpt::poses::CPose3D inFloorFrame(const mrpt::poses::CPose3D& pose,
                                  const mrpt::poses::CPose3D& floor) {
    if (!planar(pose)) return pose - floor;
    const double z = floorHeightAt(floor, pose.x(), pose.y());
    const mrpt::poses::CPose3D local =
        mrpt::poses::CPose3D(pose.x(), pose.y(), z, pose.yaw(), 0, 0) - floor;
    return mrpt::poses::CPose3D(local.x(), local.y(), 0.0, local.yaw(), 0.0, 0.0);
}

cv::Matx33d ceilingHomography(const Pinhole& a, const mrpt::poses::CPose3D& a_in_map,
                              const Pinhole& b, const mrpt::poses::CPose3D& b_in_map, double h) {
    // Plane coordinates (x, y, 1) -> pixel: K R^T [e1 e2 (0,0,h) - t].
    const auto planeToPixel = [h](const Pinhole& c, const mrpt::poses::CPose3D& pose) {
        const auto R = pose.getRotationMatrix();
        cv::Matx33d Rt;
        for (int i = 0; i < 3; ++i)
            for (int j = 0; j < 3; ++j) Rt(i, j) = R(j, i);
        const cv::Matx33d M(1, 0, -pose.x(), 0, 1, -pose.y(), 0, 0, h - pose.z());
        return c.K() * Rt * M;
    };
    const cv::Matx33d H = planeToPixel(b, b_in_map) * planeToPixel(a, a_in_map).inv();
    return H * (1.0 / H(2, 2));
}

bool applyHomography(const cv::Matx33d& H, const cv::Point2d& p, cv::Point2d& out) {
    const cv::Vec3d v = H * cv::Vec3d(p.x, p.y, 1.0);
    if (!(std::abs(v[2]) > 1e-12)) return false;
    out = {v[0] / v[2], v[1] / v[2]};
    return std::isfinite(out.x) && std::isfinite(out.y);
}

mrpt::poses::CPose2D RowTiming::motionAtRow(double v) const {
    const double dt = timeOfRow(v);
    // Constant velocity on an arc: the chord points along the mean heading over dt.
    const double dyaw = velocity.yaw_rate_radps * dt, mid = 0.5 * dyaw;
    const double c = std::cos(mid), s = std::sin(mid);
    return {(c * velocity.vx_mps - s * velocity.vy_mps) * dt,
            (s * velocity.vx_mps + c * velocity.vy_mps) * dt, dyaw};
}

mrpt::poses::CPose3D RowTiming::cameraAtRow(const mrpt::poses::CPose3D& camera_in_map,
                                            const mrpt::poses::CPose3D& camera_on_vehicle,
                                            double v) const {
    mrpt::poses::CPose3D vehicle_to_camera_inv = camera_on_vehicle;
    vehicle_to_camera_inv.inverse();
    const mrpt::poses::CPose3D vehicle = camera_in_map + vehicle_to_camera_inv;
    return vehicle + mrpt::poses::CPose3D(motionAtRow(v)) + camera_on_vehicle;
}

}  // namespace lookup::refine

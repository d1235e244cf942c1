#include "lookup/sim/camera_renderer.h"

#include "noise.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <thread>

namespace lookup::sim {
namespace {

using Eigen::Vector2d;
using Eigen::Vector3d;
using namespace detail;

constexpr double kLampPower = 0.8;  // tunnel lamp intensity (headlight at nominal range = 1)
constexpr double kAmbient = 0.02;

/// Ray o + t d against a finite cylinder; t of the entry point and its outward normal.
bool intersectCylinder(const Cylinder& c, const Vector3d& o, const Vector3d& d, double* t,
                       Vector3d* n) {
    const Vector3d oc = o - c.a;
    const double dd = d.dot(c.axis), od = oc.dot(c.axis);
    const Vector3d dp = d - dd * c.axis, op = oc - od * c.axis;
    const double A = dp.squaredNorm();
    if (A < 1e-12) return false;
    const double B = 2 * dp.dot(op), C = op.squaredNorm() - c.radius * c.radius;
    const double disc = B * B - 4 * A * C;
    if (disc < 0) return false;
    const double tt = (-B - std::sqrt(disc)) / (2 * A);
    if (tt <= 1e-3) return false;
    const double along = od + tt * dd;
    if (along < 0 || along > c.length) return false;
    *t = tt;
    *n = (op + tt * dp).normalized();
    return true;
}

bool intersectSphere(const Vector3d& centre, double radius, const Vector3d& o, const Vector3d& d,
                     double* t) {
    const Vector3d oc = o - centre;
    const double b = oc.dot(d), c = oc.squaredNorm() - radius * radius;
    const double disc = b * b - c;
    if (disc < 0) return false;
    const double tt = -b - std::sqrt(disc);
    if (tt <= 1e-3) return false;
    *t = tt;
    return true;
}

double distanceToBox(const Vector3d& p, const Vector3d& lo, const Vector3d& hi) {
    return (p.cwiseMax(lo).cwiseMin(hi) - p).norm();
}

}  // namespace

CameraRenderer::CameraRenderer(const TunnelWorld& world, const CameraOptions& camera, Kind kind,
                               int threads)
    : world_(world), opt_(camera), kind_(kind) {
    threads_ = threads > 0 ? threads : std::max(1u, std::thread::hardware_concurrency());
    const double f = (opt_.width_px / 2.0) / std::tan(opt_.hfov_deg * M_PI / 360.0);
    const double cx = (opt_.width_px - 1) / 2.0, cy = (opt_.height_px - 1) / 2.0;
    camera_.ncols = opt_.width_px;
    camera_.nrows = opt_.height_px;
    camera_.setIntrinsicParamsFromValues(f, f, cx, cy);
    camera_.setDistortionPlumbBob(0, 0, 0, 0, 0);
    camera_.cameraName = opt_.label;
    camera_.focalLengthMeters = 0.004;
    rays_.resize(static_cast<std::size_t>(opt_.width_px) * opt_.height_px);
    for (int v = 0; v < opt_.height_px; ++v) {
        for (int u = 0; u < opt_.width_px; ++u) {
            rays_[v * opt_.width_px + u] = Vector3d((u - cx) / f, (v - cy) / f, 1).normalized();
        }
    }
    beam_.resize(rays_.size());
    for (std::size_t i = 0; i < rays_.size(); ++i) {
        beam_[i] = std::pow(std::max(rays_[i].z(), 0.0), opt_.light_falloff_exp);
    }
    half_diag_fov_ = std::atan(std::hypot(cx + 0.5, cy + 0.5) / f);
}

double CameraRenderer::shadePixel(int index, const Eigen::Matrix3d& R, const Vector3d& o,
                                  const std::vector<ObjectInView>& cylinders,
                                  const std::vector<int>& lamps) const {
    const WorldOptions& w = world_.options();
    const Vector3d& ray = rays_[index];
    const Vector3d d = R * ray;
    const double cos_axis = ray.z();
    const double fx = camera_.fx();

    // Static surfaces. Looking up, the roof is found by fixed-point iteration on the relief;
    // the general marcher handles the arches, walls and steep rays.
    SurfaceHit hit;
    bool done = false;
    if (kind_ == Kind::Ceiling && d.z() > 0.3) {
        const double h = w.ceiling_height_m;
        // Flat part: fixed-point iteration on the relief alone.
        double t = (h - o.z()) / d.z();
        for (int k = 0; k < 3; ++k) {
            const Vector3d p = o + t * d;
            t = (world_.roofHeight(p.x(), p.y(), 1e9) - o.z()) / d.z();
        }
        Vector3d p = o + t * d;
        WallQuery q = world_.query(p.x(), p.y());
        if (-q.sdf > w.arch_radius_m + 0.05 &&
            std::abs(world_.roofHeight(p.x(), p.y(), -q.sdf) - p.z()) < 0.002) {
            hit.t = t;
            hit.kind = SurfaceKind::Roof;
            hit.q = q;
            done = true;
        } else {
            // Arches: regula falsi (Illinois) on G(t) = z(t) - roof(t) between a point below the
            // lowest roof and one above the highest, both inside the tunnel.
            auto G = [&](double tt, WallQuery* qq) {
                const Vector3d pp = o + tt * d;
                *qq = world_.query(pp.x(), pp.y());
                const double dw = -qq->sdf;
                return dw <= 0 ? 0.05 - dw : pp.z() - world_.roofHeight(pp.x(), pp.y(), dw);
            };
            double ta =
                std::max(0.02, (h - w.arch_radius_m - w.bump_amplitude_m - 0.02 - o.z()) / d.z());
            double tb = (h + w.bump_amplitude_m + 0.02 - o.z()) / d.z();
            WallQuery qa, qb;
            double ga = G(ta, &qa), gb = G(tb, &qb);
            if (ga < 0 && -qa.sdf > 0 && gb > 0) {
                int side = 0;
                for (int k = 0; k < 14; ++k) {
                    const double tt = ta - ga * (tb - ta) / (gb - ga);
                    WallQuery qt;
                    const double gt = G(tt, &qt);
                    if (gt < 0) {
                        ta = tt;
                        ga = gt;
                        if (side == -1) gb *= 0.5;
                        side = -1;
                    } else {
                        tb = tt;
                        gb = gt;
                        qb = qt;
                        if (side == 1) ga *= 0.5;
                        side = 1;
                    }
                    if (tb - ta < std::max(0.002, 0.3 * tb / fx) || std::abs(gt) < 0.001) break;
                }
                hit.t = tb;
                hit.q = qb;
                hit.kind = -qb.sdf <= 0.01 ? SurfaceKind::Wall : SurfaceKind::Roof;
                done = true;
            }
        }
    }
    if (!done) hit = world_.traceStatic(o, d, 0.02, opt_.max_range_m, 1.0 / fx);

    // Furniture in front of it.
    double t_best = hit.t;
    Vector3d n_obj;
    int obj = -1;
    const int pu = index % opt_.width_px, pv = index / opt_.width_px;
    for (const ObjectInView& c : cylinders) {
        if (pu < c.u0 || pu > c.u1 || pv < c.v0 || pv > c.v1) continue;
        double t;
        Vector3d n;
        if (intersectCylinder(world_.cylinders()[c.index], o, d, &t, &n) && t < t_best) {
            t_best = t;
            n_obj = n;
            obj = c.index;
        }
    }
    for (int li : lamps) {
        double t;
        const Lamp& l = world_.lamps()[li];
        if (intersectSphere(l.centre, l.radius, o, d, &t) && t < t_best) return 6.0;  // saturates
    }
    if (!std::isfinite(t_best) || t_best > opt_.max_range_m) return 0.0;

    const Vector3d p = o + t_best * d;
    Vector3d n;
    double albedo;
    const double fp = t_best / (fx * std::max(cos_axis, 0.2));  // pixel footprint [m]
    if (obj >= 0) {
        n = n_obj;
        albedo = world_.objectAlbedo(world_.cylinders()[obj], p);
    } else if (hit.kind == SurfaceKind::Roof) {
        Vector2d g = world_.roofSlope(p.x(), p.y(), hit.q);
        const double obl = std::max(std::abs(d.z()), 0.2);
        albedo = world_.roofAlbedo(p.x(), p.y(), hit.q, fp / obl, &g.x(), &g.y());
        n = Vector3d(g.x(), g.y(), -1).normalized();
    } else if (hit.kind == SurfaceKind::Wall) {
        const Vector2d a = world_.awayFromWall(p.x(), p.y(), hit.q);
        n = Vector3d(a.x(), a.y(), 0);
        const double obl = std::max(std::abs(n.dot(d)), 0.2);
        albedo = world_.wallAlbedo(hit.q, p.z(), fp / obl);
    } else {
        n = Vector3d(0, 0, 1);
        albedo = world_.floorAlbedo(p.x(), p.y(), fp / std::max(std::abs(d.z()), 0.2));
    }

    // Vehicle light at the camera, along its optical axis.
    const double r0 = kind_ == Kind::Ceiling ? std::max(w.ceiling_height_m - o.z(), 0.5) : 6.0;
    const double beam = beam_[index];
    double e =
        opt_.light_gain * beam * std::max(0.0, -n.dot(d)) * r0 * r0 / (t_best * t_best + 0.05);
    for (int li : lamps) {
        const Vector3d to = world_.lamps()[li].centre - p;
        const double dist2 = to.squaredNorm();
        e += kLampPower * std::max(0.0, n.dot(to) / std::sqrt(dist2)) / (dist2 + 0.3);
    }
    return albedo * (e + kAmbient);
}

void CameraRenderer::renderRows(const Eigen::Matrix3d& R, const Vector3d& o,
                                const std::vector<ObjectInView>& cylinders,
                                const std::vector<int>& lamps, int first, int step,
                                float* out) const {
    for (int v = first; v < opt_.height_px; v += step) {
        for (int u = 0; u < opt_.width_px; ++u) {
            const int i = v * opt_.width_px + u;
            out[i] = static_cast<float>(shadePixel(i, R, o, cylinders, lamps));
        }
    }
}

mrpt::img::CImage CameraRenderer::render(const mrpt::poses::CPose3D& camera_in_map,
                                         const FrameConditions& frame) const {
    const Eigen::Matrix3d R = camera_in_map.getRotationMatrix().asEigen();
    const Vector3d o(camera_in_map.x(), camera_in_map.y(), camera_in_map.z());
    const WorldOptions& w = world_.options();

    // Only furniture that can be in view is tested per pixel.
    double reach = opt_.max_range_m;
    if (kind_ == Kind::Ceiling) {
        reach = std::min(reach, (w.ceiling_height_m + w.bump_amplitude_m + 0.3 - o.z()) /
                                        std::cos(std::min(half_diag_fov_, 1.4)) +
                                    1.0);
    }
    std::vector<ObjectInView> cylinders;
    std::vector<int> lamps;
    const Eigen::Matrix3d Rt = R.transpose();
    const double f = camera_.fx(), cx = camera_.cx(), cy = camera_.cy();
    for (int i = 0; i < static_cast<int>(world_.cylinders().size()); ++i) {
        const Cylinder& c = world_.cylinders()[i];
        if (distanceToBox(o, c.lo, c.hi) > reach) continue;
        // Image rectangle that holds the cylinder: its axis clipped to the front of the camera,
        // projected, widened by the radius at the nearest end (conservative).
        Vector3d a = Rt * (c.a - o), b = Rt * (c.a + c.length * c.axis - o);
        constexpr double kNear = 0.05;
        if (a.z() < kNear && b.z() < kNear) continue;
        if (a.z() < kNear) a += (b - a) * ((kNear - a.z()) / (b.z() - a.z()));
        if (b.z() < kNear) b += (a - b) * ((kNear - b.z()) / (a.z() - b.z()));
        const double grow = c.radius * f / std::min(a.z(), b.z()) + 2;
        const double ua = cx + f * a.x() / a.z(), va = cy + f * a.y() / a.z();
        const double ub = cx + f * b.x() / b.z(), vb = cy + f * b.y() / b.z();
        auto clampPx = [](double x, int hi) {
            return static_cast<int>(std::clamp(x, -1.0, static_cast<double>(hi)));
        };
        ObjectInView v;
        v.index = i;
        v.u0 = clampPx(std::floor(std::min(ua, ub) - grow), opt_.width_px);
        v.u1 = clampPx(std::ceil(std::max(ua, ub) + grow), opt_.width_px);
        v.v0 = clampPx(std::floor(std::min(va, vb) - grow), opt_.height_px);
        v.v1 = clampPx(std::ceil(std::max(va, vb) + grow), opt_.height_px);
        if (v.u1 < 0 || v.v1 < 0 || v.u0 >= opt_.width_px || v.v0 >= opt_.height_px) continue;
        cylinders.push_back(v);
    }
    for (int i = 0; i < static_cast<int>(world_.lamps().size()); ++i) {
        if ((world_.lamps()[i].centre - o).norm() <= std::max(reach, 12.0)) lamps.push_back(i);
    }

    cv::Mat radiance(opt_.height_px, opt_.width_px, CV_32F);
    float* out = radiance.ptr<float>();
    const int n = std::min(threads_, opt_.height_px);
    std::vector<std::thread> pool;
    for (int k = 1; k < n; ++k) {
        pool.emplace_back([&, k] { renderRows(R, o, cylinders, lamps, k, n, out); });
    }
    renderRows(R, o, cylinders, lamps, 0, n, out);
    for (auto& t : pool) t.join();

    // Motion blur: average of shifted copies along the image motion during the exposure.
    const double blur = std::hypot(frame.blur_u_px, frame.blur_v_px);
    if (blur >= 0.5) {
        const int samples = std::min(16, static_cast<int>(std::ceil(blur)) + 1);
        cv::Mat acc = cv::Mat::zeros(radiance.size(), CV_32F), shifted;
        for (int k = 0; k < samples; ++k) {
            const double a = (k + 0.5) / samples - 0.5;
            const cv::Matx23d M(1, 0, a * frame.blur_u_px, 0, 1, a * frame.blur_v_px);
            cv::warpAffine(radiance, shifted, M, radiance.size(), cv::INTER_LINEAR,
                           cv::BORDER_REPLICATE);
            acc += shifted;
        }
        radiance = acc / samples;
    }

    // Exposure, tone curve, shot and read noise, quantisation.
    cv::Mat img(opt_.height_px, opt_.width_px, CV_8U);
    const float* src = radiance.ptr<float>();
    uint8_t* dst = img.ptr<uint8_t>();
    const int count = opt_.width_px * opt_.height_px;
    for (int i = 0; i < count; ++i) {
        const double x = src[i] * frame.exposure_gain;
        double dn = kind_ == Kind::Ceiling ? 235.0 * x : 255.0 * (1.0 - std::exp(-2.2 * x));
        if (opt_.noise_std_dn > 0) {
            const uint32_t h = hash3(frame.noise_key, static_cast<uint32_t>(i), 1);
            const double sigma = opt_.noise_std_dn * std::sqrt(1.0 + std::max(dn, 0.0) / 64.0);
            dn += sigma * fastGaussian(h);
        }
        dst[i] = static_cast<uint8_t>(std::clamp(std::lround(dn), 0L, 255L));
    }
    return mrpt::img::CImage(img, mrpt::img::DEEP_COPY);
}

}  // namespace lookup::sim

#include "lookup/sim/camera_renderer.h"

#include "noise.h"

#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

#include <lookup/common/config.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>
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

/// Looking up at the flat part of the roof: fixed-point iteration on the relief alone, from
/// the roof level h; false where the point found is not on the roof clear of the arches.
bool roofByFixedPoint(const TunnelWorld& world, const Vector3d& o, const Vector3d& d, double h,
                      SurfaceHit* hit) {
    double t = (h - o.z()) / d.z();
    // A ramp tilts the roof under the ray and slows the iteration's convergence.
    const int iterations = world.graded() ? 10 : 3;
    for (int k = 0; k < iterations; ++k) {
        const Vector3d p = o + t * d;
        t = (world.roofHeight(p.x(), p.y(), 1e9) - o.z()) / d.z();
    }
    Vector3d p = o + t * d;
    WallQuery q = world.query(p.x(), p.y());
    if (-q.sdf > world.options().arch_radius_m + 0.05 &&
        std::abs(world.roofHeight(p.x(), p.y(), -q.sdf) - p.z()) < 0.002) {
        hit->t = t;
        hit->kind = SurfaceKind::Roof;
        hit->q = q;
        return true;
    }
    return false;
}

/// G(t) = z(t) - roof(t) along the ray, positive outside the tunnel; `q` gets the query at t.
inline double heightOverRoof(const TunnelWorld& world, const Vector3d& o, const Vector3d& d,
                             double t, WallQuery* q) {
    const Vector3d p = o + t * d;
    *q = world.query(p.x(), p.y());
    const double dw = -q->sdf;
    return dw <= 0 ? 0.05 - dw : p.z() - world.roofHeight(p.x(), p.y(), dw);
}

/// Ray parameters [ta, tb] bracketing the roof: a point below the lowest roof, one above the
/// highest.
void bracketRoof(const TunnelWorld& world, const Vector3d& o, const Vector3d& d, double h,
                 double* ta, double* tb) {
    const WorldOptions& w = world.options();
    // On a grade the roof over the ray's reach differs from the roof over the camera
    // by up to the steepest grade times the ray's plan reach.
    const double slack = world.graded() ? world.maxGrade() * std::hypot(d.x(), d.y()) *
                                              (h + w.bump_amplitude_m + 1.0 - o.z()) / d.z()
                                        : 0.0;
    *ta = std::max(0.02, (h - w.arch_radius_m - w.bump_amplitude_m - 0.02 - slack - o.z()) / d.z());
    *tb = (h + w.bump_amplitude_m + 0.02 + slack - o.z()) / d.z();
}

/// Arches: regula falsi (Illinois) on heightOverRoof between the brackets, both inside the
/// tunnel; false where they do not bracket a crossing.
bool archByRegulaFalsi(const TunnelWorld& world, const Vector3d& o, const Vector3d& d, double h,
                       double fx, SurfaceHit* hit) {
    double ta, tb;
    bracketRoof(world, o, d, h, &ta, &tb);
    WallQuery qa, qb;
    double ga = heightOverRoof(world, o, d, ta, &qa), gb = heightOverRoof(world, o, d, tb, &qb);
    if (!(ga < 0 && -qa.sdf > 0 && gb > 0)) return false;
    int side = 0;
    for (int k = 0; k < 14; ++k) {
        const double tt = ta - ga * (tb - ta) / (gb - ga);
        WallQuery qt;
        const double gt = heightOverRoof(world, o, d, tt, &qt);
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
    hit->t = tb;
    hit->q = qb;
    hit->kind = -qb.sdf <= 0.01 ? SurfaceKind::Wall : SurfaceKind::Roof;
    return true;
}

/// The fast path of a ceiling camera's upward ray (roof level h over the camera); false
/// where it fails and the general marcher must trace the ray.
bool traceRoofLookingUp(const TunnelWorld& world, const Vector3d& o, const Vector3d& d, double h,
                        double fx, SurfaceHit* hit) {
    return roofByFixedPoint(world, o, d, h, hit) || archByRegulaFalsi(world, o, d, h, fx, hit);
}

/// A tunnel lamp nearer than t_max on the ray: `depth` gets its distance.
bool lampInFront(const TunnelWorld& world, const std::vector<int>& lamps, const Vector3d& o,
                 const Vector3d& d, double t_max, double* depth) {
    for (int li : lamps) {
        double t;
        const Lamp& l = world.lamps()[li];
        if (intersectSphere(l.centre, l.radius, o, d, &t) && t < t_max) {
            *depth = t;
            return true;
        }
    }
    return false;
}

/// Albedo and normal `n` of the static surface hit at p by ray direction d; `footprint` is
/// the pixel's size at the hit, face on [m] (oblique views blur the texture over more).
double surfaceAlbedo(const TunnelWorld& world, const SurfaceHit& hit, const Vector3d& p,
                     const Vector3d& d, double footprint, Vector3d* n) {
    if (hit.kind == SurfaceKind::Roof) {
        Vector2d g = world.roofSlope(p.x(), p.y(), hit.q);
        const double obl = std::max(std::abs(d.z()), 0.2);
        const double albedo =
            world.roofAlbedo(p.x(), p.y(), hit.q, footprint / obl, &g.x(), &g.y());
        *n = Vector3d(g.x(), g.y(), -1).normalized();
        return albedo;
    }
    if (hit.kind == SurfaceKind::Wall) {
        const Vector2d a = world.awayFromWall(p.x(), p.y(), hit.q);
        *n = Vector3d(a.x(), a.y(), 0);
        const double obl = std::max(std::abs(n->dot(d)), 0.2);
        return world.wallAlbedo(hit.q, p.z(), footprint / obl);
    }
    *n = Vector3d(0, 0, 1);
    return world.floorAlbedo(p.x(), p.y(), footprint / std::max(std::abs(d.z()), 0.2));
}

/// Adds to `e` the irradiance at p (normal n) from the tunnel lamps in view, one by one (the
/// order of the sum is part of the generated bytes).
void addLampLight(const TunnelWorld& world, const std::vector<int>& lamps, const Vector3d& p,
                  const Vector3d& n, double* e) {
    for (int li : lamps) {
        const Vector3d to = world.lamps()[li].centre - p;
        const double dist2 = to.squaredNorm();
        *e += kLampPower * std::max(0.0, n.dot(to) / std::sqrt(dist2)) / (dist2 + 0.3);
    }
}

/// Dust: the scene attenuated along the ray, the haze lit by the vehicle light added.
void addHaze(cv::Mat& radiance, const std::vector<float>& depth, const CameraOptions& opt,
             const std::vector<double>& beam) {
    float* r = radiance.ptr<float>();
    for (std::size_t i = 0; i < depth.size(); ++i) {
        const double tr =
            std::isfinite(depth[i]) ? std::exp(-opt.haze_extinction_per_m * depth[i]) : 0.0;
        r[i] =
            static_cast<float>(r[i] * tr + opt.haze_airlight * opt.light_gain * beam[i] * (1 - tr));
    }
}

/// Motion blur: average of shifted copies along the image motion during the exposure.
void motionBlur(cv::Mat& radiance, const FrameConditions& frame) {
    const double blur = std::hypot(frame.blur_u_px, frame.blur_v_px);
    if (blur < 0.5) return;
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

}  // namespace

CameraRenderer::CameraRenderer(const TunnelWorld& world, const CameraOptions& camera, Kind kind,
                               int threads)
    : world_(world), opt_(camera), kind_(kind) {
    threads_ = threads > 0 ? threads : std::max(1u, std::thread::hardware_concurrency());
    const bool fisheye = opt_.distortion == "kannala_brandt";
    // A fisheye's field of view is equidistant (r = f theta), a pinhole's perspective.
    const double half = opt_.hfov_deg * M_PI / 360.0;
    const double f = (opt_.width_px / 2.0) / (fisheye ? half : std::tan(half));
    const double cx = (opt_.width_px - 1) / 2.0, cy = (opt_.height_px - 1) / 2.0;
    camera_.ncols = opt_.width_px;
    camera_.nrows = opt_.height_px;
    camera_.setIntrinsicParamsFromValues(f, f, cx, cy);
    if (fisheye) {
        camera_.setDistortionKannalaBrandt(opt_.dist_k1, opt_.dist_k2, opt_.dist_k3, opt_.dist_k4);
    } else if (opt_.distortion == "plumb_bob") {
        camera_.setDistortionPlumbBob(opt_.dist_k1, opt_.dist_k2, opt_.dist_p1, opt_.dist_p2,
                                      opt_.dist_k3);
    } else {
        camera_.setDistortionPlumbBob(0, 0, 0, 0, 0);
    }
    camera_.cameraName = opt_.label;
    camera_.focalLengthMeters = 0.004;
    buildRays();
    beam_.resize(rays_.size());
    for (std::size_t i = 0; i < rays_.size(); ++i) {
        beam_[i] = std::pow(std::max(rays_[i].z(), 0.0), opt_.light_falloff_exp);
    }
    half_diag_fov_ = 0;
    for (const Vector3d& r : rays_) half_diag_fov_ = std::max(half_diag_fov_, std::acos(r.z()));
    if (opt_.distortion == "none") half_diag_fov_ = std::atan(std::hypot(cx + 0.5, cy + 0.5) / f);
    uint32_t label_hash = 0x811c9dc5U;  // FNV-1a: the same on every platform
    for (unsigned char ch : opt_.label) label_hash = (label_hash ^ ch) * 0x01000193U;
    lens_seed_ = hash3(world_.seed(), label_hash, 0x1e45U);
    buildLensMasks();
}

void CameraRenderer::buildRays() {
    const int W = opt_.width_px, H = opt_.height_px;
    const double f = camera_.fx(), cx = camera_.cx(), cy = camera_.cy();
    rays_.resize(static_cast<std::size_t>(W) * H);
    pin_u_.resize(rays_.size());
    pin_v_.resize(rays_.size());
    const bool distorted = opt_.distortion != "none";
    pin_lo_u_ = pin_lo_v_ = 1e300;
    pin_hi_u_ = pin_hi_v_ = -1e300;
    for (int v = 0; v < H; ++v) {
        for (int u = 0; u < W; ++u) {
            const std::size_t i = static_cast<std::size_t>(v) * W + u;
            double x = (u - cx) / f, y = (v - cy) / f;
            if (distorted && !undistortPixel(camera_, u, v, &x, &y)) {
                throw common::ConfigError(opt_.label + " distortion: pixel (" + std::to_string(u) +
                                          ", " + std::to_string(v) +
                                          ") has no ray (the model folds inside the image)");
            }
            rays_[i] = Vector3d(x, y, 1).normalized();
            pin_u_[i] = static_cast<float>(distorted ? cx + f * x : u);
            pin_v_[i] = static_cast<float>(distorted ? cy + f * y : v);
            pin_lo_u_ = std::min(pin_lo_u_, double(pin_u_[i]));
            pin_hi_u_ = std::max(pin_hi_u_, double(pin_u_[i]));
            pin_lo_v_ = std::min(pin_lo_v_, double(pin_v_[i]));
            pin_hi_v_ = std::max(pin_hi_v_, double(pin_v_[i]));
            // Rays near 90 deg off-axis have no useful pinhole coordinates to cull with.
            if (rays_[i].z() < 0.1) cull_ = false;
        }
    }
}

bool CameraRenderer::undistortPixel(const mrpt::img::TCamera& K, double u, double v, double* x,
                                    double* y) {
    // Gauss-Newton on distortPoint() with a numerical Jacobian, from the distorted point.
    double X = (u - K.cx()) / K.fx(), Y = (v - K.cy()) / K.fy();
    for (int it = 0; it < 60; ++it) {
        double pu, pv;
        distortPoint(K, X, Y, &pu, &pv);
        const double eu = pu - u, ev = pv - v;
        if (std::hypot(eu, ev) < 1e-12 * std::max(1.0, K.fx())) break;
        const double h = 1e-7 * std::max(1.0, std::hypot(X, Y));
        double ux, vx, uy, vy;
        distortPoint(K, X + h, Y, &ux, &vx);
        distortPoint(K, X, Y + h, &uy, &vy);
        const double a = (ux - pu) / h, c = (vx - pv) / h, b = (uy - pu) / h, d = (vy - pv) / h;
        const double det = a * d - b * c;
        if (!(std::abs(det) > 1e-12)) return false;
        X -= (d * eu - b * ev) / det;
        Y -= (-c * eu + a * ev) / det;
    }
    double pu, pv;
    distortPoint(K, X, Y, &pu, &pv);
    *x = X;
    *y = Y;
    return std::hypot(pu - u, pv - v) < 1e-6;
}

void CameraRenderer::distortPoint(const mrpt::img::TCamera& K, double x, double y, double* u,
                                  double* v) {
    double xd = x, yd = y;
    if (K.distortion == mrpt::img::DistortionModel::kannala_brandt) {
        // OpenCV's fisheye model: theta_d = theta (1 + k1 theta^2 + ... + k4 theta^8).
        const double r = std::hypot(x, y);
        if (r > 1e-12) {
            const double th = std::atan(r), t2 = th * th;
            const double thd =
                th * (1 + t2 * (K.k1() + t2 * (K.k2() + t2 * (K.k3() + t2 * K.k4()))));
            xd = x * thd / r;
            yd = y * thd / r;
        }
    } else if (K.distortion == mrpt::img::DistortionModel::plumb_bob) {
        const double r2 = x * x + y * y;
        const double radial = 1 + r2 * (K.k1() + r2 * (K.k2() + r2 * K.k3()));
        xd = x * radial + 2 * K.p1() * x * y + K.p2() * (r2 + 2 * x * x);
        yd = y * radial + K.p1() * (r2 + 2 * y * y) + 2 * K.p2() * x * y;
    }
    *u = K.cx() + K.fx() * xd;
    *v = K.cy() + K.fy() * yd;
}

void CameraRenderer::buildLensMasks() {
    const int W = opt_.width_px, H = opt_.height_px;
    auto rnd = [this](uint32_t k, uint32_t c) { return unit(hash3(lens_seed_, k, c)); };
    if (opt_.dirt_spots > 0) {
        // Out-of-focus dirt: soft dark blotches, 4-14 % of the width across.
        dirt_.assign(static_cast<std::size_t>(W) * H, 1.0f);
        for (int k = 0; k < opt_.dirt_spots; ++k) {
            const double cu = rnd(k, 1) * W, cv = rnd(k, 2) * H;
            const double r = (0.04 + 0.1 * rnd(k, 3)) * W;
            const double op = opt_.dirt_opacity * (0.5 + 0.5 * rnd(k, 4));
            for (int v = 0; v < H; ++v) {
                for (int u = 0; u < W; ++u) {
                    const double d2 = ((u - cu) * (u - cu) + (v - cv) * (v - cv)) / (r * r);
                    if (d2 < 9) dirt_[v * W + u] *= static_cast<float>(1 - op * std::exp(-d2));
                }
            }
        }
    }
    if (opt_.water_drops > 0) {
        // Drops: discs through which the scene is defocused, a soft 2 px rim.
        drops_.assign(static_cast<std::size_t>(W) * H, 0.0f);
        for (int k = 0; k < opt_.water_drops; ++k) {
            const double cu = rnd(k, 11) * W, cv = rnd(k, 12) * H;
            const double r = opt_.drop_radius_px * (0.6 + 0.8 * rnd(k, 13));
            for (int v = 0; v < H; ++v) {
                for (int u = 0; u < W; ++u) {
                    const double d = std::hypot(u - cu, v - cv);
                    float& c = drops_[v * W + u];
                    c = std::max(c, static_cast<float>(smoothstep(r, r - 2, d)));
                }
            }
        }
    }
}

double CameraRenderer::shadePixel(int index, const View& view, double* depth) const {
    const Vector3d& o = view.o;
    const Vector3d d = view.R * rays_[index];
    const double fx = camera_.fx();
    // On a grade the roof stands on the level under the camera (the fast path's brackets
    // then fail where the ramp bends the roof, and the general marcher takes over).
    const WorldOptions& w = world_.options();
    const double h =
        world_.graded() ? w.ceiling_height_m + world_.level(o.x(), o.y()) : w.ceiling_height_m;

    // Static surfaces. Looking up, the roof is found by fixed-point iteration on the relief;
    // the general marcher handles the arches, walls and steep rays.
    SurfaceHit hit;
    const bool up = kind_ == Kind::Ceiling && d.z() > 0.3;
    if (!up || !traceRoofLookingUp(world_, o, d, h, fx, &hit)) {
        hit = world_.traceStatic(o, d, 0.02, opt_.max_range_m, 1.0 / fx);
    }

    // Furniture in front of it.
    Vector3d n = Vector3d::Zero();  // the furniture's normal, else the static surface's
    int obj = -1;
    const double t = nearestCylinder(index, view, d, hit.t, &n, &obj);
    if (lampInFront(world_, view.lamps, o, d, t, depth)) return 6.0;  // saturates
    *depth = t;
    if (!std::isfinite(t) || t > opt_.max_range_m) return 0.0;

    const Vector3d p = o + t * d;
    const double footprint = t / (fx * std::max(rays_[index].z(), 0.2));  // [m]
    const double albedo = obj >= 0 ? world_.objectAlbedo(world_.cylinders()[obj], p)
                                   : surfaceAlbedo(world_, hit, p, d, footprint, &n);

    // Vehicle light at the camera, along its optical axis.
    const double r0 = kind_ == Kind::Ceiling ? std::max(h - o.z(), 0.5) : 6.0;
    double e = opt_.light_gain * beam_[index] * std::max(0.0, -n.dot(d)) * r0 * r0 / (t * t + 0.05);
    addLampLight(world_, view.lamps, p, n, &e);
    return albedo * (e + kAmbient);
}

inline double CameraRenderer::nearestCylinder(int index, const View& view, const Vector3d& d,
                                              double t_max, Vector3d* normal, int* object) const {
    double t_best = t_max;
    const float pu = pin_u_[index], pv = pin_v_[index];
    for (const ObjectInView& c : view.cylinders) {
        if (pu < c.u0 || pu > c.u1 || pv < c.v0 || pv > c.v1) continue;
        double t;
        Vector3d n;
        if (intersectCylinder(world_.cylinders()[c.index], view.o, d, &t, &n) && t < t_best) {
            t_best = t;
            *normal = n;
            *object = c.index;
        }
    }
    return t_best;
}

void CameraRenderer::renderRows(const std::vector<View>& views, int first, int step, float* out,
                                float* depth) const {
    for (int v = first; v < opt_.height_px; v += step) {
        const View& view = views.size() == 1 ? views[0] : views[v];
        for (int u = 0; u < opt_.width_px; ++u) {
            const int i = v * opt_.width_px + u;
            double t = 0;
            out[i] = static_cast<float>(shadePixel(i, view, &t));
            depth[i] = static_cast<float>(t);
        }
    }
}

CameraRenderer::View CameraRenderer::makeView(const mrpt::poses::CPose3D& camera_in_map) const {
    View view;
    view.R = camera_in_map.getRotationMatrix().asEigen();
    view.o = Vector3d(camera_in_map.x(), camera_in_map.y(), camera_in_map.z());
    const Eigen::Matrix3d& R = view.R;
    const Vector3d& o = view.o;
    const WorldOptions& w = world_.options();

    // Only furniture that can be in view is tested per pixel.
    double reach = opt_.max_range_m;
    if (kind_ == Kind::Ceiling) {
        const double h =
            world_.graded() ? w.ceiling_height_m + world_.level(o.x(), o.y()) : w.ceiling_height_m;
        reach = std::min(
            reach,
            (h + w.bump_amplitude_m + 0.3 - o.z()) / std::cos(std::min(half_diag_fov_, 1.4)) + 1.0);
        // The roof ahead on a ramp rises or falls by up to the grade times the distance.
        if (world_.graded())
            reach = std::min(opt_.max_range_m, reach * (1 + 2 * world_.maxGrade()));
    }
    const Eigen::Matrix3d Rt = R.transpose();
    const double f = camera_.fx(), cx = camera_.cx(), cy = camera_.cy();
    for (int i = 0; i < static_cast<int>(world_.cylinders().size()); ++i) {
        const Cylinder& c = world_.cylinders()[i];
        if (distanceToBox(o, c.lo, c.hi) > reach) continue;
        ObjectInView v;
        v.index = i;
        if (!cull_) {
            v.u0 = v.v0 = std::numeric_limits<int>::min();
            v.u1 = v.v1 = std::numeric_limits<int>::max();
            view.cylinders.push_back(v);
            continue;
        }
        // Image rectangle (undistorted coordinates) that holds the cylinder: its axis clipped
        // to the front of the camera, projected, widened by the radius at the nearest end.
        Vector3d a = Rt * (c.a - o), b = Rt * (c.a + c.length * c.axis - o);
        constexpr double kNear = 0.05;
        if (a.z() < kNear && b.z() < kNear) continue;
        if (a.z() < kNear) a += (b - a) * ((kNear - a.z()) / (b.z() - a.z()));
        if (b.z() < kNear) b += (a - b) * ((kNear - b.z()) / (a.z() - b.z()));
        const double grow = c.radius * f / std::min(a.z(), b.z()) + 2;
        const double ua = cx + f * a.x() / a.z(), va = cy + f * a.y() / a.z();
        const double ub = cx + f * b.x() / b.z(), vb = cy + f * b.y() / b.z();
        auto clampPx = [](double x, double lo, double hi) {
            return static_cast<int>(std::clamp(x, std::floor(lo) - 1.0, std::ceil(hi) + 1.0));
        };
        v.u0 = clampPx(std::floor(std::min(ua, ub) - grow), pin_lo_u_, pin_hi_u_);
        v.u1 = clampPx(std::ceil(std::max(ua, ub) + grow), pin_lo_u_, pin_hi_u_);
        v.v0 = clampPx(std::floor(std::min(va, vb) - grow), pin_lo_v_, pin_hi_v_);
        v.v1 = clampPx(std::ceil(std::max(va, vb) + grow), pin_lo_v_, pin_hi_v_);
        if (v.u1 < pin_lo_u_ || v.v1 < pin_lo_v_ || v.u0 > pin_hi_u_ || v.v0 > pin_hi_v_) continue;
        view.cylinders.push_back(v);
    }
    for (int i = 0; i < static_cast<int>(world_.lamps().size()); ++i) {
        if ((world_.lamps()[i].centre - o).norm() <= std::max(reach, 12.0)) view.lamps.push_back(i);
    }
    return view;
}

mrpt::img::CImage CameraRenderer::render(const mrpt::poses::CPose3D& camera_in_map,
                                         const FrameConditions& frame, FrameStats* stats) const {
    return render(std::vector<mrpt::poses::CPose3D>{camera_in_map}, frame, stats);
}

mrpt::img::CImage CameraRenderer::render(const std::vector<mrpt::poses::CPose3D>& row_poses,
                                         const FrameConditions& frame, FrameStats* stats) const {
    if (row_poses.size() != 1 && row_poses.size() != static_cast<std::size_t>(opt_.height_px)) {
        throw std::invalid_argument("CameraRenderer::render: one pose or one per row");
    }
    std::vector<View> views;
    views.reserve(row_poses.size());
    for (const auto& pose : row_poses) views.push_back(makeView(pose));

    const std::size_t count = static_cast<std::size_t>(opt_.width_px) * opt_.height_px;
    std::vector<float> radiance(count), depth(count);
    const int n = std::min(threads_, opt_.height_px);
    std::vector<std::thread> pool;
    for (int k = 1; k < n; ++k) {
        pool.emplace_back([&, k] { renderRows(views, k, n, radiance.data(), depth.data()); });
    }
    renderRows(views, 0, n, radiance.data(), depth.data());
    for (auto& t : pool) t.join();
    return develop(radiance, depth, frame, stats);
}

mrpt::img::CImage CameraRenderer::develop(std::vector<float>& radiance_px,
                                          const std::vector<float>& depth,
                                          const FrameConditions& frame, FrameStats* stats) const {
    const int W = opt_.width_px, H = opt_.height_px;
    const int count = W * H;
    cv::Mat radiance(H, W, CV_32F, radiance_px.data());
    if (opt_.haze_extinction_per_m > 0) addHaze(radiance, depth, opt_, beam_);
    motionBlur(radiance, frame);
    if (!drops_.empty()) {
        cv::Mat defocused;
        const double sigma = std::max(2.0, opt_.drop_radius_px / 2);
        cv::GaussianBlur(radiance, defocused, cv::Size(), sigma, sigma, cv::BORDER_REPLICATE);
        const cv::Mat cover(H, W, CV_32F, const_cast<float*>(drops_.data()));
        radiance = radiance.mul(1 - cover) + defocused.mul(cover);
    }
    if (!dirt_.empty()) {
        radiance = radiance.mul(cv::Mat(H, W, CV_32F, const_cast<float*>(dirt_.data())));
    }
    cv::Mat bloom;
    if (opt_.bloom_strength > 0) {
        // Light above saturation spills into the neighbouring pixels (lens flare, blooming).
        const double x_sat = kind_ == Kind::Ceiling ? 255.0 / 235.0 : 1.5;
        cv::Mat excess = cv::max(radiance * frame.exposure_gain - x_sat, 0.0);
        cv::GaussianBlur(excess, bloom, cv::Size(), opt_.bloom_radius_px, opt_.bloom_radius_px,
                         cv::BORDER_CONSTANT);
        bloom *= opt_.bloom_strength;
    }
    if (!radiance.isContinuous()) radiance = radiance.clone();

    // Exposure, tone curve, shot and read noise, response, quantisation.
    cv::Mat img(H, W, CV_8U);
    const float* src = radiance.ptr<float>();
    const float* glow = bloom.empty() ? nullptr : bloom.ptr<float>();
    uint8_t* dst = img.ptr<uint8_t>();
    const bool response = opt_.response_gamma != 1 || opt_.response_knee_dn > 0;
    for (int i = 0; i < count; ++i) {
        double x = src[i] * frame.exposure_gain;
        if (glow) x += glow[i];
        double dn = kind_ == Kind::Ceiling ? 235.0 * x : 255.0 * (1.0 - std::exp(-2.2 * x));
        if (opt_.noise_std_dn > 0) {
            const uint32_t h = hash3(frame.noise_key, static_cast<uint32_t>(i), 1);
            const double sigma = opt_.noise_std_dn * std::sqrt(1.0 + std::max(dn, 0.0) / 64.0);
            dn += sigma * fastGaussian(h);
        }
        if (response) {
            const double knee = opt_.response_knee_dn;
            if (knee > 0 && dn > knee) dn = knee + (dn - knee) * opt_.response_knee_slope;
            dn = 255.0 * std::pow(std::clamp(dn / 255.0, 0.0, 1.0), 1.0 / opt_.response_gamma);
        }
        dst[i] = static_cast<uint8_t>(std::clamp(std::lround(dn), 0L, 255L));
    }
    if (stats) stats->mean_dn = cv::mean(img)[0];
    return mrpt::img::CImage(img, mrpt::img::DEEP_COPY);
}

}  // namespace lookup::sim

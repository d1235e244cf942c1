#include "lookup/refine/estimator.h"

#include <ceres/ceres.h>
#include <ceres/rotation.h>

#include <Eigen/Geometry>
#include <Eigen/LU>
#include <cmath>

namespace lookup::refine {
namespace {

// Pixel residual of one correspondence. The reference ray meets the ceiling at
// P(h) = origin + (h - origin.z) / dir.z * dir = A + h * B (fixed camera, so linear in h).
// With a rolling shutter the query pixel was seen from the vehicle moved by `motion` (x, y,
// yaw in the vehicle's frame at the frame's pose) to its row's exposure.
struct ReprojectionCost {
    ReprojectionCost(const Eigen::Vector3d& A, const Eigen::Vector3d& B, const cv::Point2d& q,
                     const Pinhole& cam, const Eigen::Matrix3d& R_cv, const Eigen::Vector3d& t_cv,
                     double vehicle_z, double sigma, const mrpt::poses::CPose2D& motion = {})
        : A(A),
          B(B),
          q(q),
          cam(cam),
          R_cv(R_cv),
          t_cv(t_cv),
          z(vehicle_z),
          inv_sigma(1 / sigma),
          motion(motion.x(), motion.y(), motion.phi()),
          moving(motion.x() != 0 || motion.y() != 0 || motion.phi() != 0) {}

    template <typename T>
    bool operator()(const T* frame_pose, const T* h, T* residual) const {
        if (!moving) return project(frame_pose, h, residual);
        const T c = cos(frame_pose[2]), s = sin(frame_pose[2]);
        const T pose[5] = {frame_pose[0] + c * T(motion[0]) - s * T(motion[1]),
                           frame_pose[1] + s * T(motion[0]) + c * T(motion[1]),
                           frame_pose[2] + T(motion[2]), frame_pose[3], frame_pose[4]};
        return project(pose, h, residual);
    }

    template <typename T>
    bool project(const T* pose, const T* h, T* residual) const {
        // pose = x, y, yaw, pitch, roll; vehicle rotation Rz(yaw) Ry(pitch) Rx(roll) (MRPT).
        const T P[3] = {T(A[0]) + h[0] * B[0], T(A[1]) + h[0] * B[1], T(A[2]) + h[0] * B[2]};
        const T d[3] = {P[0] - pose[0], P[1] - pose[1], P[2] - T(z)};
        const T cy = cos(pose[2]), sy = sin(pose[2]);
        const T cp = cos(pose[3]), sp = sin(pose[3]);
        const T cr = cos(pose[4]), sr = sin(pose[4]);
        // R_v^T d, with R_v = Rz Ry Rx.
        const T a0 = cy * d[0] + sy * d[1];
        const T a1 = -sy * d[0] + cy * d[1];
        const T a2 = d[2];
        const T b0 = cp * a0 - sp * a2;
        const T b2 = sp * a0 + cp * a2;
        const T v[3] = {b0, cr * a1 + sr * b2, -sr * a1 + cr * b2};  // point in vehicle frame
        T c[3];
        for (int i = 0; i < 3; ++i) {
            c[i] = R_cv(0, i) * (v[0] - t_cv[0]) + R_cv(1, i) * (v[1] - t_cv[1]) +
                   R_cv(2, i) * (v[2] - t_cv[2]);
        }
        residual[0] = (T(cam.fx) * c[0] / c[2] + T(cam.cx) - T(q.x)) * T(inv_sigma);
        residual[1] = (T(cam.fy) * c[1] / c[2] + T(cam.cy) - T(q.y)) * T(inv_sigma);
        return true;
    }

    Eigen::Vector3d A, B;
    cv::Point2d q;
    Pinhole cam;
    Eigen::Matrix3d R_cv;
    Eigen::Vector3d t_cv;
    double z, inv_sigma;
    Eigen::Vector3d motion;
    bool moving;
};

struct PriorCost {
    double h0, pitch0, roll0, inv_sigma_h, inv_sigma_tilt;
    template <typename T>
    bool operator()(const T* pose, const T* h, T* residual) const {
        residual[0] = (h[0] - T(h0)) * T(inv_sigma_h);
        residual[1] = (pose[3] - T(pitch0)) * T(inv_sigma_tilt);
        residual[2] = (pose[4] - T(roll0)) * T(inv_sigma_tilt);
        return true;
    }
};

Eigen::Matrix3d rotationOf(const mrpt::poses::CPose3D& p) {
    return p.getRotationMatrix().asEigen();
}

// Every usable correspondence: the reference ray's A + h B, the query pixel and the query
// vehicle's motion to its row; and, for the closed-form start at the prior h, the ceiling
// points from the references (map frame) against the same points from the query camera with
// the vehicle at the origin, yaw 0.
struct Correspondences {
    std::vector<Eigen::Vector3d> As, Bs;
    std::vector<cv::Point2d> qs;
    std::vector<double> rows;  ///< the query points' sensor rows
    std::vector<mrpt::poses::CPose2D> motions;
    Eigen::Matrix2Xd src, dst;
};

double rowOf(const std::vector<double>& rows, const std::vector<cv::Point2d>& px, std::size_t i) {
    return rows.size() == px.size() ? rows[i] : px[i].y;
}

Correspondences collect(const EstimatorInput& in, double h0) {
    Correspondences c;
    const mrpt::poses::CPose3D vehicle_at_origin(0, 0, in.vehicle_z, 0, in.prior_pitch_rad,
                                                 in.prior_roll_rad);
    const mrpt::poses::CPose3D query_cam_at_origin = vehicle_at_origin + in.query_camera_on_vehicle;
    std::vector<Eigen::Vector2d> src, dst;
    for (const auto& view : in.views) {
        for (std::size_t i = 0; i < view.reference_px.size(); ++i) {
            const auto& r = view.reference_px[i];
            const mrpt::poses::CPose3D ref_cam =
                view.timing.active()
                    ? view.timing.cameraAtRow(view.camera_in_map, view.camera_on_vehicle,
                                              rowOf(view.reference_row, view.reference_px, i))
                    : view.camera_in_map;
            const auto R = rotationOf(ref_cam);
            const Eigen::Vector3d t(ref_cam.x(), ref_cam.y(), ref_cam.z());
            const Eigen::Vector3d dir =
                R * Eigen::Vector3d((r.x - view.camera.cx) / view.camera.fx,
                                    (r.y - view.camera.cy) / view.camera.fy, 1.0);
            if (std::abs(dir.z()) < 1e-9) continue;
            mrpt::poses::CPose2D motion;
            if (in.query_timing.active()) {
                motion = in.query_timing.motionAtRow(rowOf(view.query_row, view.query_px, i));
            }
            const mrpt::poses::CPose3D query_cam =
                in.query_timing.active()
                    ? vehicle_at_origin + mrpt::poses::CPose3D(motion) + in.query_camera_on_vehicle
                    : query_cam_at_origin;
            const auto p_ref = backProjectToCeiling(view.camera, ref_cam, r, h0);
            const auto p_qry =
                backProjectToCeiling(in.query_camera, query_cam, view.query_px[i], h0);
            if (!p_ref || !p_qry) continue;
            c.As.push_back(t - t.z() / dir.z() * dir);
            c.Bs.push_back(dir / dir.z());
            c.qs.push_back(view.query_px[i]);
            c.rows.push_back(rowOf(view.query_row, view.query_px, i));
            c.motions.push_back(motion);
            src.emplace_back(p_qry->x, p_qry->y);
            dst.emplace_back(p_ref->x, p_ref->y);
        }
    }
    c.src.resize(2, Eigen::Index(src.size()));
    c.dst.resize(2, Eigen::Index(dst.size()));
    for (std::size_t i = 0; i < src.size(); ++i) {
        c.src.col(Eigen::Index(i)) = src[i];
        c.dst.col(Eigen::Index(i)) = dst[i];
    }
    return c;
}

// 2-D rigid fit dst = R(yaw) src + t (closed form, Umeyama without scale): (t.x, t.y, yaw).
Eigen::Vector3d rigidFit(const Eigen::Matrix2Xd& src, const Eigen::Matrix2Xd& dst) {
    const Eigen::Vector2d src_mean = src.rowwise().mean(), dst_mean = dst.rowwise().mean();
    double dot = 0.0, cross = 0.0;
    for (Eigen::Index i = 0; i < src.cols(); ++i) {
        const Eigen::Vector2d a = src.col(i) - src_mean, b = dst.col(i) - dst_mean;
        dot += a.dot(b);
        cross += a.x() * b.y() - a.y() * b.x();
    }
    const double yaw = std::atan2(cross, dot);
    const Eigen::Vector2d t = dst_mean - Eigen::Rotation2Dd(yaw) * src_mean;
    return {t.x(), t.y(), yaw};
}

// The query camera on the vehicle, as ReprojectionCost takes it.
struct CameraMount {
    explicit CameraMount(const mrpt::poses::CPose3D& on_vehicle)
        : R(rotationOf(on_vehicle)), t(on_vehicle.x(), on_vehicle.y(), on_vehicle.z()) {}
    Eigen::Matrix3d R;
    Eigen::Vector3d t;
};

ReprojectionCost reprojection(const Correspondences& corr, std::size_t i, const EstimatorInput& in,
                              const CameraMount& mount, double sigma_px) {
    return ReprojectionCost(corr.As[i], corr.Bs[i], corr.qs[i], in.query_camera, mount.R, mount.t,
                            in.vehicle_z, sigma_px, corr.motions[i]);
}

// One Huber-robust pixel residual per correspondence.
void addReprojections(ceres::Problem& problem, const Correspondences& corr,
                      const EstimatorInput& in, const EstimatorOptions& o, const CameraMount& mount,
                      double* pose, double* h) {
    const double huber = o.huber_loss_px / o.pixel_sigma_px;  // residuals are in sigmas
    for (std::size_t i = 0; i < corr.qs.size(); ++i) {
        auto* cost = new ceres::AutoDiffCostFunction<ReprojectionCost, 2, 5, 1>(
            new ReprojectionCost(reprojection(corr, i, in, mount, o.pixel_sigma_px)));
        problem.AddResidualBlock(cost, new ceres::HuberLoss(huber), pose, h);
    }
}

// The priors on the ceiling height and on the tilt (pitch, roll).
void addPrior(ceres::Problem& problem, const EstimatorInput& in, const EstimatorOptions& o,
              double* pose, double* h) {
    const double tilt_sigma = o.tilt_sigma_deg * M_PI / 180.0;
    problem.AddResidualBlock(new ceres::AutoDiffCostFunction<PriorCost, 3, 5, 1>(new PriorCost{
                                 in.ceiling_height_m, in.prior_pitch_rad, in.prior_roll_rad,
                                 1.0 / o.ceiling_height_sigma_m, 1.0 / tilt_sigma}),
                             nullptr, pose, h);
}

void solve(ceres::Problem& problem, int max_iterations, ceres::Solver::Summary* summary) {
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::DENSE_QR;
    solver.max_num_iterations = max_iterations;
    solver.num_threads = 1;
    solver.logging_type = ceres::SILENT;
    ceres::Solve(solver, &problem, summary);
}

// The covariance of (x, y, yaw, pitch, roll, h); false when rank deficient.
bool jointCovariance(ceres::Problem& problem, const double* pose, const double* h,
                     mrpt::math::CMatrixDouble66& out) {
    ceres::Covariance::Options cov_options;
    cov_options.num_threads = 1;
    ceres::Covariance covariance(cov_options);
    const std::vector<std::pair<const double*, const double*>> blocks = {
        {pose, pose}, {pose, h}, {h, h}};
    if (!covariance.Compute(blocks, &problem)) return false;
    double c_pp[25], c_ph[5], c_hh[1];
    covariance.GetCovarianceBlock(pose, pose, c_pp);
    covariance.GetCovarianceBlock(pose, h, c_ph);
    covariance.GetCovarianceBlock(h, h, c_hh);
    for (int i = 0; i < 5; ++i) {
        for (int j = 0; j < 5; ++j) out(i, j) = c_pp[i * 5 + j];
        out(i, 5) = out(5, i) = c_ph[i];
    }
    out(5, 5) = c_hh[0];
    return true;
}

// The solved pose and height into `out`, whose covariance is already set.
void storeSolution(const EstimatorInput& in, const double* pose, const double* h,
                   PoseEstimate& out) {
    out.vehicle_in_map =
        mrpt::poses::CPose3D(pose[0], pose[1], in.vehicle_z, pose[2], pose[3], pose[4]);
    mrpt::math::CMatrixDouble33 c3;
    for (int i = 0; i < 3; ++i)
        for (int j = 0; j < 3; ++j) c3(i, j) = out.covariance(i, j);
    out.pose = mrpt::poses::CPosePDFGaussian(mrpt::poses::CPose2D(pose[0], pose[1], pose[2]), c3);
    out.ceiling_height_m = h[0];
    out.ceiling_height_sigma_m = std::sqrt(std::max(0.0, out.covariance(5, 5)));
}

// The unweighted pixel residual of every correspondence at the solution.
std::vector<Eigen::Vector2d> pixelResiduals(const Correspondences& corr, const EstimatorInput& in,
                                            const CameraMount& mount, const double* pose,
                                            const double* h) {
    std::vector<Eigen::Vector2d> r(corr.qs.size());
    for (std::size_t i = 0; i < r.size(); ++i) {
        reprojection(corr, i, in, mount, 1.0)(pose, h, r[i].data());
    }
    return r;
}

double rootMeanSquare(const std::vector<Eigen::Vector2d>& residuals) {
    double sq = 0.0;
    for (const auto& r : residuals) sq += r[0] * r[0] + r[1] * r[1];
    return std::sqrt(sq / double(residuals.size()));
}

// The unknowns of the rows' refit: c, isotropic scale, rotation, shift x, shift y, tilt about
// the camera's x and y axes.
constexpr int kRowUnknowns = 7;
using RowDesign = Eigen::Matrix<double, 2, kRowUnknowns>;
using RowVector = Eigen::Matrix<double, kRowUnknowns, 1>;
using RowNormal = Eigen::Matrix<double, kRowUnknowns, kRowUnknowns>;

// Each correspondence's design against its residual: the rows' term c (row - mean row) u with
// u the image direction of the vehicle's heading, then what the pose and h would take of a
// stretch (shift, rotation, scale, tilt).
std::vector<RowDesign> rowDesign(const Correspondences& corr, const EstimatorInput& in,
                                 const Eigen::Vector2d& u) {
    const std::size_t n = corr.qs.size();
    double mean_row = 0;
    Eigen::Vector2d mean_px = Eigen::Vector2d::Zero();
    for (std::size_t i = 0; i < n; ++i) {
        mean_row += corr.rows[i] / double(n);
        mean_px += Eigen::Vector2d(corr.qs[i].x, corr.qs[i].y) / double(n);
    }
    const Pinhole& c = in.query_camera;
    std::vector<RowDesign> A(n);
    for (std::size_t i = 0; i < n; ++i) {
        const double dr = corr.rows[i] - mean_row;
        const Eigen::Vector2d p = Eigen::Vector2d(corr.qs[i].x, corr.qs[i].y) - mean_px;
        const double x = corr.qs[i].x - c.cx, y = corr.qs[i].y - c.cy;
        A[i] << dr * u.x(), p.x(), -p.y(), 1, 0, x * y / c.fx, x * x / c.fx,  //
            dr * u.y(), p.y(), p.x(), 0, 1, y * y / c.fx, x * y / c.fx;
    }
    return A;
}

// Least squares of r = A x twice, all points then those within 3 robust deviations of the
// first fit; the variance of x's first unknown. None with too few points or a singular fit.
std::optional<std::pair<double, double>> robustFirstUnknown(const std::vector<RowDesign>& A,
                                                            const std::vector<Eigen::Vector2d>& r,
                                                            std::size_t min_points) {
    const std::size_t n = A.size();
    std::vector<char> use(n, 1);
    RowVector x;
    RowNormal AtA;
    double rr = 0;
    std::size_t used = 0;
    for (int pass = 0; pass < 2; ++pass) {
        AtA.setZero();
        RowVector Atr = RowVector::Zero();
        rr = 0;
        used = 0;
        for (std::size_t i = 0; i < n; ++i) {
            if (!use[i]) continue;
            AtA += A[i].transpose() * A[i];
            Atr += A[i].transpose() * r[i];
            ++used;
        }
        if (used < min_points) return std::nullopt;
        const Eigen::FullPivLU<RowNormal> lu(AtA);
        if (!lu.isInvertible()) return std::nullopt;
        x = lu.solve(Atr);
        std::vector<double> e(n);
        for (std::size_t i = 0; i < n; ++i) e[i] = (r[i] - A[i] * x).norm();
        for (std::size_t i = 0; i < n; ++i) rr += use[i] ? e[i] * e[i] : 0.0;
        std::vector<double> sorted = e;
        std::nth_element(sorted.begin(), sorted.begin() + n / 2, sorted.end());
        const double gate = std::max(0.5, 3 * 1.4826 * sorted[n / 2]);
        for (std::size_t i = 0; i < n; ++i) use[i] = e[i] <= gate;
    }
    const double s2 = rr / double(2 * used - kRowUnknowns);
    return std::make_pair(x(0), s2 * AtA.inverse()(0, 0));
}

// The vehicle's travel between the first and the last row's exposure that the residuals at the
// solution show: a rolling shutter the model does not carry moves each point by the image
// motion of the travel up to its row; refitted beside what the pose and h would take of it so
// that only the stretch or shear along the drive is left.
std::optional<RowTravel> rowTravel(const Correspondences& corr, const EstimatorInput& in,
                                   const CameraMount& mount, const double* h,
                                   const std::vector<Eigen::Vector2d>& residuals) {
    constexpr std::size_t kMinPoints = 20;
    const Eigen::Vector2d u = mount.R.row(0).head<2>();  // the vehicle's x axis, camera frame
    const double distance_m = h[0] - in.vehicle_z - mount.t.z();
    if (in.query_rows < 2 || u.norm() < 0.5 || !(distance_m > 0) || corr.qs.size() < kMinPoints) {
        return std::nullopt;
    }
    const auto c = robustFirstUnknown(rowDesign(corr, in, u.normalized()), residuals, kMinPoints);
    if (!c) return std::nullopt;
    // c is pixels per row; the vehicle moving d metres moves the ceiling by f d / distance px.
    const double px_per_m = std::sqrt(in.query_camera.fx * in.query_camera.fy) / distance_m;
    const double rows = double(in.query_rows - 1);
    return RowTravel{c->first * rows / px_per_m, std::sqrt(c->second) * rows / px_per_m};
}

}  // namespace

PoseEstimate estimateQueryPose(const EstimatorInput& in, const EstimatorOptions& o) {
    PoseEstimate out;
    const double h0 = in.ceiling_height_m;
    if (!std::isfinite(h0)) {
        out.reason = "ceiling height prior is not finite";
        return out;
    }
    const Correspondences corr = collect(in, h0);
    out.correspondences = int(corr.qs.size());
    if (out.correspondences < o.min_inliers) {
        out.reason = "only " + std::to_string(out.correspondences) +
                     " usable correspondences (min_inliers = " + std::to_string(o.min_inliers) +
                     ")";
        return out;
    }
    const Eigen::Vector3d start = rigidFit(corr.src, corr.dst);
    double pose[5] = {start.x(), start.y(), start.z(), in.prior_pitch_rad, in.prior_roll_rad};
    double h[1] = {h0};

    ceres::Problem problem;
    const CameraMount mount(in.query_camera_on_vehicle);
    addReprojections(problem, corr, in, o, mount, pose, h);
    addPrior(problem, in, o, pose, h);
    ceres::Solver::Summary summary;
    solve(problem, o.max_iterations, &summary);
    out.iterations = int(summary.iterations.size());
    if (!summary.IsSolutionUsable()) {
        out.reason = "Ceres: " + summary.message;
        return out;
    }
    if (!jointCovariance(problem, pose, h, out.covariance)) {
        out.reason = "Ceres covariance is rank deficient (pose not observable from the matches)";
        return out;
    }
    storeSolution(in, pose, h, out);
    const auto residuals = pixelResiduals(corr, in, mount, pose, h);
    out.rms_residual_px = rootMeanSquare(residuals);
    out.row_travel = rowTravel(corr, in, mount, h, residuals);
    out.ok = true;
    return out;
}

}  // namespace lookup::refine

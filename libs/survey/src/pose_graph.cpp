#include "lookup/survey/pose_graph.h"

#include <ceres/ceres.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/poses/CPoint2D.h>
#include <mrpt/system/CTicTac.h>

#include <Eigen/Dense>
#include <algorithm>
#include <atomic>
#include <cmath>
#include <exception>
#include <mutex>
#include <optional>
#include <stdexcept>
#include <thread>

#include "lookup/common/config.h"

namespace lookup::survey {

void PoseGraphOptions::declareKeys(common::OptionsTable& t) {
    t.add("enabled", enabled);
    t.add("all_traverses", all_traverses);
    t.add("keyframe_spacing_m", keyframe_spacing_m, common::kPositive);
    t.add("keyframe_spacing_deg", keyframe_spacing_deg, common::kPositive);
    t.add("max_edge_distance_m", max_edge_distance_m, common::kPositive);
    t.add("edges_per_keyframe", edges_per_keyframe, 1, 1000);
    t.add("cross_edges_per_keyframe", cross_edges_per_keyframe, 0, 1000);
    t.add("min_matched_share", min_matched_share, 0.0, 1.0);
    t.add("max_correction_m", max_correction_m, common::kPositive);
    t.add("max_correction_deg", max_correction_deg, common::kPositive);
    t.add("point_std_m", point_std_m, common::kPositive);
    t.add("registration_min_std_xy_m", registration_min_std_xy_m, common::kPositive);
    t.add("registration_min_std_yaw_deg", registration_min_std_yaw_deg, common::kPositive);
    t.add("odometry_std_per_m", odometry_std_per_m, common::kPositive);
    t.add("odometry_std_yaw_deg_per_m", odometry_std_yaw_deg_per_m, common::kPositive);
    t.add("huber_sigmas", huber_sigmas, common::kPositive);
    t.add("max_iterations", max_iterations, 1, 100000);
    t.add("threads", threads, 0, 1024);
    t.add("covariance_stride", covariance_stride, 0, 100000000);
}

void PoseGraphOptions::check() const {
    common::OptionsCheck c("pose_graph");
    checkRanges(c);
    c.throwIfFailed();
}

namespace {

template <typename T>
T wrapAngle(const T& a) {
    using std::floor;
    const T two_pi(2.0 * M_PI);
    return a - two_pi * floor((a + T(M_PI)) / two_pi);
}

/// Residual of a relative-pose measurement a -> b (the pose of b in a's frame), whitened by the
/// square root of its information matrix.
struct RelativePoseCost {
    RelativePoseCost(const mrpt::poses::CPose2D& a_to_b, const Eigen::Matrix3d& sqrt_information)
        : dx(a_to_b.x()), dy(a_to_b.y()), dyaw(a_to_b.phi()), w(sqrt_information) {}

    template <typename T>
    bool operator()(const T* a, const T* b, T* r) const {
        using std::cos;
        using std::sin;
        const T ex = b[0] - a[0], ey = b[1] - a[1];
        const T c = cos(a[2]), s = sin(a[2]);
        const T e[3] = {c * ex + s * ey - T(dx), -s * ex + c * ey - T(dy),
                        wrapAngle(b[2] - a[2] - T(dyaw))};
        for (int i = 0; i < 3; ++i) {
            r[i] = T(w(i, 0)) * e[0] + T(w(i, 1)) * e[1] + T(w(i, 2)) * e[2];
        }
        return true;
    }

    double dx, dy, dyaw;
    Eigen::Matrix3d w;
};

ceres::CostFunction* relativePoseCost(const mrpt::poses::CPose2D& a_to_b,
                                      const Eigen::Matrix3d& covariance) {
    // W^T W = covariance^-1 with W = L^-1, covariance = L L^T.
    const Eigen::Matrix3d L = covariance.llt().matrixL();
    return new ceres::AutoDiffCostFunction<RelativePoseCost, 3, 3, 3>(
        new RelativePoseCost(a_to_b, L.inverse()));
}

/// A scan as points in the vehicle frame, each with the normal of the wall line through its
/// neighbours along the scan (zero where they do not lie on a line).
struct ScanPoints {
    mrpt::maps::CSimplePointsMap map;  ///< same order as `normals`; its KD-tree pairs points
    std::vector<Eigen::Vector2f> normals;
};

ScanPoints scanPoints(const mrpt::obs::CObservation2DRangeScan& scan) {
    const mrpt::poses::CPose2D sensor(scan.sensorPose);
    std::vector<Eigen::Vector2f> pts;
    for (std::size_t i = 0; i < scan.getScanSize(); ++i) {
        if (!scan.getScanRangeValidity(i)) continue;
        const double r = scan.getScanRange(i);
        if (r <= 0 || r >= scan.maxRange * 0.999) continue;
        const double angle = scan.getScanAngle(i);
        const auto p = sensor + mrpt::poses::CPoint2D(r * std::cos(angle), r * std::sin(angle));
        pts.emplace_back(float(p.x()), float(p.y()));
    }
    ScanPoints out;
    out.normals.assign(pts.size(), Eigen::Vector2f::Zero());
    constexpr int kHalf = 3;                   // 7 neighbouring rays
    constexpr float kMaxNeighbourDist = 0.6f;  // [m]: farther ones are another surface
    constexpr float kMaxFlatness = 0.05f;      // small / large eigenvalue of a line
    for (std::size_t i = 0; i < pts.size(); ++i) {
        out.map.insertPoint(pts[i].x(), pts[i].y(), 0);
        Eigen::Vector2f mean = Eigen::Vector2f::Zero();
        int count = 0;
        Eigen::Vector2f nb[2 * kHalf + 1];
        for (int d = -kHalf; d <= kHalf; ++d) {
            const long j = long(i) + d;
            if (j < 0 || j >= long(pts.size())) continue;
            if ((pts[j] - pts[i]).norm() > kMaxNeighbourDist) continue;
            nb[count++] = pts[j];
            mean += pts[j];
        }
        if (count < 5) continue;
        mean /= float(count);
        Eigen::Matrix2f c = Eigen::Matrix2f::Zero();
        for (int k = 0; k < count; ++k) c += (nb[k] - mean) * (nb[k] - mean).transpose();
        const Eigen::SelfAdjointEigenSolver<Eigen::Matrix2f> eig(c);  // ascending eigenvalues
        if (eig.eigenvalues()(0) > kMaxFlatness * eig.eigenvalues()(1)) continue;
        out.normals[i] = eig.eigenvectors().col(0);
    }
    // Build the KD-tree now: registrations query it from several threads.
    if (out.map.size() > 0) {
        float d2;
        out.map.kdTreeClosestPoint2D(0.f, 0.f, d2);
    }
    return out;
}

struct Registration {
    mrpt::poses::CPose2D pose;                          ///< pose of scan b in the frame of scan a
    Eigen::Matrix3d hessian = Eigen::Matrix3d::Zero();  ///< J^T J of the point residuals
    double matched_share = 0;  ///< share of b's points with a wall line of a within reach
    bool ok = false;
};

/// Point-to-line ICP (Gauss-Newton, Huber-weighted) of b's points against a's wall lines from
/// `guess`. MRPT 2.5's CICP matches point to point: between two sparse scans of the same rough
/// wall that leaves heading errors a 1 km graph integrates into metres.
Registration registerPointToLine(const ScanPoints& a, const ScanPoints& b,
                                 const mrpt::poses::CPose2D& guess) {
    Registration out;
    if (a.map.size() < 20 || b.map.size() < 20) return out;
    double x = guess.x(), y = guess.y(), th = guess.phi();
    const auto& bx = b.map.getPointsBufferRef_x();
    const auto& by = b.map.getPointsBufferRef_y();
    const auto& ax = a.map.getPointsBufferRef_x();
    const auto& ay = a.map.getPointsBufferRef_y();
    // Pairing distance, shrinking as the estimate settles [m]; Huber threshold [m].
    constexpr double kGates[] = {0.5, 0.3, 0.2, 0.12};
    constexpr double kHuber = 0.03;
    constexpr int kMaxIterations = 20;
    constexpr double kDamping = 1e-3;
    for (int it = 0; it < kMaxIterations; ++it) {
        const double gate = kGates[std::min(it / 2, 3)];
        const double c = std::cos(th), s = std::sin(th);
        Eigen::Matrix3d H = Eigen::Matrix3d::Zero();
        Eigen::Vector3d g = Eigen::Vector3d::Zero();
        std::size_t matched = 0;
        for (std::size_t j = 0; j < bx.size(); ++j) {
            const double px = bx[j], py = by[j];
            const double qx = x + c * px - s * py, qy = y + s * px + c * py;
            float d2;
            const std::size_t i = a.map.kdTreeClosestPoint2D(float(qx), float(qy), d2);
            if (d2 > gate * gate) continue;
            const Eigen::Vector2f& n = a.normals[i];
            if (n.squaredNorm() < 0.5f) continue;
            const double r = n.x() * (qx - ax[i]) + n.y() * (qy - ay[i]);
            const Eigen::Vector3d J(n.x(), n.y(),
                                    n.x() * (-s * px - c * py) + n.y() * (c * px - s * py));
            const double w = std::abs(r) <= kHuber ? 1.0 : kHuber / std::abs(r);
            H += w * J * J.transpose();
            g += w * J * r;
            ++matched;
        }
        out.matched_share = double(matched) / double(bx.size());
        if (matched < 20) return out;
        // Slightly damped (Levenberg): along a drive with little relief the problem is nearly
        // degenerate.
        Eigen::Matrix3d damped = H;
        damped.diagonal() *= 1.0 + kDamping;
        const Eigen::Vector3d step = damped.ldlt().solve(-g);
        if (!step.allFinite()) return out;
        x += step(0);
        y += step(1);
        th += step(2);
        out.hessian = H;
        if (it >= 6 && step.head<2>().norm() < 1e-5 && std::abs(step(2)) < 1e-6) break;
    }
    out.pose = mrpt::poses::CPose2D(x, y, th);
    out.ok = true;
    return out;
}

/// The traverse's scans in order, each with the latest odometry before it.
struct ScanWithOdometry {
    const mrpt::obs::CObservation2DRangeScan* scan;
    mrpt::poses::CPose2D odometry;
};

std::vector<ScanWithOdometry> scansOf(const TraverseData& traverse) {
    std::vector<ScanWithOdometry> out;
    mrpt::poses::CPose2D odometry;
    for (const auto& o : traverse.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            odometry = odo->odometry;
        } else if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            out.push_back({scan.get(), odometry});
        }
    }
    return out;
}

struct Keyframe {
    std::size_t traverse = 0, scan = 0;
    mrpt::poses::CPose2D initial, odometry;
    double travelled_m = 0;  ///< along its traverse, by the first estimate
    ScanPoints points;
};

struct Pair {
    std::size_t a, b;
    bool cross;
};

/// Up to `count` indices spread evenly over first..last (inclusive), last always among them.
template <class F>
void spread(std::size_t first, std::size_t last, int count, F&& take) {
    if (last < first || count <= 0) return;
    const std::size_t n = last - first + 1;
    const std::size_t k = std::min<std::size_t>(n, std::size_t(count));
    for (std::size_t e = 1; e <= k; ++e) take(first + e * n / k - 1);
}

}  // namespace

std::vector<common::PoseTrack> optimisePoseGraph(
    const std::vector<GraphTraverse>& traverses, const PoseGraphOptions& options,
    PoseGraphReport* report, const GraphProgressFn& progress,
    std::vector<std::vector<mrpt::math::CMatrixDouble33>>* covariances) {
    mrpt::system::CTicTac timer;
    PoseGraphReport rep;
    rep.traverses = traverses.size();

    // 1. Keyframes by first-estimate travel or turn, per traverse.
    std::vector<std::vector<ScanWithOdometry>> scans;
    std::vector<Keyframe> keyframes;
    std::vector<std::pair<std::size_t, std::size_t>> ranges;  // keyframes of each traverse
    for (std::size_t t = 0; t < traverses.size(); ++t) {
        const auto& tr = traverses[t];
        scans.push_back(scansOf(*tr.data));
        if (scans[t].size() != tr.initial.size()) {
            throw std::invalid_argument("optimisePoseGraph: " + tr.data->rawlog + ": " +
                                        std::to_string(scans[t].size()) + " scans but " +
                                        std::to_string(tr.initial.size()) + " poses");
        }
        const std::size_t first = keyframes.size();
        double travelled = 0;
        for (std::size_t i = 0; i < scans[t].size(); ++i) {
            const mrpt::poses::CPose2D pose(tr.initial[i].pose);
            if (i > 0) {
                const mrpt::poses::CPose2D prev(tr.initial[i - 1].pose);
                travelled += std::hypot(pose.x() - prev.x(), pose.y() - prev.y());
            }
            if (keyframes.size() > first) {
                const auto& last = keyframes.back();
                const bool far = travelled - last.travelled_m >= options.keyframe_spacing_m;
                const bool turned =
                    std::abs(mrpt::math::wrapToPi(pose.phi() - last.initial.phi())) >=
                    mrpt::DEG2RAD(options.keyframe_spacing_deg);
                if (!far && !turned && i + 1 < scans[t].size()) continue;
            }
            Keyframe k;
            k.traverse = t;
            k.scan = i;
            k.initial = pose;
            k.odometry = scans[t][i].odometry;
            k.travelled_m = travelled;
            keyframes.push_back(std::move(k));
        }
        ranges.emplace_back(first, keyframes.size());
    }
    rep.keyframes = keyframes.size();
    if (keyframes.empty()) {
        std::vector<common::PoseTrack> same;
        for (const auto& tr : traverses) same.push_back(tr.initial);
        return same;
    }

    // 2. Which keyframes to register: along the own traverse, the next ones within reach,
    // spread so both short and long baselines tie each keyframe; across traverses, the
    // keyframes of each other traverse near this one's first estimate.
    std::vector<Pair> pairs;
    for (std::size_t t = 0; t < traverses.size(); ++t) {
        const auto [first, end] = ranges[t];
        for (std::size_t a = first; a < end; ++a) {
            std::size_t last = a;
            while (last + 1 < end && keyframes[last + 1].travelled_m - keyframes[a].travelled_m <=
                                         options.max_edge_distance_m) {
                ++last;
            }
            spread(a + 1, last, options.edges_per_keyframe, [&](std::size_t b) {
                pairs.push_back({a, b, false});
            });
        }
    }
    if (options.cross_edges_per_keyframe > 0) {
        for (std::size_t t = 0; t < traverses.size(); ++t) {
            for (std::size_t u = t + 1; u < traverses.size(); ++u) {
                mrpt::maps::CSimplePointsMap positions;
                for (std::size_t b = ranges[u].first; b < ranges[u].second; ++b) {
                    positions.insertPoint(float(keyframes[b].initial.x()),
                                          float(keyframes[b].initial.y()), 0);
                }
                if (positions.size() == 0) continue;
                const double half_window = 0.5 * options.max_edge_distance_m;
                for (std::size_t a = ranges[t].first; a < ranges[t].second; ++a) {
                    float d2;
                    const std::size_t near =
                        ranges[u].first +
                        positions.kdTreeClosestPoint2D(float(keyframes[a].initial.x()),
                                                       float(keyframes[a].initial.y()), d2);
                    if (d2 > half_window * half_window) continue;
                    std::size_t lo = near, hi = near;
                    const auto within = [&](std::size_t b) {
                        return std::hypot(keyframes[b].initial.x() - keyframes[a].initial.x(),
                                          keyframes[b].initial.y() - keyframes[a].initial.y()) <=
                               half_window;
                    };
                    while (lo > ranges[u].first && within(lo - 1)) --lo;
                    while (hi + 1 < ranges[u].second && within(hi + 1)) ++hi;
                    spread(lo, hi, options.cross_edges_per_keyframe, [&](std::size_t b) {
                        pairs.push_back({a, b, true});
                    });
                }
            }
        }
    }

    // 3. Scan points (normals, KD-trees), then the registrations, on all threads.
    const unsigned threads = options.threads > 0
                                 ? unsigned(options.threads)
                                 : std::max(1u, std::thread::hardware_concurrency());
    std::vector<Registration> results(pairs.size());
    {
        std::atomic<std::size_t> next_keyframe{0}, next_pair{0}, done{0};
        // A worker's exception would end the process: the first is kept and rethrown here.
        std::mutex failure_mutex;
        std::exception_ptr failure;
        const auto guarded = [&](auto&& body) {
            return [&, body] {
                try {
                    body();
                } catch (...) {
                    const std::lock_guard<std::mutex> lock(failure_mutex);
                    if (!failure) failure = std::current_exception();
                    next_keyframe = keyframes.size();
                    next_pair = done = pairs.size();
                }
            };
        };
        const auto run = [&](auto&& body) {
            std::vector<std::thread> pool;
            for (unsigned i = 0; i < threads; ++i) pool.emplace_back(guarded(body));
            return pool;
        };
        for (auto& th : run([&] {
                 for (std::size_t k; (k = next_keyframe++) < keyframes.size();) {
                     keyframes[k].points =
                         scanPoints(*scans[keyframes[k].traverse][keyframes[k].scan].scan);
                 }
             })) {
            th.join();
        }
        if (failure) std::rethrow_exception(failure);
        auto pool = run([&] {
            for (std::size_t p; (p = next_pair++) < pairs.size();) {
                const auto& ka = keyframes[pairs[p].a];
                const auto& kb = keyframes[pairs[p].b];
                results[p] = registerPointToLine(ka.points, kb.points, kb.initial - ka.initial);
                ++done;
            }
        });
        if (progress) {
            while (done < pairs.size()) {
                progress(0.95 * double(done) / double(std::max<std::size_t>(1, pairs.size())));
                std::this_thread::sleep_for(std::chrono::milliseconds(200));
            }
        }
        for (auto& th : pool) th.join();
        if (failure) std::rethrow_exception(failure);
    }

    // 4. One least-squares problem over all keyframe poses.
    std::vector<double> state(3 * keyframes.size());
    for (std::size_t k = 0; k < keyframes.size(); ++k) {
        state[3 * k] = keyframes[k].initial.x();
        state[3 * k + 1] = keyframes[k].initial.y();
        state[3 * k + 2] = keyframes[k].initial.phi();
    }
    ceres::Problem problem;
    const double min_yaw_std = mrpt::DEG2RAD(options.registration_min_std_yaw_deg);
    for (std::size_t p = 0; p < pairs.size(); ++p) {
        const Registration& r = results[p];
        const auto& ka = keyframes[pairs[p].a];
        const auto& kb = keyframes[pairs[p].b];
        const mrpt::poses::CPose2D correction = r.pose - (kb.initial - ka.initial);
        if (!r.ok || r.matched_share < options.min_matched_share ||
            std::hypot(correction.x(), correction.y()) > options.max_correction_m ||
            std::abs(correction.phi()) > mrpt::DEG2RAD(options.max_correction_deg)) {
            ++rep.rejected_registrations;
            continue;
        }
        // The point residuals through the fit's Hessian (weak along a featureless drive,
        // strong across it), plus a floor for what the fit cannot see.
        Eigen::Matrix3d cov = options.point_std_m * options.point_std_m * r.hessian.inverse();
        cov(0, 0) += std::pow(options.registration_min_std_xy_m, 2);
        cov(1, 1) += std::pow(options.registration_min_std_xy_m, 2);
        cov(2, 2) += min_yaw_std * min_yaw_std;
        if (!cov.allFinite()) {
            ++rep.rejected_registrations;
            continue;
        }
        problem.AddResidualBlock(relativePoseCost(r.pose, cov),
                                 new ceres::HuberLoss(options.huber_sigmas), &state[3 * pairs[p].a],
                                 &state[3 * pairs[p].b]);
        ++rep.registrations;
        rep.cross_registrations += pairs[p].cross;
    }
    // Weak odometry links keep each traverse connected where scans match nothing.
    for (std::size_t t = 0; t < traverses.size(); ++t) {
        for (std::size_t a = ranges[t].first; a + 1 < ranges[t].second; ++a) {
            const auto& ka = keyframes[a];
            const auto& kb = keyframes[a + 1];
            const double d = std::max(0.05, kb.travelled_m - ka.travelled_m);
            const double s_xy = options.odometry_std_per_m * d;
            const double s_yaw = mrpt::DEG2RAD(options.odometry_std_yaw_deg_per_m) * d;
            problem.AddResidualBlock(
                relativePoseCost(
                    kb.odometry - ka.odometry,
                    Eigen::Vector3d(s_xy * s_xy, s_xy * s_xy, s_yaw * s_yaw).asDiagonal()),
                nullptr, &state[3 * a], &state[3 * (a + 1)]);
        }
    }
    problem.SetParameterBlockConstant(&state[0]);  // the frame

    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    solver.max_num_iterations = options.max_iterations;
    solver.num_threads = int(threads);
    ceres::Solver::Summary summary;
    ceres::Solve(solver, &problem, &summary);
    if (!summary.IsSolutionUsable()) {
        std::string names;
        for (const auto& tr : traverses) names += (names.empty() ? "" : ", ") + tr.data->rawlog;
        throw std::runtime_error("pose graph over " + names + ": the optimisation failed (" +
                                 summary.message + ")");
    }
    rep.initial_cost = summary.initial_cost;
    rep.final_cost = summary.final_cost;

    // 5. Marginal covariances of every n-th keyframe (the first is fixed: zero).
    std::vector<std::optional<Eigen::Matrix3d>> keyframe_cov(keyframes.size());
    if (covariances && options.covariance_stride > 0) {
        mrpt::system::CTicTac cov_timer;
        ceres::Covariance::Options cov_options;
        cov_options.algorithm_type = ceres::SPARSE_QR;
        cov_options.num_threads = int(threads);
        ceres::Covariance covariance(cov_options);
        std::vector<std::pair<const double*, const double*>> blocks;
        std::vector<std::size_t> sampled;
        for (std::size_t t = 0; t < traverses.size(); ++t) {
            for (std::size_t k = ranges[t].first; k < ranges[t].second;
                 k += std::size_t(options.covariance_stride)) {
                if (k != 0) sampled.push_back(k);
            }
            if (ranges[t].second > ranges[t].first &&
                (sampled.empty() || sampled.back() != ranges[t].second - 1)) {
                sampled.push_back(ranges[t].second - 1);
            }
        }
        for (const std::size_t k : sampled) blocks.emplace_back(&state[3 * k], &state[3 * k]);
        if (covariance.Compute(blocks, &problem)) {
            rep.covariance_ok = true;
            keyframe_cov[0] = Eigen::Matrix3d::Zero();
            for (const std::size_t k : sampled) {
                Eigen::Matrix<double, 3, 3, Eigen::RowMajor> c;
                covariance.GetCovarianceBlock(&state[3 * k], &state[3 * k], c.data());
                keyframe_cov[k] = c;
            }
        }
        rep.covariance_time_s = cov_timer.Tac();
    }

    // Between two computed keyframes (each traverse's first and last are among them) the
    // covariance is interpolated by keyframe index.
    std::vector<Eigen::Matrix3d> interpolated_cov;
    if (rep.covariance_ok) {
        interpolated_cov.resize(keyframes.size());
        std::size_t prev = 0;
        for (std::size_t k = 0; k < keyframes.size(); ++k) {
            if (!keyframe_cov[k]) continue;
            for (std::size_t m = prev; m <= k; ++m) {
                const double w = k == prev ? 1.0 : double(m - prev) / double(k - prev);
                interpolated_cov[m] = (1 - w) * *keyframe_cov[prev] + w * *keyframe_cov[k];
            }
            prev = k;
        }
    }

    // 6. Every scan follows the keyframe at or before it: its first-estimate pose relative
    // to that keyframe is kept, the keyframe's correction (and covariance) applied.
    std::vector<common::PoseTrack> out;
    for (std::size_t t = 0; t < traverses.size(); ++t) {
        common::PoseTrack track = traverses[t].initial;
        std::vector<mrpt::math::CMatrixDouble33> covs;
        std::size_t k = ranges[t].first;
        for (std::size_t i = 0; i < track.size(); ++i) {
            while (k + 1 < ranges[t].second && keyframes[k + 1].scan <= i) ++k;
            const mrpt::poses::CPose2D optimised(state[3 * k], state[3 * k + 1], state[3 * k + 2]);
            const mrpt::poses::CPose2D relative =
                mrpt::poses::CPose2D(traverses[t].initial[i].pose) - keyframes[k].initial;
            track[i].pose = mrpt::poses::CPose3D(optimised + relative);
            if (!interpolated_cov.empty()) covs.emplace_back(interpolated_cov[k]);
        }
        out.push_back(std::move(track));
        if (covariances) covariances->push_back(std::move(covs));
    }
    if (progress) progress(1.0);
    rep.time_s = timer.Tac();
    if (report) *report = rep;
    return out;
}

mrpt::maps::COccupancyGridMap2D gridFromTracks(const std::vector<GraphTraverse>& traverses,
                                               const std::vector<common::PoseTrack>& tracks,
                                               const mrpt::config::CConfigFileBase& config) {
    if (tracks.size() != traverses.size()) {
        throw std::invalid_argument("gridFromTracks: one track per traverse expected");
    }
    const std::string prefix = "MappingApplication_occupancyGrid_00_";
    double min_x = 1e300, max_x = -1e300, min_y = 1e300, max_y = -1e300;
    for (const auto& track : tracks) {
        for (const auto& p : track) {
            min_x = std::min(min_x, p.pose.x());
            max_x = std::max(max_x, p.pose.x());
            min_y = std::min(min_y, p.pose.y());
            max_y = std::max(max_y, p.pose.y());
        }
    }
    if (min_x > max_x) throw std::invalid_argument("gridFromTracks: no poses");
    const double resolution = config.read_double(prefix + "creationOpts", "resolution", 0.05);
    mrpt::maps::COccupancyGridMap2D grid;
    grid.insertionOptions.loadFromConfigFile(config, prefix + "insertOpts");
    const double margin = grid.insertionOptions.maxDistanceInsertion + 1.0;
    grid.setSize(float(min_x - margin), float(max_x + margin), float(min_y - margin),
                 float(max_y + margin), float(resolution));
    for (std::size_t t = 0; t < traverses.size(); ++t) {
        const auto scans = scansOf(*traverses[t].data);
        if (scans.size() != tracks[t].size()) {
            throw std::invalid_argument("gridFromTracks: " + traverses[t].data->rawlog +
                                        ": scan and pose counts differ");
        }
        for (std::size_t i = 0; i < scans.size(); ++i) {
            const mrpt::poses::CPose3D pose(mrpt::poses::CPose2D(tracks[t][i].pose));
            grid.insertObservation(*scans[i].scan, pose);
        }
    }
    return grid;
}

}  // namespace lookup::survey

#include "lookup/survey/pose_graph.h"

#include <ceres/ceres.h>
#include <mrpt/maps/CSimplePointsMap.h>
#include <mrpt/obs/CObservation2DRangeScan.h>
#include <mrpt/obs/CObservationOdometry.h>
#include <mrpt/poses/CPoint2D.h>
#include <mrpt/system/CTicTac.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>
#include <functional>
#include <optional>
#include <stdexcept>
#include <thread>

#include "lookup/common/config.h"
#include "lookup/common/odometry_track.h"
#include "lookup/common/parallel_for.h"

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
    t.add("odometry_gap_s", odometry_gap_s, common::kPositive);
    t.add("odometry_gap_accel_mps2", odometry_gap_accel_mps2, 0.0);
    t.add("odometry_gap_yaw_accel_deg_s2", odometry_gap_yaw_accel_deg_s2, 0.0);
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

/// The traverse's range scans in order.
std::vector<const mrpt::obs::CObservation2DRangeScan*> rangeScans(const TraverseData& traverse) {
    std::vector<const mrpt::obs::CObservation2DRangeScan*> out;
    for (const auto& o : traverse.laser_sequence) {
        if (auto scan = std::dynamic_pointer_cast<mrpt::obs::CObservation2DRangeScan>(o)) {
            out.push_back(scan.get());
        }
    }
    return out;
}

/// The traverse's scans in order, each with the odometry at its time (interpolated between the
/// readings around it) and how long it lies from the nearer reading inside a dropout.
struct ScanWithOdometry {
    const mrpt::obs::CObservation2DRangeScan* scan;
    mrpt::poses::CPose2D odometry;
    double uncovered_s = 0;
};

std::vector<ScanWithOdometry> scansOf(const TraverseData& traverse, double gap_s) {
    common::OdometryTrack odometry;
    for (const auto& o : traverse.laser_sequence) {
        if (auto odo = std::dynamic_pointer_cast<mrpt::obs::CObservationOdometry>(o)) {
            odometry.add(mrpt::Clock::toDouble(odo->timestamp), odo->odometry);
        }
    }
    std::vector<ScanWithOdometry> out;
    for (const auto* scan : rangeScans(traverse)) {
        ScanWithOdometry s{scan, {}, 0.0};
        constexpr double kAnyTime = 1e9;
        if (const auto p = odometry.at(mrpt::Clock::toDouble(scan->timestamp), kAnyTime)) {
            s.odometry = p->pose;
            s.uncovered_s = p->extrapolated_s + (p->gap_s > gap_s ? p->inside_gap_s : 0.0);
        }
        out.push_back(s);
    }
    return out;
}

struct Keyframe {
    std::size_t traverse = 0, scan = 0;
    mrpt::poses::CPose2D initial, odometry;
    double uncovered_s = 0;  ///< ScanWithOdometry::uncovered_s
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

/// Keyframes of all traverses, in traverse order, with each traverse's scans.
struct KeyframeSet {
    std::vector<std::vector<ScanWithOdometry>> scans;         ///< per traverse
    std::vector<common::PoseTrack> initial;                   ///< first estimate per traverse
    std::vector<Keyframe> keyframes;                          ///< all traverses, in order
    std::vector<std::pair<std::size_t, std::size_t>> ranges;  ///< [first, end) per traverse
};

/// The first estimate with every scan inside an odometry dropout dead-reckoned from the scan
/// before it: without odometry, ICP-SLAM along a featureless drive stands still or wanders
/// (its scans match at any offset along the drive).
common::PoseTrack bridgedDropouts(const common::PoseTrack& initial,
                                  const std::vector<ScanWithOdometry>& scans) {
    common::PoseTrack out = initial;
    for (std::size_t i = 1; i < out.size(); ++i) {
        if (scans[i].uncovered_s <= 0) continue;
        const mrpt::poses::CPose2D step = scans[i].odometry - scans[i - 1].odometry;
        out[i].pose = mrpt::poses::CPose3D(mrpt::poses::CPose2D(out[i - 1].pose) + step);
    }
    return out;
}

/// Appends the keyframes of traverse `t`: the first scan, then every scan where the first
/// estimate has travelled keyframe_spacing_m or turned keyframe_spacing_deg since the last
/// keyframe, every scan inside an odometry dropout and the first after it (each then holds
/// the odometry's own motion), and the last scan.
void addKeyframes(std::size_t t, const PoseGraphOptions& options, KeyframeSet& set) {
    const auto& scans = set.scans[t];
    const auto& initial = set.initial[t];
    auto& keyframes = set.keyframes;
    const std::size_t first = keyframes.size();
    double travelled = 0;
    for (std::size_t i = 0; i < scans.size(); ++i) {
        const mrpt::poses::CPose2D pose(initial[i].pose);
        if (i > 0) {
            const mrpt::poses::CPose2D prev(initial[i - 1].pose);
            travelled += std::hypot(pose.x() - prev.x(), pose.y() - prev.y());
        }
        if (keyframes.size() > first) {
            const auto& last = keyframes.back();
            const bool far = travelled - last.travelled_m >= options.keyframe_spacing_m;
            const bool turned = std::abs(mrpt::math::wrapToPi(pose.phi() - last.initial.phi())) >=
                                mrpt::DEG2RAD(options.keyframe_spacing_deg);
            const bool dropout =
                scans[i].uncovered_s > 0 || (i > 0 && scans[i - 1].uncovered_s > 0);
            if (!far && !turned && !dropout && i + 1 < scans.size()) continue;
        }
        Keyframe k;
        k.traverse = t;
        k.scan = i;
        k.initial = pose;
        k.odometry = scans[i].odometry;
        k.uncovered_s = scans[i].uncovered_s;
        k.travelled_m = travelled;
        keyframes.push_back(std::move(k));
    }
    set.ranges.emplace_back(first, keyframes.size());
}

KeyframeSet selectKeyframes(const std::vector<GraphTraverse>& traverses,
                            const PoseGraphOptions& options) {
    KeyframeSet set;
    for (std::size_t t = 0; t < traverses.size(); ++t) {
        const auto& tr = traverses[t];
        set.scans.push_back(scansOf(*tr.data, options.odometry_gap_s));
        if (set.scans[t].size() != tr.initial.size()) {
            throw std::invalid_argument("optimisePoseGraph: " + tr.data->rawlog + ": " +
                                        std::to_string(set.scans[t].size()) + " scans but " +
                                        std::to_string(tr.initial.size()) + " poses");
        }
        set.initial.push_back(bridgedDropouts(tr.initial, set.scans[t]));
        addKeyframes(t, options, set);
    }
    return set;
}

/// Along each traverse: the next keyframes within max_edge_distance_m of travel, spread so both
/// short and long baselines tie each keyframe.
void addAlongTraversePairs(const KeyframeSet& set, const PoseGraphOptions& options,
                           std::vector<Pair>& pairs) {
    const auto& keyframes = set.keyframes;
    for (const auto& [first, end] : set.ranges) {
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
}

/// Across traverses t < u: for each keyframe of t, the keyframes of u whose first estimate lies
/// within half of max_edge_distance_m of its own.
void addCrossTraversePairs(const KeyframeSet& set, std::size_t t, std::size_t u,
                           const PoseGraphOptions& options, std::vector<Pair>& pairs) {
    const auto& keyframes = set.keyframes;
    const auto [u_first, u_end] = set.ranges[u];
    mrpt::maps::CSimplePointsMap positions;
    for (std::size_t b = u_first; b < u_end; ++b) {
        positions.insertPoint(float(keyframes[b].initial.x()), float(keyframes[b].initial.y()), 0);
    }
    if (positions.size() == 0) return;
    const double half_window = 0.5 * options.max_edge_distance_m;
    for (std::size_t a = set.ranges[t].first; a < set.ranges[t].second; ++a) {
        float d2;
        const std::size_t near =
            u_first + positions.kdTreeClosestPoint2D(float(keyframes[a].initial.x()),
                                                     float(keyframes[a].initial.y()), d2);
        if (d2 > half_window * half_window) continue;
        std::size_t lo = near, hi = near;
        const auto within = [&](std::size_t b) {
            return std::hypot(keyframes[b].initial.x() - keyframes[a].initial.x(),
                              keyframes[b].initial.y() - keyframes[a].initial.y()) <= half_window;
        };
        while (lo > u_first && within(lo - 1)) --lo;
        while (hi + 1 < u_end && within(hi + 1)) ++hi;
        spread(lo, hi, options.cross_edges_per_keyframe, [&](std::size_t b) {
            pairs.push_back({a, b, true});
        });
    }
}

/// Which keyframes to register: along the own traverse, then across traverses.
std::vector<Pair> keyframePairs(const KeyframeSet& set, const PoseGraphOptions& options) {
    std::vector<Pair> pairs;
    addAlongTraversePairs(set, options, pairs);
    if (options.cross_edges_per_keyframe > 0) {
        for (std::size_t t = 0; t < set.ranges.size(); ++t) {
            for (std::size_t u = t + 1; u < set.ranges.size(); ++u) {
                addCrossTraversePairs(set, t, u, options, pairs);
            }
        }
    }
    return pairs;
}

/// Scan points (normals, KD-trees) of every keyframe, on all threads.
void computeScanPoints(KeyframeSet& set, unsigned threads) {
    common::parallelFor(set.keyframes.size(), threads, [&](std::size_t k) {
        auto& keyframe = set.keyframes[k];
        keyframe.points = scanPoints(*set.scans[keyframe.traverse][keyframe.scan].scan);
    });
}

/// The registration of every pair from the first estimate, on all threads; `progress` up to
/// 0.95 while they run.
std::vector<Registration> registerPairs(const std::vector<Keyframe>& keyframes,
                                        const std::vector<Pair>& pairs, unsigned threads,
                                        const GraphProgressFn& progress) {
    std::vector<Registration> results(pairs.size());
    std::function<void(std::size_t)> report;
    if (progress) {
        report = [&](std::size_t done) {
            progress(0.95 * double(done) / double(std::max<std::size_t>(1, pairs.size())));
        };
    }
    common::parallelFor(
        pairs.size(), threads,
        [&](std::size_t p) {
            const auto& ka = keyframes[pairs[p].a];
            const auto& kb = keyframes[pairs[p].b];
            results[p] = registerPointToLine(ka.points, kb.points, kb.initial - ka.initial);
        },
        report);
    return results;
}

std::vector<double> initialState(const std::vector<Keyframe>& keyframes) {
    std::vector<double> state(3 * keyframes.size());
    for (std::size_t k = 0; k < keyframes.size(); ++k) {
        state[3 * k] = keyframes[k].initial.x();
        state[3 * k + 1] = keyframes[k].initial.y();
        state[3 * k + 2] = keyframes[k].initial.phi();
    }
    return state;
}

/// One edge per plausible registration (matched enough, correcting the first estimate by less
/// than max_correction_m / _deg, finite covariance); the others are counted as rejected.
void addRegistrationEdges(const std::vector<Keyframe>& keyframes, const std::vector<Pair>& pairs,
                          const std::vector<Registration>& results, const PoseGraphOptions& options,
                          std::vector<double>& state, ceres::Problem& problem,
                          PoseGraphReport& rep) {
    const double min_yaw_std = mrpt::DEG2RAD(options.registration_min_std_yaw_deg);
    for (std::size_t p = 0; p < pairs.size(); ++p) {
        const Registration& r = results[p];
        const auto& ka = keyframes[pairs[p].a];
        const auto& kb = keyframes[pairs[p].b];
        const mrpt::poses::CPose2D correction = r.pose - (kb.initial - ka.initial);
        // A first estimate dead-reckoned through an odometry dropout may be off by what the
        // vehicle's accelerations allow (3 sigmas of it) on top of the usual correction.
        const double u2 = ka.uncovered_s * ka.uncovered_s + kb.uncovered_s * kb.uncovered_s;
        const double max_m = options.max_correction_m + 1.5 * options.odometry_gap_accel_mps2 * u2;
        const double max_deg =
            options.max_correction_deg + 1.5 * options.odometry_gap_yaw_accel_deg_s2 * u2;
        if (!r.ok || r.matched_share < options.min_matched_share ||
            std::hypot(correction.x(), correction.y()) > max_m ||
            std::abs(correction.phi()) > mrpt::DEG2RAD(max_deg)) {
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
}

/// Weak odometry links between consecutive keyframes keep each traverse connected where scans
/// match nothing.
void addOdometryEdges(const KeyframeSet& set, const PoseGraphOptions& options,
                      std::vector<double>& state, ceres::Problem& problem) {
    for (const auto& [first, end] : set.ranges) {
        for (std::size_t a = first; a + 1 < end; ++a) {
            const auto& ka = set.keyframes[a];
            const auto& kb = set.keyframes[a + 1];
            const mrpt::poses::CPose2D motion = kb.odometry - ka.odometry;
            // Through a dropout the first estimate may stand still: the odometry's travel counts.
            const double d = std::max({0.05, kb.travelled_m - ka.travelled_m, motion.norm()});
            const double u2 = ka.uncovered_s * ka.uncovered_s + kb.uncovered_s * kb.uncovered_s;
            const double s_xy =
                options.odometry_std_per_m * d + 0.5 * options.odometry_gap_accel_mps2 * u2;
            const double s_yaw = mrpt::DEG2RAD(options.odometry_std_yaw_deg_per_m * d +
                                               0.5 * options.odometry_gap_yaw_accel_deg_s2 * u2);
            problem.AddResidualBlock(
                relativePoseCost(
                    motion, Eigen::Vector3d(s_xy * s_xy, s_xy * s_xy, s_yaw * s_yaw).asDiagonal()),
                nullptr, &state[3 * a], &state[3 * (a + 1)]);
        }
    }
}

// Ceres solves on one thread: with more it sums costs and Jacobian products per thread, and the
// last bits of the optimised poses would depend on the thread count.
void solveGraph(ceres::Problem& problem, const std::vector<GraphTraverse>& traverses,
                const PoseGraphOptions& options, PoseGraphReport& rep) {
    ceres::Solver::Options solver;
    solver.linear_solver_type = ceres::SPARSE_NORMAL_CHOLESKY;
    solver.max_num_iterations = options.max_iterations;
    solver.num_threads = 1;
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
}

/// Every covariance_stride-th keyframe of each traverse, every one inside an odometry dropout,
/// and its last (never keyframe 0, the fixed frame).
std::vector<std::size_t> covarianceKeyframes(const KeyframeSet& set, int stride) {
    std::vector<std::size_t> sampled;
    for (const auto& [first, end] : set.ranges) {
        for (std::size_t k = first; k < end; ++k) {
            // Inside a dropout the uncertainty differs from the neighbours': interpolating
            // past it would hide it.
            const bool due = (k - first) % std::size_t(stride) == 0;
            if (k != 0 && (due || set.keyframes[k].uncovered_s > 0)) sampled.push_back(k);
        }
        if (end > first && (sampled.empty() || sampled.back() != end - 1)) {
            sampled.push_back(end - 1);
        }
    }
    return sampled;
}

/// Marginal covariances of the sampled keyframes (the first is fixed: zero); all empty when
/// Ceres cannot compute them.
std::vector<std::optional<Eigen::Matrix3d>> keyframeCovariances(
    const KeyframeSet& set, const PoseGraphOptions& options, unsigned threads,
    std::vector<double>& state, ceres::Problem& problem, PoseGraphReport& rep) {
    std::vector<std::optional<Eigen::Matrix3d>> keyframe_cov(set.keyframes.size());
    mrpt::system::CTicTac cov_timer;
    ceres::Covariance::Options cov_options;
    cov_options.algorithm_type = ceres::SPARSE_QR;
    // Columns of the inverse are independent solves, so threads do not reorder sums; the
    // factorisation (SuiteSparseQR) can still differ in the last bits from run to run.
    cov_options.num_threads = int(threads);
    ceres::Covariance covariance(cov_options);
    const std::vector<std::size_t> sampled = covarianceKeyframes(set, options.covariance_stride);
    std::vector<std::pair<const double*, const double*>> blocks;
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
    return keyframe_cov;
}

/// Between two computed keyframes (each traverse's first and last are among them) the
/// covariance is interpolated by keyframe index.
std::vector<Eigen::Matrix3d> interpolateCovariances(
    const std::vector<std::optional<Eigen::Matrix3d>>& keyframe_cov) {
    std::vector<Eigen::Matrix3d> interpolated(keyframe_cov.size());
    std::size_t prev = 0;
    for (std::size_t k = 0; k < keyframe_cov.size(); ++k) {
        if (!keyframe_cov[k]) continue;
        for (std::size_t m = prev; m <= k; ++m) {
            const double w = k == prev ? 1.0 : double(m - prev) / double(k - prev);
            interpolated[m] = (1 - w) * *keyframe_cov[prev] + w * *keyframe_cov[k];
        }
        prev = k;
    }
    return interpolated;
}

/// `a` and `b` blended: w = 0 gives a, 1 gives b.
mrpt::poses::CPose2D blend(const mrpt::poses::CPose2D& a, const mrpt::poses::CPose2D& b, double w) {
    return {a.x() + w * (b.x() - a.x()), a.y() + w * (b.y() - a.y()),
            a.phi() + w * mrpt::math::wrapToPi(b.phi() - a.phi())};
}

/// Every scan between two keyframes is placed by the odometry's motion from each of them,
/// blended by time: run forward from the one before and back from the one after, the two meet
/// both optimised poses (an odometry scale error cancels). ICP-SLAM's own poses between
/// keyframes are no guide: it lags behind a vehicle starting from rest and stands still through
/// an odometry dropout. After a traverse's last keyframe, the odometry from it. Covariances:
/// the keyframe before's (when computed).
std::vector<common::PoseTrack> followKeyframes(
    const std::vector<GraphTraverse>& traverses, const KeyframeSet& set,
    const std::vector<double>& state, const std::vector<Eigen::Matrix3d>& keyframe_cov,
    std::vector<std::vector<mrpt::math::CMatrixDouble33>>* covariances) {
    const auto optimised = [&](std::size_t k) {
        return mrpt::poses::CPose2D(state[3 * k], state[3 * k + 1], state[3 * k + 2]);
    };
    std::vector<common::PoseTrack> out;
    for (std::size_t t = 0; t < traverses.size(); ++t) {
        const auto& scans = set.scans[t];
        common::PoseTrack track = traverses[t].initial;
        std::vector<mrpt::math::CMatrixDouble33> covs;
        const auto [first, end] = set.ranges[t];
        std::size_t k = first;
        for (std::size_t i = 0; i < track.size(); ++i) {
            while (k + 1 < end && set.keyframes[k + 1].scan <= i) ++k;
            const Keyframe& a = set.keyframes[k];
            mrpt::poses::CPose2D pose = optimised(k) + (scans[i].odometry - a.odometry);
            if (k + 1 < end && a.scan < i) {
                const Keyframe& b = set.keyframes[k + 1];
                const double t0 = track[a.scan].time_s, t1 = track[b.scan].time_s;
                const double w = t1 > t0 ? (track[i].time_s - t0) / (t1 - t0) : 0.0;
                pose = blend(pose, optimised(k + 1) + (scans[i].odometry - b.odometry), w);
            }
            track[i].pose = mrpt::poses::CPose3D(pose);
            if (!keyframe_cov.empty()) covs.emplace_back(keyframe_cov[k]);
        }
        out.push_back(std::move(track));
        if (covariances) covariances->push_back(std::move(covs));
    }
    return out;
}

}  // namespace

std::vector<common::PoseTrack> optimisePoseGraph(
    const std::vector<GraphTraverse>& traverses, const PoseGraphOptions& options,
    PoseGraphReport* report, const GraphProgressFn& progress,
    std::vector<std::vector<mrpt::math::CMatrixDouble33>>* covariances) {
    mrpt::system::CTicTac timer;
    PoseGraphReport rep;
    rep.traverses = traverses.size();
    KeyframeSet set = selectKeyframes(traverses, options);
    rep.keyframes = set.keyframes.size();
    if (set.keyframes.empty()) {
        std::vector<common::PoseTrack> same;
        for (const auto& tr : traverses) same.push_back(tr.initial);
        return same;
    }
    const unsigned threads = options.threads > 0
                                 ? unsigned(options.threads)
                                 : std::max(1u, std::thread::hardware_concurrency());
    const std::vector<Pair> pairs = keyframePairs(set, options);
    computeScanPoints(set, threads);
    const std::vector<Registration> registrations =
        registerPairs(set.keyframes, pairs, threads, progress);

    // One least-squares problem over all keyframe poses, the first fixed (the frame).
    std::vector<double> state = initialState(set.keyframes);
    ceres::Problem problem;
    addRegistrationEdges(set.keyframes, pairs, registrations, options, state, problem, rep);
    addOdometryEdges(set, options, state, problem);
    problem.SetParameterBlockConstant(&state[0]);
    solveGraph(problem, traverses, options, rep);

    std::vector<Eigen::Matrix3d> keyframe_cov;
    if (covariances && options.covariance_stride > 0) {
        const auto sampled = keyframeCovariances(set, options, threads, state, problem, rep);
        if (rep.covariance_ok) keyframe_cov = interpolateCovariances(sampled);
    }
    std::vector<common::PoseTrack> out =
        followKeyframes(traverses, set, state, keyframe_cov, covariances);
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
        const auto scans = rangeScans(*traverses[t].data);
        if (scans.size() != tracks[t].size()) {
            throw std::invalid_argument("gridFromTracks: " + traverses[t].data->rawlog +
                                        ": scan and pose counts differ");
        }
        for (std::size_t i = 0; i < scans.size(); ++i) {
            const mrpt::poses::CPose3D pose(mrpt::poses::CPose2D(tracks[t][i].pose));
            grid.insertObservation(*scans[i], pose);
        }
    }
    return grid;
}

}  // namespace lookup::survey

#include "lookup/eval/evaluator.h"

#include <mrpt/math/wrap2pi.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <map>
#include <optional>

#include "lookup/common/config.h"
#include "lookup/common/pose_files.h"

namespace lookup::eval {

void EvalOptions::declareKeys(common::OptionsTable& t) {
    t.add("coarse_exclusion_m", coarse_exclusion_m, common::kPositive);
    t.add("max_gt_gap_s", max_gt_gap_s, common::kPositive);
    t.add("confident_wrong_min_error_m", confident_wrong_min_error_m, common::kPositive);
}

void EvalOptions::check() const {
    common::OptionsCheck c("eval");
    checkRanges(c);
    c.throwIfFailed();
}

GroundTruth loadGroundTruth(const std::string& path) {
    GroundTruth gt;
    const std::string name = std::filesystem::path(path).filename().string();
    gt.traverse = name.substr(0, name.find('.'));
    gt.track = common::readPoseFile(path);
    return gt;
}

namespace {

/// Linear-interpolated quantile of sorted, non-empty values.
double sortedQuantile(const std::vector<double>& e, double q) {
    const double pos = q * (e.size() - 1);
    const size_t lo = static_cast<size_t>(std::floor(pos));
    const size_t hi = std::min(lo + 1, e.size() - 1);
    return e[lo] + (pos - lo) * (e[hi] - e[lo]);
}

}  // namespace

ErrorStats summarize(std::vector<double> e) {
    ErrorStats s;
    s.count = e.size();
    if (e.empty()) return s;
    std::sort(e.begin(), e.end());
    double sum = 0;
    for (double v : e) sum += v;
    s.mean_m = sum / e.size();
    s.median_m = sortedQuantile(e, 0.5);
    s.p95_m = sortedQuantile(e, 0.95);
    s.max_m = e.back();
    return s;
}

namespace {

// Chi-square quantiles with 2 degrees of freedom: -2 ln(1 - p).
constexpr double kChi2_2dof_95 = 5.991464547107979;
constexpr double kChi2_2dof_997 = 11.618285696058;

const GroundTruth* truthFor(const std::vector<GroundTruth>& truths, const Run& run) {
    // Traverses have disjoint time bases, so the truth covering most frames is the right one.
    const GroundTruth* best = nullptr;
    size_t best_count = 0;
    for (const auto& gt : truths) {
        const double t0 = gt.track.front().time_s, t1 = gt.track.back().time_s;
        size_t count = 0;
        for (const auto& f : run.frames) count += (f.time_s >= t0 && f.time_s <= t1);
        if (count > best_count) best = &gt, best_count = count;
    }
    return best;
}

/// Squared Mahalanobis distance of a position error under the frame's reported covariance;
/// infinite where that covariance is not positive definite (it claims certainty).
double mahalanobis2(const FrameRow& f, double ex, double ey) {
    const double det = f.cov_xx * f.cov_yy - f.cov_xy * f.cov_xy;
    if (!(det > 0) || !(f.cov_xx > 0)) return std::numeric_limits<double>::infinity();
    return (f.cov_yy * ex * ex - 2 * f.cov_xy * ex * ey + f.cov_xx * ey * ey) / det;
}

/// Per-run tallies while walking its frames against the truth.
struct Tally {
    std::vector<double> errors, coarse_errors, yaw_errors, height_errors, frame_ms;
    size_t refined = 0, refined_inside = 0, coarse_frames = 0;
    size_t evaluated_after_fix = 0, refined_after_fix = 0;
    double driven_m = 0;
    std::optional<mrpt::poses::CPose3D> last_truth;
};

/// Time to first fix and integrity, over every frame with ground truth (excluded ones too:
/// a confident wrong pose is a failure whatever the coarse stage did).
void scoreIntegrity(const FrameRow& f, size_t index, const mrpt::poses::CPose3D& truth,
                    double first_time_s, const EvalOptions& o, Tally& t, MethodResult& m) {
    if (t.last_truth)
        t.driven_m += std::hypot(truth.x() - t.last_truth->x(), truth.y() - t.last_truth->y());
    t.last_truth = truth;
    if (f.status == "refined" && m.first_fix_frame < 0) {
        m.first_fix_frame = static_cast<long>(index);
        m.first_fix_s = f.time_s - first_time_s;
        m.first_fix_distance_m = t.driven_m;
    }
    if (!f.has_pose) return;
    const double ex = f.x - truth.x(), ey = f.y - truth.y();
    if (std::hypot(ex, ey) > o.confident_wrong_min_error_m &&
        mahalanobis2(f, ex, ey) > kChi2_2dof_997) {
        ++m.confident_wrong;
    }
}

/// Accuracy over the frames the paper's rule keeps.
void scoreAccuracy(const FrameRow& f, const mrpt::poses::CPose3D& truth, bool after_fix, Tally& t,
                   MethodResult& m) {
    t.evaluated_after_fix += after_fix;
    if (!f.has_pose) {
        ++m.without_pose;
        return;
    }
    const double ex = f.x - truth.x(), ey = f.y - truth.y();
    t.errors.push_back(std::hypot(ex, ey));
    t.yaw_errors.push_back(std::abs(mrpt::math::wrapToPi(f.yaw - truth.yaw())));
    if (f.has_z) t.height_errors.push_back(std::abs(f.z - truth.z()));
    if (f.status != "refined") return;
    ++t.refined;
    t.refined_after_fix += after_fix;
    t.refined_inside += mahalanobis2(f, ex, ey) <= kChi2_2dof_95;
}

void finishRow(Tally& t, MethodResult& m) {
    const size_t evaluated = m.frames - m.excluded;
    m.error = summarize(t.errors);
    m.height = summarize(t.height_errors);
    m.acceptance_share = evaluated ? static_cast<double>(t.refined) / evaluated : 0;
    m.inside_95_share = t.refined ? static_cast<double>(t.refined_inside) / t.refined : 0;
    m.refined_after_first_fix_share =
        t.evaluated_after_fix ? static_cast<double>(t.refined_after_fix) / t.evaluated_after_fix
                              : 0;
    double yaw_sum = 0;
    for (double v : t.yaw_errors) yaw_sum += v;
    m.yaw_error_mean_deg = t.yaw_errors.empty() ? 0 : yaw_sum / t.yaw_errors.size() * 180 / M_PI;
    if (!t.frame_ms.empty()) {
        std::sort(t.frame_ms.begin(), t.frame_ms.end());
        m.frame_ms_p99 = sortedQuantile(t.frame_ms, 0.99);
    }
}

FrameTrace traceFrame(const FrameRow& f, const mrpt::poses::CPose3D& truth, double driven_m,
                      const EvalOptions& o) {
    FrameTrace ft;
    ft.distance_m = driven_m;
    ft.truth_x = truth.x();
    ft.truth_y = truth.y();
    ft.status = f.status;
    ft.has_pose = f.has_pose;
    ft.x = f.x;
    ft.y = f.y;
    if (f.has_pose) ft.error_m = std::hypot(f.x - truth.x(), f.y - truth.y());
    if (f.has_coarse) {
        ft.coarse_error_m = std::hypot(f.coarse_x - truth.x(), f.coarse_y - truth.y());
        ft.excluded = ft.coarse_error_m > o.coarse_exclusion_m;
    }
    return ft;
}

}  // namespace

MethodResult scoreRun(const Run& run, const GroundTruth& gt, const EvalOptions& options,
                      MethodResult* coarse, RunTrace* trace) {
    if (trace) {
        trace->traverse = gt.traverse;
        trace->method = run.method;
        trace->frames.clear();
    }
    auto interp = common::makeInterpolator(gt.track, options.max_gt_gap_s);
    MethodResult m;
    m.traverse = gt.traverse;
    m.method = run.method;
    m.run_directory = run.directory;
    m.frames_per_s = run.frames_per_s;
    m.match_ms_per_frame = run.match_ms_per_frame;
    m.frames_dropped = run.frames_dropped;
    m.flagged = run.flagged;
    Tally t;
    double first_time_s = 0;
    for (size_t i = 0; i < run.frames.size(); ++i) {
        const FrameRow& f = run.frames[i];
        if (f.status != "dropped" && f.ms > 0) t.frame_ms.push_back(f.ms);
        const auto truth_at = common::poseAt(interp, f.time_s);
        if (!truth_at) continue;
        const mrpt::poses::CPose3D& truth = *truth_at;
        if (m.frames++ == 0) first_time_s = f.time_s;
        const bool after_fix = m.first_fix_frame >= 0;
        scoreIntegrity(f, i, truth, first_time_s, options, t, m);
        if (trace) trace->frames.push_back(traceFrame(f, truth, t.driven_m, options));
        if (f.has_coarse) {
            const double ce = std::hypot(f.coarse_x - truth.x(), f.coarse_y - truth.y());
            if (ce > options.coarse_exclusion_m) {
                ++m.excluded;
                continue;
            }
            t.coarse_errors.push_back(ce);
            ++t.coarse_frames;
        }
        scoreAccuracy(f, truth, after_fix || f.status == "refined", t, m);
    }
    finishRow(t, m);
    if (coarse != nullptr) {
        coarse->traverse = gt.traverse;
        coarse->method = "coarse";
        coarse->run_directory = run.directory;
        coarse->flagged = run.flagged;
        coarse->frames = t.coarse_frames > 0 ? m.frames : 0;
        coarse->excluded = m.excluded;
        coarse->error = summarize(t.coarse_errors);
    }
    return m;
}

Report evaluate(const std::vector<GroundTruth>& truths, const std::vector<Run>& runs,
                const EvalOptions& options) {
    options.check();
    Report report;
    report.options = options;
    std::map<std::string, bool> coarse_done;
    for (const auto& run : runs) {
        const GroundTruth* gt = truthFor(truths, run);
        if (gt == nullptr) {
            report.warnings.push_back(run.directory + ": no ground truth covers its time stamps");
            continue;
        }
        MethodResult coarse;
        report.traces.emplace_back();
        MethodResult m = scoreRun(run, *gt, options, &coarse, &report.traces.back());
        if (coarse.frames > 0 && !coarse_done[gt->traverse]) {
            coarse_done[gt->traverse] = true;
            report.rows.push_back(coarse);
        }
        report.rows.push_back(m);
    }
    std::stable_sort(
        report.rows.begin(), report.rows.end(),
        [](const MethodResult& a, const MethodResult& b) { return a.traverse < b.traverse; });
    return report;
}

}  // namespace lookup::eval

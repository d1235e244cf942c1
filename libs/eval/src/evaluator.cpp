#include "lookup/eval/evaluator.h"

#include <mrpt/math/wrap2pi.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "lookup/common/config.h"

namespace lookup::eval {

void EvalOptions::loadFromConfigFile(const mrpt::config::CConfigFileBase& source,
                                     const std::string& section) {
    const common::IniSection s(source, section, "eval options");
    coarse_exclusion_m = s.getDouble("coarse_exclusion_m", coarse_exclusion_m);
    max_gt_gap_s = s.getDouble("max_gt_gap_s", max_gt_gap_s);
    check();
}

void EvalOptions::saveToConfigFile(mrpt::config::CConfigFileBase& target,
                                   const std::string& section) const {
    target.write(section, "coarse_exclusion_m", coarse_exclusion_m);
    target.write(section, "max_gt_gap_s", max_gt_gap_s);
}

void EvalOptions::check() const {
    common::OptionsCheck c("eval");
    c.require(coarse_exclusion_m > 0, "coarse_exclusion_m", "> 0");
    c.require(max_gt_gap_s > 0, "max_gt_gap_s", "> 0");
    c.throwIfFailed();
}

GroundTruth loadGroundTruth(const std::string& path) {
    GroundTruth gt;
    const std::string name = std::filesystem::path(path).filename().string();
    gt.traverse = name.substr(0, name.find('.'));
    gt.track = common::readPoseFile(path);
    return gt;
}

ErrorStats summarize(std::vector<double> e) {
    ErrorStats s;
    s.count = e.size();
    if (e.empty()) return s;
    std::sort(e.begin(), e.end());
    double sum = 0;
    for (double v : e) sum += v;
    s.mean_m = sum / e.size();
    const auto quantile = [&](double q) {
        const double pos = q * (e.size() - 1);
        const size_t lo = static_cast<size_t>(std::floor(pos));
        const size_t hi = std::min(lo + 1, e.size() - 1);
        return e[lo] + (pos - lo) * (e[hi] - e[lo]);
    };
    s.median_m = quantile(0.5);
    s.p95_m = quantile(0.95);
    s.max_m = e.back();
    return s;
}

namespace {

constexpr double kChi2_2dof_95 = 5.991464547107979;

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

}  // namespace

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
        auto interp = common::makeInterpolator(gt->track, options.max_gt_gap_s);

        MethodResult m, coarse;
        m.traverse = coarse.traverse = gt->traverse;
        m.method = run.method;
        coarse.method = "coarse";
        m.run_directory = coarse.run_directory = run.directory;
        m.frames_per_s = run.frames_per_s;
        m.match_ms_per_frame = run.match_ms_per_frame;
        m.frames_dropped = run.frames_dropped;
        m.flagged = coarse.flagged = run.flagged;
        std::vector<double> errors, coarse_errors, yaw_errors;
        size_t refined = 0, refined_inside = 0, coarse_frames = 0;

        for (const auto& f : run.frames) {
            mrpt::poses::CPose3D truth;
            bool valid = false;
            interp.interpolate(mrpt::Clock::fromDouble(f.time_s), truth, valid);
            if (!valid) continue;
            ++m.frames;
            if (f.has_coarse) {
                const double ce = std::hypot(f.coarse_x - truth.x(), f.coarse_y - truth.y());
                if (ce > options.coarse_exclusion_m) {
                    ++m.excluded;
                    continue;
                }
                coarse_errors.push_back(ce);
                ++coarse_frames;
            }
            if (!f.has_pose) {
                ++m.without_pose;
                continue;
            }
            const double ex = f.x - truth.x(), ey = f.y - truth.y();
            errors.push_back(std::hypot(ex, ey));
            yaw_errors.push_back(std::abs(mrpt::math::wrapToPi(f.yaw - truth.yaw())));
            if (f.status == "refined") {
                ++refined;
                const double det = f.cov_xx * f.cov_yy - f.cov_xy * f.cov_xy;
                if (det > 0) {
                    const double d2 =
                        (f.cov_yy * ex * ex - 2 * f.cov_xy * ex * ey + f.cov_xx * ey * ey) / det;
                    refined_inside += d2 <= kChi2_2dof_95;
                }
            }
        }
        const size_t evaluated = m.frames - m.excluded;
        m.error = summarize(errors);
        m.acceptance_share = evaluated ? static_cast<double>(refined) / evaluated : 0;
        m.inside_95_share = refined ? static_cast<double>(refined_inside) / refined : 0;
        double yaw_sum = 0;
        for (double v : yaw_errors) yaw_sum += v;
        m.yaw_error_mean_deg = yaw_errors.empty() ? 0 : yaw_sum / yaw_errors.size() * 180 / M_PI;

        if (coarse_frames > 0 && !coarse_done[gt->traverse]) {
            coarse_done[gt->traverse] = true;
            coarse.frames = m.frames;
            coarse.excluded = m.excluded;
            coarse.error = summarize(coarse_errors);
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

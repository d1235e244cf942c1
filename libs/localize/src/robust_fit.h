#pragma once
// The two-term robust line fit the localiser's self-calibrations share (camera_clock.h,
// readout_estimator.h).

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <optional>
#include <vector>

namespace lookup::localize::detail {

struct LineFit {
    double slope = 0, sigma = 0;              ///< of x
    double nuisance = 0, nuisance_sigma = 0;  ///< of z
};

/// y = slope x + nuisance z over the samples by least squares, those beyond 3 robust
/// deviations dropped and refitted (five times); sigmas from the inliers' scatter. None when x
/// and z do not vary apart (nothing to see).
template <class Samples, class X, class Z, class Y>
std::optional<LineFit> robustFit(const Samples& samples, X x, Z z, Y y) {
    constexpr int kIterations = 5;
    constexpr double kInlierMads = 3.0;
    std::vector<double> w(samples.size(), 1.0), res(samples.size());
    double slope = 0, nuisance = 0, det = 0, sxx = 0, s11 = 0, mad = 0;
    for (int it = 0; it < kIterations; ++it) {
        double sx1 = 0, sxr = 0, s1r = 0;
        sxx = s11 = 0;
        for (std::size_t k = 0; k < samples.size(); ++k) {
            const auto& p = samples[k];
            sxx += w[k] * x(p) * x(p);
            sx1 += w[k] * x(p) * z(p);
            s11 += w[k] * z(p) * z(p);
            sxr += w[k] * x(p) * y(p);
            s1r += w[k] * z(p) * y(p);
        }
        det = sxx * s11 - sx1 * sx1;
        if (!(det > 0)) return std::nullopt;
        slope = (sxr * s11 - sx1 * s1r) / det;
        nuisance = (sxx * s1r - sx1 * sxr) / det;
        for (std::size_t k = 0; k < samples.size(); ++k) {
            res[k] = std::abs(y(samples[k]) - slope * x(samples[k]) - nuisance * z(samples[k]));
        }
        std::vector<double> sorted = res;
        std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
        mad = 1.4826 * sorted[sorted.size() / 2] + 1e-9;
        for (std::size_t k = 0; k < samples.size(); ++k) w[k] = res[k] < kInlierMads * mad ? 1 : 0;
    }
    return LineFit{slope, mad * std::sqrt(s11 / det), nuisance, mad * std::sqrt(sxx / det)};
}

}  // namespace lookup::localize::detail

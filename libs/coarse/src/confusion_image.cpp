#include "lookup/coarse/confusion_image.h"

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace lookup::coarse {

void writeConfusionImage(const std::string& png_path, const ReferenceDescriptors& references,
                         const std::vector<Descriptor>& queries,
                         const std::vector<CoarseResult>& results,
                         const std::vector<std::size_t>& truth,
                         const ConfusionImageOptions& options) {
    const int n = static_cast<int>(references.size());
    const int m = static_cast<int>(queries.size());
    if (n == 0 || m == 0) throw std::invalid_argument(png_path + ": empty confusion matrix");
    if (results.size() != queries.size() || (!truth.empty() && truth.size() != queries.size())) {
        throw std::invalid_argument(png_path + ": results/truth and queries differ in length");
    }
    cv::Mat z(n, m, CV_32F);
    std::vector<double> col(n);
    const int r = options.contrast_window_refs;
    for (int q = 0; q < m; ++q) {
        for (int i = 0; i < n; ++i)
            col[i] = descriptorDifference(queries[q], references.descriptor(i));
        for (int i = 0; i < n; ++i) {
            const int lo = std::max(0, i - r), hi = std::min(n - 1, i + r);
            double s = 0, s2 = 0;
            for (int k = lo; k <= hi; ++k) s += col[k], s2 += col[k] * col[k];
            const double cnt = hi - lo + 1, mean = s / cnt;
            const double sd = std::max(0.05, std::sqrt(std::max(0.0, s2 / cnt - mean * mean)));
            z.at<float>(i, q) = static_cast<float>((col[i] - mean) / sd);
        }
    }
    const double scale = std::min(1.0, static_cast<double>(options.max_side_px) / std::max(n, m));
    cv::Mat shown = z;
    if (scale < 1.0) {
        cv::resize(z, shown, cv::Size(), scale, scale, cv::INTER_AREA);
    }
    // z of -3 (a clear match) is brightest, +1 and above dark.
    cv::Mat grey;
    shown.convertTo(grey, CV_8U, -255.0 / 4.0, 255.0 / 4.0);
    cv::Mat colour;
    cv::applyColorMap(grey, colour, cv::COLORMAP_INFERNO);
    auto dot = [&](int q, std::size_t ref, const cv::Scalar& c) {
        const cv::Point p(static_cast<int>(q * scale), static_cast<int>(ref * scale));
        cv::circle(colour, p, 1, c, cv::FILLED);
    };
    for (int q = 0; q < m; ++q) {
        if (!truth.empty() && truth[q] != CoarseResult::kNone) dot(q, truth[q], {255, 255, 255});
    }
    for (int q = 0; q < m; ++q) {
        if (!results[q].hasMatch()) continue;
        dot(q, results[q].reference_index,
            results[q].usable() ? cv::Scalar(0, 220, 0) : cv::Scalar(0, 0, 255));
    }
    bool ok = false;
    try {
        ok = cv::imwrite(png_path, colour);
    } catch (const cv::Exception& e) {
        throw std::runtime_error(png_path + ": cannot write the confusion image: " + e.what());
    }
    if (!ok) throw std::runtime_error(png_path + ": cannot write the confusion image");
}

}  // namespace lookup::coarse

#include "lookup/refine/matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

namespace lookup::refine {

const char* toString(MatchStatus s) {
    switch (s) {
        case MatchStatus::Matched:
            return "matched";
        case MatchStatus::LowTexture:
            return "low texture";
        case MatchStatus::NotDistinctive:
            return "not distinctive";
        case MatchStatus::BorderPeak:
            return "peak on the search-window border";
        default:
            return "outside the image";
    }
}

cv::Mat removeIllumination(const cv::Mat& grey, double sigma) {
    if (sigma <= 0.0) return grey;
    // The blur runs on a pyrDown'ed copy (the illumination is smooth) and is upsampled
    // bilinearly: 0.2 ms instead of 0.7 ms for a full resolution float blur of a 320 x 240
    // image at sigma 8.
    cv::Mat small = grey;
    double small_sigma = sigma;
    while (small_sigma >= 4.0 && small.cols >= 16 && small.rows >= 16) {
        cv::Mat down;
        cv::pyrDown(small, down);
        small = down;
        small_sigma /= 2.0;
    }
    cv::Mat blurred, illumination, out;
    cv::GaussianBlur(small, blurred, cv::Size(0, 0), small_sigma);
    cv::resize(blurred, illumination, grey.size(), 0, 0, cv::INTER_LINEAR);
    cv::subtract(grey, illumination, out, cv::noArray(), grey.depth() == CV_32F ? CV_32F : CV_16S);
    return out;
}

cv::Mat stretchContrast(const cv::Mat& texture, double max_gain) {
    cv::Scalar mean, stddev;
    cv::meanStdDev(texture, mean, stddev);
    const double gain = stddev[0] > 0.0 ? std::min(48.0 / stddev[0], max_gain) : 1.0;
    cv::Mat stretched;
    texture.convertTo(stretched, CV_8U, gain, 128.0 - gain * mean[0]);
    return stretched;
}

ImagePyramid ImagePyramid::build(const cv::Mat& image, int extra_levels,
                                 const MatcherOptions& matcher) {
    return build(image, extra_levels, matcher.normalize_brightness, matcher.illumination_sigma_px,
                 matcher.max_contrast_gain);
}

ImagePyramid ImagePyramid::build(const cv::Mat& image, int extra_levels, bool normalize,
                                 double illumination_sigma_px, double max_contrast_gain) {
    ImagePyramid p;
    if (image.empty()) return p;
    cv::Mat grey;
    if (image.type() == CV_8UC1) {
        grey = image;
    } else if (image.type() == CV_8UC3) {
        cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
    } else {
        CV_Error(cv::Error::StsUnsupportedFormat, "ImagePyramid: image must be CV_8UC1 or CV_8UC3");
    }
    // CV_8U, or CV_16S with the illumination removed
    const cv::Mat source = removeIllumination(grey, illumination_sigma_px);
    p.illumination_sigma_px = std::max(0.0, illumination_sigma_px);
    if (normalize) {
        grey = stretchContrast(source, max_contrast_gain);
        p.normalized = true;
        p.max_contrast_gain = max_contrast_gain;
    } else if (source.type() != CV_8U) {
        source.convertTo(grey, CV_8U, 1.0, 128.0);  // the texture around mid-grey
    }
    // Each level lives in a buffer 32 columns wider than the view, so SIMD rows may overrun.
    auto padded = [](const cv::Mat& src) {
        cv::Mat buffer;
        cv::copyMakeBorder(src, buffer, 0, 0, 0, 32, cv::BORDER_CONSTANT, cv::Scalar(0));
        return buffer(cv::Rect(0, 0, src.cols, src.rows));
    };
    p.levels.push_back(padded(grey));
    cv::Mat current = grey;
    for (int i = 0; i < extra_levels; ++i) {
        cv::Mat down;
        cv::pyrDown(current, down);
        p.levels.push_back(padded(down));
        current = down;
    }
    return p;
}

int effectivePyramidLevels(const MatcherOptions& o) {
    int levels = 0;
    while (levels < o.pyramid_levels && (o.patch_px >> (levels + 1)) >= o.min_top_patch_px) {
        ++levels;
    }
    return levels;
}

namespace {

// Inclusive integer range of displacements.
struct Range {
    int lo = 0, hi = -1;
    bool empty() const { return hi < lo; }
    Range intersect(const Range& o) const { return {std::max(lo, o.lo), std::min(hi, o.hi)}; }
};

int floorDiv(int a, int b) { return a >= 0 ? a / b : -((-a + b - 1) / b); }
int ceilDiv(int a, int b) { return -floorDiv(-a, b); }

// SAD values over a rectangle of displacements.
struct Surface {
    Range rx, ry;
    std::vector<std::uint32_t> values;
    std::uint32_t at(int dx, int dy) const {
        return values[static_cast<std::size_t>(dy - ry.lo) * (rx.hi - rx.lo + 1) + (dx - rx.lo)];
    }
};

// One pyramid level of one point: the reference patch and the displacements keeping the
// query block inside the image.
struct LevelSearch {
    PaddedPatch patch;
    cv::Point top_left;  // of the reference patch in the level
    const cv::Mat* query = nullptr;
    Range valid_x, valid_y;
    SimdLevel simd = SimdLevel::Scalar;

    bool init(const cv::Mat& ref, const cv::Mat& qry, cv::Point centre, int side, SimdLevel s) {
        top_left = centre - cv::Point(side / 2, side / 2);
        const cv::Rect roi(top_left, cv::Size(side, side));
        if ((roi & cv::Rect(0, 0, ref.cols, ref.rows)) != roi) return false;
        patch = PaddedPatch::from(ref, roi);
        query = &qry;
        valid_x = {-top_left.x, qry.cols - side - top_left.x};
        valid_y = {-top_left.y, qry.rows - side - top_left.y};
        simd = s;
        return !valid_x.empty() && !valid_y.empty();
    }

    Surface compute(Range rx, Range ry) const {
        Surface s{rx, ry, {}};
        s.values.reserve(static_cast<std::size_t>(rx.hi - rx.lo + 1) * (ry.hi - ry.lo + 1));
        const std::size_t stride = query->step[0];
        for (int dy = ry.lo; dy <= ry.hi; ++dy) {
            const std::uint8_t* row = query->ptr<std::uint8_t>(top_left.y + dy);
            for (int dx = rx.lo; dx <= rx.hi; ++dx) {
                s.values.push_back(sad(simd, patch, row + top_left.x + dx, stride));
            }
        }
        return s;
    }
};

cv::Point argMin(const Surface& s) {
    cv::Point best(s.rx.lo, s.ry.lo);
    std::uint32_t best_value = std::numeric_limits<std::uint32_t>::max();
    for (int dy = s.ry.lo; dy <= s.ry.hi; ++dy) {
        for (int dx = s.rx.lo; dx <= s.rx.hi; ++dx) {
            if (s.at(dx, dy) < best_value) {  // first minimum in raster order: deterministic
                best_value = s.at(dx, dy);
                best = {dx, dy};
            }
        }
    }
    return best;
}

bool onBorder(cv::Point d, const Range& rx, const Range& ry) {
    return d.x == rx.lo || d.x == rx.hi || d.y == ry.lo || d.y == ry.hi;
}

// Offset of the true minimum from the middle sample, in [-0.5, 0.5].
double subpixel(double sm, double s0, double sp, SubpixelMethod method) {
    double delta = 0.0;
    if (method == SubpixelMethod::Parabola) {
        const double denom = sm - 2.0 * s0 + sp;
        if (denom > 0.0) delta = 0.5 * (sm - sp) / denom;
    } else if (method == SubpixelMethod::Equiangular) {
        const double denom = std::max(sm, sp) - s0;
        if (denom > 0.0) delta = 0.5 * (sm - sp) / denom;
    }
    return std::clamp(delta, -0.5, 0.5);
}

PointMatch matchOne(const ImagePyramid& ref, const ImagePyramid& qry, cv::Point c, cv::Point p,
                    const MatcherOptions& o, int top, SimdLevel simd) {
    PointMatch m;
    m.reference_px = cv::Point2f(float(c.x), float(c.y));
    m.query_px = m.reference_px + cv::Point2f(float(p.x), float(p.y));

    const cv::Rect patch0(c - cv::Point(o.patch_px / 2, o.patch_px / 2),
                          cv::Size(o.patch_px, o.patch_px));
    const cv::Mat& ref0 = ref.levels[0];
    if ((patch0 & cv::Rect(0, 0, ref0.cols, ref0.rows)) != patch0) return m;  // OutOfImage
    cv::Scalar mean, stddev;
    cv::meanStdDev(ref0(patch0), mean, stddev);
    if (stddev[0] < o.min_texture) {
        m.status = MatchStatus::LowTexture;
        return m;
    }

    const int r = o.search_range_px / 2;
    // Exhaustive search on the top level over the window scaled down (rounded outwards).
    const int scale = 1 << top;
    // One extra coarse pixel each side: a peak just inside the full-resolution window may
    // round onto the scaled border. Only level 0 judges the true window border.
    const int pad = top > 0 ? 1 : 0;
    const Range window_x{floorDiv(p.x - r, scale) - pad, ceilDiv(p.x + r, scale) + pad};
    const Range window_y{floorDiv(p.y - r, scale) - pad, ceilDiv(p.y + r, scale) + pad};
    LevelSearch level;
    if (!level.init(ref.levels[top], qry.levels[top], cv::Point(c.x >> top, c.y >> top),
                    o.patch_px >> top, simd)) {
        return m;
    }
    Range rx = window_x.intersect(level.valid_x), ry = window_y.intersect(level.valid_y);
    if (rx.empty() || ry.empty()) return m;
    Surface surface = level.compute(rx, ry);
    cv::Point best = argMin(surface);
    // On coarse levels the image limits are rounded, so only level 0 judges them.
    if (top == 0 ? onBorder(best, rx, ry) : onBorder(best, window_x, window_y)) {
        m.status = MatchStatus::BorderPeak;
        return m;
    }
    // Distinctiveness: best against the best outside the exclusion radius.
    std::uint32_t second = std::numeric_limits<std::uint32_t>::max();
    for (int dy = ry.lo; dy <= ry.hi; ++dy) {
        for (int dx = rx.lo; dx <= rx.hi; ++dx) {
            if (std::max(std::abs(dx - best.x), std::abs(dy - best.y)) > o.exclusion_radius_px) {
                second = std::min(second, surface.at(dx, dy));
            }
        }
    }
    const std::uint32_t best_value = surface.at(best.x, best.y);
    m.quality = (second == std::numeric_limits<std::uint32_t>::max() || second == 0)
                    ? 0.f
                    : float(1.0 - double(best_value) / double(second));
    if (m.quality < o.min_distinctiveness) {
        m.status = MatchStatus::NotDistinctive;
        return m;
    }

    // Finer levels: local search around the doubled estimate, re-centred while the best is on
    // the local border but not on the window's (a coarse estimate may be off by a little more).
    for (int k = top - 1; k >= 0; --k) {
        const int s = 1 << k;
        const int pad_k = k > 0 ? 1 : 0;
        const Range wx{floorDiv(p.x - r, s) - pad_k, ceilDiv(p.x + r, s) + pad_k};
        const Range wy{floorDiv(p.y - r, s) - pad_k, ceilDiv(p.y + r, s) + pad_k};
        if (!level.init(ref.levels[k], qry.levels[k], cv::Point(c.x >> k, c.y >> k),
                        o.patch_px >> k, simd)) {
            return m;
        }
        const Range lx = wx.intersect(level.valid_x), ly = wy.intersect(level.valid_y);
        cv::Point centre = best * 2;
        const int R = o.refine_radius_px;
        for (int iteration = 0;; ++iteration) {
            rx = Range{centre.x - R, centre.x + R}.intersect(lx);
            ry = Range{centre.y - R, centre.y + R}.intersect(ly);
            if (rx.empty() || ry.empty()) return m;
            surface = level.compute(rx, ry);
            best = argMin(surface);
            const bool moved_x =
                (best.x == rx.lo && rx.lo > lx.lo) || (best.x == rx.hi && rx.hi < lx.hi);
            const bool moved_y =
                (best.y == ry.lo && ry.lo > ly.lo) || (best.y == ry.hi && ry.hi < ly.hi);
            if (!(moved_x || moved_y) || iteration >= 8) break;
            centre = best;
        }
        if (k == 0 && (onBorder(best, lx, ly) || onBorder(best, rx, ry))) {
            m.status = MatchStatus::BorderPeak;
            return m;
        }
    }
    const double s0 = surface.at(best.x, best.y);
    const double dx =
        subpixel(surface.at(best.x - 1, best.y), s0, surface.at(best.x + 1, best.y), o.subpixel);
    const double dy =
        subpixel(surface.at(best.x, best.y - 1), s0, surface.at(best.x, best.y + 1), o.subpixel);
    m.query_px = cv::Point2f(float(c.x + best.x + dx), float(c.y + best.y + dy));
    m.sad_per_px = float(s0 / (double(o.patch_px) * o.patch_px));
    m.status = MatchStatus::Matched;
    return m;
}

}  // namespace

std::vector<PointMatch> matchPoints(const ImagePyramid& reference, const ImagePyramid& query,
                                    const std::vector<cv::Point2f>& points,
                                    const std::vector<cv::Point2f>& predicted_offsets,
                                    const MatcherOptions& options, SimdLevel simd) {
    CV_Assert(predicted_offsets.empty() || predicted_offsets.size() == points.size());
    const int top = effectivePyramidLevels(options);
    std::vector<PointMatch> out;
    out.reserve(points.size());
    const bool usable = int(reference.levels.size()) > top && int(query.levels.size()) > top &&
                        !reference.empty() && !query.empty();
    for (std::size_t i = 0; i < points.size(); ++i) {
        const cv::Point c(cvRound(points[i].x), cvRound(points[i].y));
        cv::Point p(0, 0);
        if (!predicted_offsets.empty()) {
            const cv::Point2f& o = predicted_offsets[i];
            if (std::isfinite(o.x) && std::isfinite(o.y) && std::abs(o.x) < 1e6 &&
                std::abs(o.y) < 1e6) {
                p = cv::Point(cvRound(o.x), cvRound(o.y));
            }
        }
        if (!usable || !std::isfinite(points[i].x) || !std::isfinite(points[i].y)) {
            PointMatch m;
            m.reference_px = points[i];
            m.query_px = points[i];
            out.push_back(m);
            continue;
        }
        out.push_back(matchOne(reference, query, c, p, options, top, simd));
    }
    return out;
}

std::vector<PointMatch> matchPoints(const ImagePyramid& reference, const ImagePyramid& query,
                                    const std::vector<cv::Point2f>& points,
                                    const std::vector<cv::Point2f>& predicted_offsets,
                                    const MatcherOptions& options) {
    return matchPoints(reference, query, points, predicted_offsets, options,
                       options.use_simd ? bestSimdLevel() : SimdLevel::Scalar);
}

}  // namespace lookup::refine

#include "lookup/coarse/coarse_localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <stdexcept>

namespace lookup::coarse {
namespace {

using Clock = std::chrono::steady_clock;
double msSince(Clock::time_point t0) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t0).count();
}

constexpr float kInf = std::numeric_limits<float>::infinity();
// Floor of the local standard deviation in contrast enhancement [descriptor units]: keeps a
// stretch of identical references from turning noise into huge z-scores.
constexpr double kMinLocalStd = 0.05;

/// Largest index with arcLength <= `arc`, 0 when none (binary search; arc lengths grow).
long lastAtOrBelow(const ReferenceDescriptors& refs, double arc) {
    long lo = 0, hi = static_cast<long>(refs.size());  // answer in [lo, hi)
    while (hi - lo > 1) {
        const long mid = (lo + hi) / 2;
        (refs.arcLength(mid) <= arc ? lo : hi) = mid;
    }
    return lo;
}

/// Reference whose arc length is nearest to `arc` [m].
long nearestArc(const ReferenceDescriptors& refs, double arc) {
    const long last = static_cast<long>(refs.size()) - 1;
    if (arc <= refs.arcLength(0)) return 0;
    if (arc >= refs.arcLength(last)) return last;
    const long lo = lastAtOrBelow(refs, arc);
    return arc - refs.arcLength(lo) <= refs.arcLength(lo + 1) - arc ? lo : lo + 1;
}

/// Reference index at one query frame of the paths ending at candidates lo..hi (one speed
/// hypothesis), -1 where a path leaves the reference: lround(j - offset), or with odometry the
/// reference nearest in arc length to arc(j) + arc_shift (as nearestArc, found by a walk: the
/// targets grow with j).
void pathIndices(const ReferenceDescriptors& refs, long lo, long hi, double arc_shift,
                 double offset, bool odometry, std::vector<long>& out) {
    if (!odometry) {
        for (long j = lo; j <= hi; ++j) {
            // lround without the library call: x + 0.5 > 0 truncates to its floor.
            const double x = static_cast<double>(j) - offset;
            out[j - lo] = x > -0.5 ? static_cast<long>(x + 0.5) : -1;
        }
        return;
    }
    const std::vector<double>& arc_of = refs.arcLengths();  // unchecked access: the hot loop
    const long n = static_cast<long>(arc_of.size());
    // Largest index with arc(p) <= target, while the target is inside the range. The walk
    // starts where the first target lies: from 0 it cost O(n) per call.
    long p = lastAtOrBelow(refs, arc_of[lo] + arc_shift);
    for (long j = lo; j <= hi; ++j) {
        const double arc = arc_of[j] + arc_shift;
        long i;
        if (arc < arc_of[0] - 1e-9) {
            i = -1;
        } else if (arc <= arc_of[0]) {
            i = 0;
        } else if (arc >= arc_of[n - 1]) {
            i = n - 1;
        } else {
            while (p + 1 < n && arc_of[p + 1] <= arc) ++p;
            i = arc - arc_of[p] <= arc_of[p + 1] - arc ? p : p + 1;
        }
        out[j - lo] = i;
    }
}

}  // namespace

const char* toString(CoarseStatus status) {
    switch (status) {
        case CoarseStatus::kTracking:
            return "tracking";
        case CoarseStatus::kGlobal:
            return "global";
        case CoarseStatus::kNotEnoughFrames:
            return "not_enough_frames";
        case CoarseStatus::kLost:
            return "lost";
        case CoarseStatus::kInvalidInput:
            return "invalid_input";
        case CoarseStatus::kExternal:
            return "external";
        case CoarseStatus::kNotSearched:
            return "not_searched";
    }
    return "unknown";
}

/// One query frame of the buffer: its descriptor and the confusion-matrix entries computed so
/// far against references [lo, lo + raw.size()).
struct CoarseLocalizer::Column {
    Descriptor descriptor;
    std::optional<double> travelled_m;  ///< odometry since the previous query frame
    long lo = 0;
    std::vector<float> raw;
};

struct CoarseLocalizer::Search {
    bool valid = false;
    std::size_t best = 0;
    double best_score = kInf;    ///< mean enhanced difference along the best path
    double second_score = kInf;  ///< best outside the exclusion window
    double velocity = 0;
    std::size_t candidates = 0;
};

CoarseLocalizer::CoarseLocalizer(std::shared_ptr<const ReferenceDescriptors> references,
                                 const CoarseOptions& options)
    : references_(std::move(references)), options_(options) {
    options_.check();
    if (!references_ || references_->empty()) {
        throw std::invalid_argument("CoarseLocalizer: the reference sequence is empty");
    }
    if (!options_.sameDescriptor(references_->layout())) {
        const auto& l = references_->layout();
        throw std::invalid_argument(
            "CoarseLocalizer: reference descriptors are " + std::to_string(l.thumb_width_px) + "x" +
            std::to_string(l.thumb_height_px) + " patch " + std::to_string(l.patch_size_px) +
            ", options ask for " + std::to_string(options_.thumb_width_px) + "x" +
            std::to_string(options_.thumb_height_px) + " patch " +
            std::to_string(options_.patch_size_px));
    }
    if (references_->size() < static_cast<std::size_t>(options_.sequence_length)) {
        throw std::invalid_argument(
            "CoarseLocalizer: the reference sequence has " + std::to_string(references_->size()) +
            " frames, fewer than coarse.sequence_length = " +
            std::to_string(options_.sequence_length) + ": sequences cannot be matched");
    }
}

void CoarseLocalizer::reset() {
    columns_.clear();
    tracking_ = false;
}

CoarseResult CoarseLocalizer::locate(const CoarseQuery& query) {
    if (!query.forward_image) {
        CoarseResult r;
        r.status = CoarseStatus::kInvalidInput;
        r.reason = "no forward image given";
        r.query_index = queries_++;
        r.query_time_s = query.time_s;
        return r;
    }
    return process(*query.forward_image, query.time_s, query.travelled_m, query.search);
}

CoarseResult CoarseLocalizer::process(const mrpt::img::CImage& image, double time_s,
                                      std::optional<double> travelled_m, bool search) {
    const auto t0 = Clock::now();
    CoarseResult invalid;
    invalid.status = CoarseStatus::kInvalidInput;
    invalid.query_time_s = time_s;
    Descriptor d;
    try {
        if (image.isExternallyStored()) image.forceLoad();
        const int w = static_cast<int>(image.getWidth());
        const int h = static_cast<int>(image.getHeight());
        if (references_->imageWidth() > 0 &&
            (w != references_->imageWidth() || h != references_->imageHeight())) {
            invalid.reason = "query image is " + std::to_string(w) + "x" + std::to_string(h) +
                             ", reference images are " + std::to_string(references_->imageWidth()) +
                             "x" + std::to_string(references_->imageHeight());
        } else {
            d = computeDescriptor(image, options_);
        }
    } catch (const std::exception& e) {
        invalid.reason = std::string("cannot use the query image: ") + e.what();
    }
    if (d.empty()) {
        invalid.query_index = queries_++;
        return invalid;
    }
    const double descriptor_ms = msSince(t0);
    CoarseResult r = processDescriptor(d, time_s, travelled_m, search);
    r.descriptor_ms = descriptor_ms;
    return r;
}

void CoarseLocalizer::ensureComputed(Column& column, long lo, long hi,
                                     std::size_t& evaluated) const {
    const long n = static_cast<long>(references_->size());
    lo = std::max(lo, 0L);
    hi = std::min(hi, n - 1);
    if (lo > hi) return;
    auto diff = [&](long i) {
        ++evaluated;
        return descriptorDifference(column.descriptor, references_->descriptor(i));
    };
    if (column.raw.empty()) {
        column.lo = lo;
        column.raw.resize(static_cast<std::size_t>(hi - lo + 1));
        for (long i = lo; i <= hi; ++i) column.raw[i - lo] = diff(i);
        return;
    }
    const long cached_hi = column.lo + static_cast<long>(column.raw.size()) - 1;
    if (lo < column.lo) {  // extend to the left (filling any gap, so the cache stays contiguous)
        std::vector<float> front(static_cast<std::size_t>(column.lo - lo));
        for (long i = lo; i < column.lo; ++i) front[i - lo] = diff(i);
        column.raw.insert(column.raw.begin(), front.begin(), front.end());
        column.lo = lo;
    }
    for (long i = cached_hi + 1; i <= hi; ++i) column.raw.push_back(diff(i));
}

CoarseLocalizer::Search CoarseLocalizer::search(long cand_lo, long cand_hi, bool odometry,
                                                std::size_t& evaluated) {
    const long n_refs = static_cast<long>(references_->size());
    const int n_cols = static_cast<int>(columns_.size());
    const long R = options_.contrast_window_refs;
    const int H = odometry ? options_.odometry_scale_steps : options_.velocity_steps;

    // Hypotheses: path slopes [refs / query frame], or odometry scale factors.
    std::vector<double> hyp(H);
    const double h_lo = odometry ? 1.0 - options_.odometry_scale_tolerance : options_.velocity_min;
    const double h_hi = odometry ? 1.0 + options_.odometry_scale_tolerance : options_.velocity_max;
    for (int h = 0; h < H; ++h)
        hyp[h] = H == 1 ? 0.5 * (h_lo + h_hi) : h_lo + (h_hi - h_lo) * h / (H - 1);

    // Odometry distance from query frame k back to the newest frame [m].
    std::vector<double> back_m(n_cols, 0.0);
    for (int k = 1; k < n_cols; ++k)
        back_m[k] = back_m[k - 1] + columns_[k - 1]->travelled_m.value_or(0);

    // With odometry, the reference at query frame k on the path ending at j with scale
    // hypothesis h; -1 when the path leaves the reference. (Without odometry the span below is
    // a closed form, and the path scores use pathIndices.)
    auto odometryPathIndex = [&](long j, int h, int k) -> long {
        const double arc = references_->arcLength(j) - hyp[h] * back_m[k];
        if (arc < references_->arcLength(0) - 1e-9) return -1;
        return nearestArc(*references_, arc);
    };

    // Locally contrast-enhanced confusion entries, per column, over the span paths can reach.
    auto& enhanced = scratch_.enhanced;
    enhanced.resize(std::max<std::size_t>(enhanced.size(), n_cols));
    for (auto& e : enhanced) e.clear();
    std::vector<long> enh_lo(n_cols, 0);
    for (int k = 0; k < n_cols; ++k) {
        long a, b;
        if (odometry) {
            a = std::max(0L, odometryPathIndex(cand_lo, H - 1, k));
            b = odometryPathIndex(cand_hi, 0, k);
        } else {
            a = std::max(0L, cand_lo - static_cast<long>(std::ceil(hyp[H - 1] * k)) - 1);
            b = cand_hi - static_cast<long>(std::floor(hyp[0] * k)) + 1;
        }
        b = std::min(b, n_refs - 1);
        if (b < a) continue;
        Column& col = *columns_[k];
        ensureComputed(col, a - R, b + R, evaluated);
        const long wlo = std::max(0L, a - R), whi = std::min(n_refs - 1, b + R);
        // Prefix sums over the window span for mean / deviation of +/- R neighbours.
        auto& s1 = scratch_.s1;
        auto& s2 = scratch_.s2;
        s1.assign(whi - wlo + 2, 0.0);
        s2.assign(whi - wlo + 2, 0.0);
        for (long i = wlo; i <= whi; ++i) {
            const double v = col.raw[i - col.lo];
            s1[i - wlo + 1] = s1[i - wlo] + v;
            s2[i - wlo + 1] = s2[i - wlo] + v * v;
        }
        enh_lo[k] = a;
        enhanced[k].resize(b - a + 1);
        for (long i = a; i <= b; ++i) {
            const long l = std::max(wlo, i - R), u = std::min(whi, i + R);
            const double cnt = static_cast<double>(u - l + 1);
            const double mean = (s1[u - wlo + 1] - s1[l - wlo]) / cnt;
            const double var = std::max(0.0, (s2[u - wlo + 1] - s2[l - wlo]) / cnt - mean * mean);
            const double sd = std::max(kMinLocalStd, std::sqrt(var));
            enhanced[k][i - a] = static_cast<float>((col.raw[i - col.lo] - mean) / sd);
        }
    }

    // Path scores, one speed hypothesis and one query frame at a time over all candidates:
    // contiguous adds, and path indices by a walk instead of a search per path point. Sums run
    // over k in the same order as a path-by-path loop, so scores are identical to it.
    Search s;
    const std::size_t n_cand = static_cast<std::size_t>(cand_hi - cand_lo + 1);
    auto& score = scratch_.score;
    auto& slope = scratch_.slope;
    auto& sum = scratch_.sum;
    auto& index = scratch_.index;
    score.assign(n_cand, kInf);
    slope.assign(n_cand, 0.f);
    sum.resize(n_cand);
    index.resize(n_cand);
    for (int h = 0; h < H; ++h) {
        std::fill(sum.begin(), sum.end(), 0.f);
        for (int k = 0; k < n_cols; ++k) {
            pathIndices(*references_, cand_lo, cand_hi, odometry ? -hyp[h] * back_m[k] : 0.0,
                        odometry ? 0.0 : hyp[h] * k, odometry, index);
            const auto& e = enhanced[k];
            const long e_lo = enh_lo[k], e_n = static_cast<long>(e.size());
            for (std::size_t c = 0; c < n_cand; ++c) {
                const long i = index[c] - e_lo;
                sum[c] = (index[c] < 0 || i < 0 || i >= e_n) ? kInf : sum[c] + e[i];
            }
        }
        for (std::size_t c = 0; c < n_cand; ++c) {
            if (sum[c] < score[c]) {
                score[c] = sum[c];
                const long j = cand_lo + static_cast<long>(c);
                slope[c] = n_cols > 1 ? static_cast<float>(j - index[c]) / (n_cols - 1) : 0.f;
            }
        }
    }
    s.candidates = n_cand;
    for (long j = cand_lo; j <= cand_hi; ++j) {
        if (score[j - cand_lo] < s.best_score) {
            s.best_score = score[j - cand_lo];
            s.best = static_cast<std::size_t>(j);
            s.velocity = slope[j - cand_lo];
            s.valid = true;
        }
    }
    if (!s.valid) return s;
    const long excl = options_.exclusion_half_window_refs;
    for (long j = cand_lo; j <= cand_hi; ++j) {
        if (std::abs(j - static_cast<long>(s.best)) > excl) {
            s.second_score = std::min<double>(s.second_score, score[j - cand_lo]);
        }
    }
    s.best_score /= n_cols;
    s.second_score /= n_cols;
    return s;
}

CoarseResult CoarseLocalizer::processDescriptor(const Descriptor& descriptor, double time_s,
                                                std::optional<double> travelled_m,
                                                bool search_now) {
    const auto t0 = Clock::now();
    CoarseResult r;
    r.query_index = queries_++;
    r.query_time_s = time_s;
    const std::size_t expected = references_->descriptor(0).size();
    if (descriptor.size() != expected) {
        r.status = CoarseStatus::kInvalidInput;
        r.reason = "descriptor has " + std::to_string(descriptor.size()) +
                   " values, the references have " + std::to_string(expected);
        return r;
    }
    if (travelled_m && !(std::isfinite(*travelled_m) && *travelled_m >= 0)) {
        travelled_m.reset();  // a broken odometry reading only disables odometry here
    }

    auto column = std::make_shared<Column>();
    column->descriptor = descriptor;
    column->travelled_m = travelled_m;
    columns_.push_front(column);
    while (columns_.size() > static_cast<std::size_t>(options_.sequence_length)) {
        columns_.pop_back();
    }
    if (!search_now) {
        // The last match goes stale while frames pass unsearched: the next search is global.
        tracking_ = false;
        r.status = CoarseStatus::kNotSearched;
        r.reason = "search skipped: no match needed for this frame";
        return r;
    }
    const int n_cols = static_cast<int>(columns_.size());
    const long n_refs = static_cast<long>(references_->size());

    // Odometry applies when references are surveyed and every step in the buffer has it.
    bool odometry = options_.use_odometry && references_->hasPoses();
    for (int k = 0; k + 1 < n_cols && odometry; ++k)
        odometry = columns_[k]->travelled_m.has_value();
    r.used_odometry = odometry;

    const bool full = n_cols >= options_.sequence_length;
    Search s;
    bool global = true;
    if (tracking_ && full) {
        long predicted;
        if (odometry) {
            predicted = nearestArc(*references_,
                                   references_->arcLength(last_match_) + travelled_m.value_or(0));
        } else {
            predicted = static_cast<long>(last_match_) + std::lround(last_velocity_);
        }
        const long w = options_.tracking_half_window_refs;
        long lo = predicted - w, hi = predicted + w;
        if (lo < 0) hi = std::min(n_refs - 1, hi - lo), lo = 0;
        if (hi > n_refs - 1) lo = std::max(0L, lo - (hi - (n_refs - 1))), hi = n_refs - 1;
        s = search(lo, hi, odometry, r.evaluated_references);
        r.searched_candidates += s.candidates;
        global = !(s.valid && s.second_score - s.best_score >= options_.min_confidence);
    }
    if (global) {
        s = search(0, n_refs - 1, odometry, r.evaluated_references);
        r.searched_candidates += s.candidates;
    }
    r.search_ms = msSince(t0);

    if (!s.valid) {
        r.status = CoarseStatus::kLost;
        r.reason = "no sequence path fits inside the reference sequence";
        tracking_ = false;
        return r;
    }
    r.reference_index = s.best;
    r.reference_time_s = references_->time(s.best);
    if (references_->hasPoses()) r.coarse_pose = references_->pose(s.best);
    r.velocity = s.velocity;
    r.confidence = std::isfinite(s.second_score) ? s.second_score - s.best_score : 0.0;
    last_match_ = s.best;
    last_velocity_ = s.velocity;

    if (!full) {
        r.status = CoarseStatus::kNotEnoughFrames;
        r.reason = "only " + std::to_string(n_cols) +
                   " of sequence_length = " + std::to_string(options_.sequence_length) +
                   " query frames seen";
        tracking_ = false;
    } else if (!std::isfinite(s.second_score)) {
        r.status = CoarseStatus::kLost;
        r.reason = "no competing candidate outside the exclusion window: confidence unknown";
        tracking_ = false;
    } else if (r.confidence < options_.min_confidence) {
        r.status = CoarseStatus::kLost;
        r.reason = "confidence " + std::to_string(r.confidence) + " below min_confidence " +
                   std::to_string(options_.min_confidence) + " (aliased or unknown place)";
        tracking_ = false;
    } else {
        r.status = global ? CoarseStatus::kGlobal : CoarseStatus::kTracking;
        tracking_ = true;
    }
    return r;
}

}  // namespace lookup::coarse

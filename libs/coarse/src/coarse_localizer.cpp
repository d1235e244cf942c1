#include "lookup/coarse/coarse_localizer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <stdexcept>
#include <tuple>

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
// While tracking with odometry, every this many frames global searches check the track (in an
// aliased tunnel a wrong track is held as well as a right one): a tenth of their cost per frame.
constexpr int kAuditEveryFrames = 10;
// A track whose own path scores worse than this share of all places is dropped.
constexpr double kMaxTrackRank = 0.1;

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
/// targets grow with j). A path driven forwards leaves before the start, a reversing one (the
/// shift positive) past the end.
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
        } else if (arc > arc_of[n - 1] + 1e-9) {
            i = -1;
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
        case CoarseStatus::Tracking:
            return "tracking";
        case CoarseStatus::Global:
            return "global";
        case CoarseStatus::NotEnoughFrames:
            return "not_enough_frames";
        case CoarseStatus::Lost:
            return "lost";
        case CoarseStatus::InvalidInput:
            return "invalid_input";
        case CoarseStatus::External:
            return "external";
        case CoarseStatus::NotSearched:
            return "not_searched";
        case CoarseStatus::Odometry:
            return "odometry";
        case CoarseStatus::Unconfirmed:
            return "unconfirmed";
    }
    return "unknown";
}

/// One query frame of the buffer: its descriptor and the confusion-matrix entries computed so
/// far, in blocks of kBlockRefs references (an indexed global search touches a few places of a
/// long reference; pages of kPageRefs are allocated as they are touched).
struct CoarseLocalizer::Column {
    static constexpr long kBlockRefs = 8;
    static constexpr long kPageRefs = 256;
    Descriptor descriptor;
    std::optional<double> travelled_m;  ///< odometry since the previous query frame (signed)
    std::vector<std::unique_ptr<float[]>> pages;
    std::vector<bool> computed;                   ///< per block
    std::optional<std::vector<long>> neighbours;  ///< nearest references (DescriptorIndex)

    float raw(long i) const { return pages[i / kPageRefs][i % kPageRefs]; }
};

struct CoarseLocalizer::Search {
    bool valid = false;
    std::size_t best = 0;
    double best_score = kInf;    ///< mean enhanced difference along the best path
    double second_score = kInf;  ///< best outside the exclusion window
    double velocity = 0;
    std::size_t candidates = 0;
    double probe_score = kInf;  ///< best score among the probed candidates (see search())
    double probe_rank = 0;      ///< share of candidates scoring better than probe_score
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
    if (references_->size() >= static_cast<std::size_t>(options_.global_index_min_references)) {
        index_ = std::make_shared<const DescriptorIndex>(*references_);
    }
}

void CoarseLocalizer::reset() {
    columns_.clear();
    queries_ = 0;
    unconfident_searches_ = 0;
    tracking_ = false;
    coasted_m_ = 0;
    coast_frames_ = 0;
    pending_.clear();
}

void CoarseLocalizer::rejectLastMatch() {
    tracking_ = false;
    coasted_m_ = 0;
    coast_frames_ = 0;
    pending_.clear();
}

CoarseResult CoarseLocalizer::locate(const CoarseQuery& query) {
    if (!query.forward_image) {
        CoarseResult r;
        r.status = CoarseStatus::InvalidInput;
        r.reason = "no forward image given";
        r.query_index = queries_++;
        r.query_time_s = query.time_s;
        return r;
    }
    return process(*query.forward_image, query.time_s, query.travelled_m, query.search, query.audit,
                   query.forward_descriptor);
}

CoarseResult CoarseLocalizer::process(const mrpt::img::CImage& image, double time_s,
                                      std::optional<double> travelled_m, bool search, bool audit,
                                      const Descriptor* descriptor) {
    const auto t0 = Clock::now();
    CoarseResult invalid;
    invalid.status = CoarseStatus::InvalidInput;
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
            d = descriptor ? *descriptor : computeDescriptor(image, options_);
        }
    } catch (const std::exception& e) {
        invalid.reason = std::string("cannot use the query image: ") + e.what();
    }
    if (d.empty()) {
        invalid.query_index = queries_++;
        return invalid;
    }
    const double descriptor_ms = msSince(t0);
    CoarseResult r = processDescriptor(d, time_s, travelled_m, search, audit);
    r.descriptor_ms = descriptor_ms;
    return r;
}

void CoarseLocalizer::ensureComputed(Column& column, long lo, long hi,
                                     std::size_t& evaluated) const {
    const long n = static_cast<long>(references_->size());
    lo = std::max(lo, 0L);
    hi = std::min(hi, n - 1);
    if (lo > hi) return;
    if (column.computed.empty()) {
        column.computed.assign(
            static_cast<std::size_t>((n + Column::kBlockRefs - 1) / Column::kBlockRefs), false);
        column.pages.resize(
            static_cast<std::size_t>((n + Column::kPageRefs - 1) / Column::kPageRefs));
    }
    for (long b = lo / Column::kBlockRefs; b <= hi / Column::kBlockRefs; ++b) {
        if (column.computed[b]) continue;
        column.computed[b] = true;
        const long first = b * Column::kBlockRefs;
        const long last = std::min(n, first + Column::kBlockRefs);
        auto& page = column.pages[first / Column::kPageRefs];
        if (!page) page.reset(new float[Column::kPageRefs]);
        for (long i = first; i < last; ++i) {
            page[i % Column::kPageRefs] =
                descriptorDifference(column.descriptor, references_->descriptor(i));
        }
        evaluated += static_cast<std::size_t>(last - first);
    }
}

std::vector<std::pair<long, long>> CoarseLocalizer::globalWindows(bool odometry, int n_cols,
                                                                  int stride,
                                                                  std::pair<long, long> extra) {
    const long n_refs = static_cast<long>(references_->size());
    if (!index_) return {{0, n_refs - 1}};
    const long w = options_.tracking_half_window_refs;
    const std::vector<double> back_m = backDistances(n_cols);
    // Each place the index finds for a buffered frame votes for the span of sequence ends its
    // paths can reach; where many votes overlap, the frames agree on a place.
    std::vector<std::pair<long, int>> events;  // (position, +1 at a span's start, -1 past its end)
    for (int k = 0; k < n_cols; k += stride) {
        Column& col = *columns_[k];
        if (!col.neighbours) {
            col.neighbours = index_->nearest(col.descriptor, options_.global_index_neighbours);
        }
        for (long r : *col.neighbours) {
            long lo, hi;
            if (odometry) {
                const double arc = references_->arcLength(r) + back_m[k];
                const double tol = options_.odometry_scale_tolerance * std::abs(back_m[k]);
                if (arc - tol > references_->arcLength(n_refs - 1)) continue;  // beyond the end
                if (arc + tol < references_->arcLength(0)) continue;  // before the start (reversed)
                lo = lastAtOrBelow(*references_, arc - tol);
                hi = std::min(n_refs - 1, lastAtOrBelow(*references_, arc + tol) + 1);
            } else {
                lo = r + static_cast<long>(std::floor(options_.velocity_min * k));
                hi = std::min(n_refs - 1,
                              r + static_cast<long>(std::ceil(options_.velocity_max * k)));
                if (lo > n_refs - 1) continue;
            }
            events.emplace_back(lo, 1);
            events.emplace_back(hi + 1, -1);
        }
    }
    std::sort(events.begin(), events.end());
    // Segments of constant vote count, most voted first; each picked segment's centre becomes
    // a window of +/- w, and segments within a window of a picked centre are passed over.
    struct Segment {
        long lo, hi;
        int votes;
    };
    std::vector<Segment> segments;
    int votes = 0;
    for (std::size_t e = 0; e < events.size();) {
        const long at = events[e].first;
        while (e < events.size() && events[e].first == at) votes += events[e++].second;
        if (votes > 0 && e < events.size()) segments.push_back({at, events[e].first - 1, votes});
    }
    std::stable_sort(segments.begin(), segments.end(),
                     [](const Segment& x, const Segment& y) { return x.votes > y.votes; });
    std::vector<long> centres;
    for (const Segment& g : segments) {
        if (static_cast<int>(centres.size()) >= options_.global_index_windows) break;
        const long c = (g.lo + g.hi) / 2;
        const bool covered = std::any_of(centres.begin(), centres.end(),
                                         [&](long p) { return std::abs(p - c) <= 2 * w; });
        if (!covered) centres.push_back(c);
    }
    std::vector<std::pair<long, long>> windows;
    for (long c : centres) windows.emplace_back(c - w, c + w);
    if (extra.first <= extra.second) windows.emplace_back(extra.first - w, extra.second + w);
    std::sort(windows.begin(), windows.end());
    std::vector<std::pair<long, long>> merged;
    for (auto [lo, hi] : windows) {
        lo = std::max(0L, lo);
        hi = std::min(n_refs - 1, hi);
        if (hi < lo) continue;
        if (!merged.empty() && lo <= merged.back().second + 1) {
            merged.back().second = std::max(merged.back().second, hi);
        } else {
            merged.emplace_back(lo, hi);
        }
    }
    return merged;
}

std::vector<double> CoarseLocalizer::backDistances(int n_cols) const {
    std::vector<double> back_m(n_cols, 0.0);
    for (int k = 1; k < n_cols; ++k)
        back_m[k] = back_m[k - 1] + columns_[k - 1]->travelled_m.value_or(0);
    return back_m;
}

void CoarseLocalizer::scoreWindow(long cand_lo, long cand_hi, bool odometry, int n_cols, int stride,
                                  const std::vector<double>& hyp, const std::vector<double>& back_m,
                                  std::size_t& evaluated) {
    const long n_refs = static_cast<long>(references_->size());
    const long R = options_.contrast_window_refs;
    const int H = static_cast<int>(hyp.size());

    // With odometry, the span of references the paths ending at the candidates reach at query
    // frame k over all scale hypotheses (a reversing vehicle's lie ahead of their candidates);
    // lo > hi when all leave the reference. (Without odometry the span below is a closed form;
    // the path scores use pathIndices either way.)
    auto odometrySpan = [&](int k) -> std::pair<long, long> {
        const double a = references_->arcLength(cand_lo), b = references_->arcLength(cand_hi);
        const double d0 = hyp[0] * back_m[k], d1 = hyp[H - 1] * back_m[k];
        const double low = a - std::max(d0, d1), high = b - std::min(d0, d1);
        if (high < references_->arcLength(0) - 1e-9 ||
            low > references_->arcLength(n_refs - 1) + 1e-9) {
            return {0, -1};
        }
        return {nearestArc(*references_, low), nearestArc(*references_, high)};
    };

    // Locally contrast-enhanced confusion entries, per column, over the span paths can reach.
    auto& enhanced = scratch_.enhanced;
    enhanced.resize(std::max<std::size_t>(enhanced.size(), n_cols));
    for (auto& e : enhanced) e.clear();
    std::vector<long> enh_lo(n_cols, 0);
    for (int k = 0; k < n_cols; k += stride) {
        long a, b;
        if (odometry) {
            std::tie(a, b) = odometrySpan(k);
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
            const double v = col.raw(i);
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
            enhanced[k][i - a] = static_cast<float>((col.raw(i) - mean) / sd);
        }
    }

    // Path scores, one speed hypothesis and one query frame at a time over all candidates:
    // contiguous adds, and path indices by a walk instead of a search per path point. Sums run
    // over k in the same order as a path-by-path loop, so scores are identical to it.
    const int k_last = (n_cols - 1) / stride * stride;  // oldest frame scored
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
        for (int k = 0; k < n_cols; k += stride) {
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
                slope[c] = k_last > 0 ? static_cast<float>(j - index[c]) / k_last : 0.f;
            }
        }
    }
}

CoarseLocalizer::Search CoarseLocalizer::search(const std::vector<std::pair<long, long>>& windows,
                                                bool odometry, int n_cols, int stride,
                                                std::size_t& evaluated, long probe_lo,
                                                long probe_hi) {
    const int H = odometry ? options_.odometry_scale_steps : options_.velocity_steps;
    // Hypotheses: path slopes [refs / query frame], or odometry scale factors.
    std::vector<double> hyp(H);
    const double h_lo = odometry ? 1.0 - options_.odometry_scale_tolerance : options_.velocity_min;
    const double h_hi = odometry ? 1.0 + options_.odometry_scale_tolerance : options_.velocity_max;
    for (int h = 0; h < H; ++h)
        hyp[h] = H == 1 ? 0.5 * (h_lo + h_hi) : h_lo + (h_hi - h_lo) * h / (H - 1);
    // Odometry distance from query frame k back to the newest frame [m].
    const std::vector<double> back_m = backDistances(n_cols);
    const int used = (n_cols - 1) / stride + 1;  // frames scored

    // Scores of every candidate of the (sorted, disjoint) windows, in reference order.
    auto& all_j = scratch_.all_j;
    auto& all_score = scratch_.all_score;
    auto& all_slope = scratch_.all_slope;
    all_j.clear();
    all_score.clear();
    all_slope.clear();
    for (const auto& [lo, hi] : windows) {
        if (hi < lo) continue;
        scoreWindow(lo, hi, odometry, n_cols, stride, hyp, back_m, evaluated);
        for (long j = lo; j <= hi; ++j) all_j.push_back(j);
        all_score.insert(all_score.end(), scratch_.score.begin(), scratch_.score.end());
        all_slope.insert(all_slope.end(), scratch_.slope.begin(), scratch_.slope.end());
    }
    const std::size_t n_all = all_j.size();

    Search s;
    s.candidates = n_all;
    for (std::size_t c = 0; c < n_all; ++c) {
        if (all_j[c] >= probe_lo && all_j[c] <= probe_hi) {
            s.probe_score = std::min<double>(s.probe_score, all_score[c] / used);
        }
    }
    if (probe_lo <= probe_hi) {
        std::size_t finite = 0, better = 0;
        for (float v : all_score) {
            if (!std::isfinite(v)) continue;
            ++finite;
            better += v / used < s.probe_score;
        }
        s.probe_rank = finite > 0 ? static_cast<double>(better) / finite : 1.0;
    }
    for (std::size_t c = 0; c < n_all; ++c) {
        if (all_score[c] < s.best_score) {
            s.best_score = all_score[c];
            s.best = static_cast<std::size_t>(all_j[c]);
            s.velocity = all_slope[c];
            s.valid = true;
        }
    }
    if (!s.valid) return s;
    const long excl = options_.exclusion_half_window_refs;
    for (std::size_t c = 0; c < n_all; ++c) {
        if (std::abs(all_j[c] - static_cast<long>(s.best)) > excl) {
            s.second_score = std::min<double>(s.second_score, all_score[c]);
        }
    }
    s.best_score /= used;
    s.second_score /= used;
    return s;
}

double CoarseLocalizer::odometryTolerance(double travelled_m) const {
    return options_.odometry_tolerance_m + options_.odometry_tolerance_per_m * travelled_m;
}

int CoarseLocalizer::odometryFrames(double max_back_m) const {
    int frames = 1;
    double back_m = 0;
    while (frames < static_cast<int>(columns_.size()) && columns_[frames - 1]->travelled_m) {
        back_m += std::abs(*columns_[frames - 1]->travelled_m);
        if (back_m > max_back_m) break;
        ++frames;
    }
    return frames;
}

std::size_t CoarseLocalizer::bufferLength() const {
    const bool odometry = options_.use_odometry && references_->hasPoses();
    return static_cast<std::size_t>(
        odometry ? std::max(options_.sequence_length, options_.odometry_sequence_length)
                 : options_.sequence_length);
}

int CoarseLocalizer::strideFor(int frames) const {
    // Long sequences score every few frames only: the span decides, and a search over the
    // whole reference then costs what one of sequence_length frames does.
    return (frames + options_.sequence_length - 1) / options_.sequence_length;
}

double CoarseLocalizer::minConfidence(int frames) const {
    // The margin is a mean over the path's frames; its noise falls as 1/sqrt(frames).
    return options_.min_confidence *
           std::sqrt(static_cast<double>(options_.sequence_length) / std::max(frames, 1));
}

bool CoarseLocalizer::confirmGlobal(std::size_t best, std::size_t query_index, std::string& why) {
    const double arc = references_->arcLength(best);
    for (const auto& p : pending_) {
        const double tolerance = odometryTolerance(p.driven_m);
        if (std::abs(p.arc_m + p.travelled_m - arc) > tolerance) continue;
        if (query_index >= p.query_index + options_.sequence_length) return true;
        // Agrees, but their sequences overlap: the older match waits for a later frame.
        why = "global match awaits confirmation: agrees with the match of query frame " +
              std::to_string(p.query_index) + ", whose sequence overlaps this one";
        return false;
    }
    pending_.push_back({query_index, arc, 0.0, 0.0});
    why =
        "global match awaits confirmation by a later, non-overlapping sequence at the place "
        "odometry carries it to";
    return false;
}

void CoarseLocalizer::auditTrack(CoarseResult& r) {
    const double tolerance = odometryTolerance(coasted_m_);
    const long probe_lo = lastAtOrBelow(*references_, track_arc_m_ - tolerance);
    const long probe_hi = lastAtOrBelow(*references_, track_arc_m_ + tolerance) + 1;
    // Frames with odometry whose path back from the track stays on the reference (a longer
    // path would leave it before its start and lose to any place by default).
    const int odometry_cols =
        odometryFrames((1.0 - options_.odometry_scale_tolerance) *
                       (track_arc_m_ - tolerance - references_->arcLength(0)));
    // Two spans: the longest (a wrong track that chance window matches keep alive loses over
    // a hundred metres), and the frames since the window match turned unconfident with one
    // sequence before (after a kidnapping the longest span still favours the old place).
    const int spans[2] = {
        std::min(odometry_cols, options_.odometry_sequence_length),
        std::min(odometry_cols, static_cast<int>(coast_frames_) + options_.sequence_length)};
    for (int i = 0; i < 2; ++i) {
        const int cols = spans[i];
        if (cols < options_.sequence_length || (i == 1 && cols == spans[0])) continue;
        // The short span only once the window has been unconfident for a whole sequence: a
        // few unconfident frames are the aliased stretch the track is held through.
        if (i == 1 && static_cast<int>(coast_frames_) < options_.sequence_length) continue;
        const int stride = strideFor(cols);
        const Search g = search(globalWindows(true, cols, stride, {probe_lo, probe_hi}), true, cols,
                                stride, r.evaluated_references, probe_lo, probe_hi);
        r.searched_candidates += g.candidates;
        // The best of thousands of places beats the track's own path now and then even when
        // the track is right (on the full presets every right track ranked in the best 4 %):
        // only a track that many places beat, one of them by a confident margin, is dropped.
        // Moving it to the best place instead moved right tracks to wrong places.
        if (!g.valid || g.probe_rank <= kMaxTrackRank ||
            g.probe_score - g.best_score < minConfidence(cols)) {
            continue;  // (in a uniform stretch many places tie with the track: no margin)
        }
        std::ostringstream msg;
        msg << "track dropped: over " << cols << " frames " << 100 * g.probe_rank
            << " % of the places score better than the track";
        r.status = CoarseStatus::Lost;
        r.reason = msg.str();
        tracking_ = false;
        return;
    }
}

/// What one searched frame can use: the buffered sequence, its odometry, the frame's step.
struct CoarseLocalizer::FramePlan {
    std::chrono::steady_clock::time_point t0;  ///< when the frame arrived
    int n_cols = 0;                            ///< buffered frames
    long n_refs = 0;
    int odometry_cols = 0;  ///< newest buffered frames whose steps all have odometry
    int track_cols = 0;     ///< frames a tracking search scores
    bool odometry = false;  ///< surveyed references and odometry over the whole sequence
    bool full = false;      ///< sequence_length frames buffered
    double step_m = 0;      ///< odometry since the previous frame [m], negative reversing
};

void CoarseLocalizer::agePending(const std::optional<double>& travelled_m,
                                 std::size_t query_index) {
    // Pending global matches move with the vehicle; without odometry they cannot.
    if (!travelled_m) {
        pending_.clear();
        return;
    }
    for (auto& p : pending_) {
        p.travelled_m += *travelled_m;
        p.driven_m += std::abs(*travelled_m);
    }
    // A match older than a few sequences no longer helps: the tolerance has grown loose.
    const std::size_t max_age = 4 * static_cast<std::size_t>(options_.sequence_length);
    pending_.erase(std::remove_if(pending_.begin(), pending_.end(),
                                  [&](const PendingMatch& p) {
                                      return query_index > p.query_index + max_age;
                                  }),
                   pending_.end());
}

void CoarseLocalizer::skipSearch(const std::optional<double>& travelled_m, double step_m,
                                 CoarseResult& r) {
    // With odometry the track moves on unsearched; otherwise the next search is global.
    const bool coast = tracking_ && travelled_m && options_.use_odometry &&
                       references_->hasPoses() &&
                       coasted_m_ + std::abs(step_m) <= options_.max_coast_m;
    if (coast) {
        coasted_m_ += std::abs(step_m);
        track_arc_m_ += step_m;
        last_match_ = static_cast<std::size_t>(nearestArc(*references_, track_arc_m_));
    }
    tracking_ = coast;
    r.status = CoarseStatus::NotSearched;
    r.reason = "search skipped: no match needed for this frame";
}

bool CoarseLocalizer::searchTrack(const FramePlan& plan, bool audit, CoarseResult& r, Search& s,
                                  bool& held) {
    long predicted;
    if (plan.odometry) {
        // From the continuous arc length: snapping to a reference every frame while
        // coasting would add up rounding errors of half a reference spacing.
        predicted = nearestArc(*references_, track_arc_m_ + plan.step_m);
    } else {
        predicted = static_cast<long>(last_match_) + std::lround(last_velocity_);
    }
    const long w = options_.tracking_half_window_refs, n_refs = plan.n_refs;
    long lo = predicted - w, hi = predicted + w;
    if (lo < 0) hi = std::min(n_refs - 1, hi - lo), lo = 0;
    if (hi > n_refs - 1) lo = std::max(0L, lo - (hi - (n_refs - 1))), hi = n_refs - 1;
    s = search({{lo, hi}}, plan.odometry, plan.track_cols, 1, r.evaluated_references);
    r.searched_candidates += s.candidates;
    bool confident = s.valid && s.second_score - s.best_score >= options_.min_confidence;
    const double off_m =
        plan.odometry && s.valid
            ? std::abs(references_->arcLength(s.best) - (track_arc_m_ + plan.step_m))
            : 0.0;
    const bool far =
        plan.odometry && s.valid && off_m > odometryTolerance(coasted_m_ + std::abs(plan.step_m));
    if (far && options_.max_coast_m > 0) confident = false;  // aliasing within the window
    if (confident) return true;
    if (plan.odometry && coasted_m_ + std::abs(plan.step_m) <= options_.max_coast_m) {
        // Aliased stretch: the window cannot tell its places apart, odometry still can.
        holdByOdometry(plan, predicted, s, far ? std::optional<double>(off_m) : std::nullopt, audit,
                       r);
        held = true;
    }
    return false;
}

void CoarseLocalizer::holdByOdometry(const FramePlan& plan, long predicted, const Search& s,
                                     std::optional<double> far_m, bool audit, CoarseResult& r) {
    coasted_m_ += std::abs(plan.step_m);
    track_arc_m_ += plan.step_m;
    r.search_ms = msSince(plan.t0);
    r.status = CoarseStatus::Odometry;
    r.reference_index = static_cast<std::size_t>(predicted);
    r.reference_time_s = references_->time(r.reference_index);
    r.coarse_pose = references_->pose(r.reference_index);
    r.velocity = s.velocity;
    r.confidence = s.valid && std::isfinite(s.second_score)
                       ? std::max(0.0, s.second_score - s.best_score)
                       : 0.0;
    std::ostringstream why;
    if (far_m) {
        why << "window match " << *far_m << " m from the odometry prediction";
    } else {
        why << "window match not confident (" << r.confidence << ")";
    }
    why << ": held by odometry, " << coasted_m_ << " m since the last confident match";
    r.reason = why.str();
    last_match_ = r.reference_index;
    ++coast_frames_;
    if (++frames_since_audit_ >= kAuditEveryFrames && audit) {
        frames_since_audit_ = 0;
        auditTrack(r);
    }
}

CoarseLocalizer::Search CoarseLocalizer::searchGlobally(const FramePlan& plan, int global_cols,
                                                        CoarseResult& r) {
    // After a track, its place is searched too (the index may miss it in a uniform stretch).
    const long last = static_cast<long>(last_match_), n_refs = plan.n_refs;
    const std::pair<long, long> previous =
        queries_ > 1 && last < n_refs ? std::make_pair(last, last) : std::make_pair(0L, -1L);
    const int stride = strideFor(global_cols);
    const int every = options_.global_index_full_search_every;
    const bool whole = index_ && every > 0 && unconfident_searches_ >= every;
    if (whole) unconfident_searches_ = 0;
    Search s = search(whole ? std::vector<std::pair<long, long>>{{0, n_refs - 1}}
                            : globalWindows(plan.odometry, global_cols, stride, previous),
                      plan.odometry, global_cols, stride, r.evaluated_references);
    r.searched_candidates += s.candidates;
    return s;
}

void CoarseLocalizer::judgeMatch(const FramePlan& plan, const Search& s, bool global,
                                 int global_cols, bool audit, CoarseResult& r) {
    r.reference_index = s.best;
    r.reference_time_s = references_->time(s.best);
    if (references_->hasPoses()) r.coarse_pose = references_->pose(s.best);
    r.velocity = s.velocity;
    r.confidence = std::isfinite(s.second_score) ? s.second_score - s.best_score : 0.0;
    last_match_ = s.best;
    last_velocity_ = s.velocity;

    const int cols = global ? global_cols : plan.track_cols;
    if (global && plan.full) ++unconfident_searches_;  // (reset below when it is trusted)
    if (!plan.full) {
        r.status = CoarseStatus::NotEnoughFrames;
        r.reason = "only " + std::to_string(plan.n_cols) +
                   " of sequence_length = " + std::to_string(options_.sequence_length) +
                   " query frames seen";
        tracking_ = false;
    } else if (!std::isfinite(s.second_score)) {
        r.status = CoarseStatus::Lost;
        r.reason = "no competing candidate outside the exclusion window: confidence unknown";
        tracking_ = false;
    } else if (r.confidence < minConfidence(cols)) {
        r.status = CoarseStatus::Lost;
        r.reason = "confidence " + std::to_string(r.confidence) + " below " +
                   std::to_string(minConfidence(cols)) + " (min_confidence for " +
                   std::to_string(cols) + " frames: aliased or unknown place)";
        tracking_ = false;
    } else if (global && plan.odometry && options_.confirm_global &&
               !confirmGlobal(s.best, r.query_index, r.reason)) {
        r.status = CoarseStatus::Unconfirmed;
        tracking_ = false;
    } else {
        trust(s.best, global, plan.odometry, audit, r);
    }
}

void CoarseLocalizer::trust(std::size_t best, bool global, bool odometry, bool audit,
                            CoarseResult& r) {
    r.status = global ? CoarseStatus::Global : CoarseStatus::Tracking;
    tracking_ = true;
    unconfident_searches_ = 0;
    coasted_m_ = 0;
    coast_frames_ = 0;
    if (references_->hasPoses()) track_arc_m_ = references_->arcLength(best);
    if (global) {
        pending_.clear();
        frames_since_audit_ = 0;
    } else if (odometry && ++frames_since_audit_ >= kAuditEveryFrames && audit) {
        frames_since_audit_ = 0;
        auditTrack(r);
    }
}

CoarseResult CoarseLocalizer::processDescriptor(const Descriptor& descriptor, double time_s,
                                                std::optional<double> travelled_m, bool search_now,
                                                bool audit) {
    FramePlan plan;
    plan.t0 = Clock::now();
    CoarseResult r;
    r.query_index = queries_++;
    r.query_time_s = time_s;
    const std::size_t expected = references_->descriptor(0).size();
    if (descriptor.size() != expected) {
        r.status = CoarseStatus::InvalidInput;
        r.reason = "descriptor has " + std::to_string(descriptor.size()) +
                   " values, the references have " + std::to_string(expected);
        return r;
    }
    if (travelled_m && !std::isfinite(*travelled_m)) {
        travelled_m.reset();  // a broken odometry reading only disables odometry here
    }
    agePending(travelled_m, r.query_index);
    auto column = std::make_shared<Column>();
    column->descriptor = descriptor;
    column->travelled_m = travelled_m;
    columns_.push_front(column);
    while (columns_.size() > bufferLength()) columns_.pop_back();
    plan.step_m = travelled_m.value_or(0);
    if (!search_now) {
        skipSearch(travelled_m, plan.step_m, r);
        return r;
    }
    plan.n_cols = static_cast<int>(columns_.size());
    plan.n_refs = static_cast<long>(references_->size());
    // Odometry applies when references are surveyed and every step of the sequence has it.
    plan.odometry_cols = odometryFrames(std::numeric_limits<double>::infinity());
    plan.track_cols = std::min(plan.n_cols, options_.sequence_length);
    plan.odometry =
        options_.use_odometry && references_->hasPoses() && plan.odometry_cols >= plan.track_cols;
    plan.full = plan.n_cols >= options_.sequence_length;
    r.used_odometry = plan.odometry;

    Search s;
    bool global = true;
    if (tracking_ && plan.full) {
        bool held = false;
        global = !searchTrack(plan, audit, r, s, held);
        if (held) return r;
    }
    // A global search with odometry scores longer sequences: over a long uniform drive a few
    // seconds of forward views alias, a hundred metres of them rarely do.
    int global_cols = plan.track_cols;
    if (plan.odometry) {
        global_cols = std::max(plan.track_cols,
                               std::min(plan.odometry_cols, options_.odometry_sequence_length));
    }
    if (global) s = searchGlobally(plan, global_cols, r);
    r.search_ms = msSince(plan.t0);
    if (!s.valid) {
        r.status = CoarseStatus::Lost;
        r.reason = "no sequence path fits inside the reference sequence";
        tracking_ = false;
        return r;
    }
    judgeMatch(plan, s, global, global_cols, audit, r);
    return r;
}

}  // namespace lookup::coarse

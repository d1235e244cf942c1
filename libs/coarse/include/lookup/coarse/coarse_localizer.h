#pragma once
// Online SeqSLAM (Milford & Wyeth, ICRA 2012) over a reference sequence, one forward image at
// a time, as the coarse stage of LookUP.
//
// Per frame: descriptor -> one new column of the confusion matrix D (reference x query, mean
// absolute descriptor difference) -> local contrast enhancement of every buffered column over
// +/- R_window references -> each candidate reference j is the end of straight paths through
// the last d_s columns with slopes in [V_min, V_max] (or, with odometry and surveyed
// references, paths that follow the travelled distance within a scale tolerance) -> best
// path score vs the best score outside +/- exclusion_half_window gives the confidence.
//
// Cost: while tracking, only candidates within tracking_half_window of the predicted
// reference are scored, and confusion entries are computed lazily and cached per buffered
// column, so the work per frame does not depend on the reference length. A search over the
// whole reference runs at start-up and whenever the windowed match is not confident
// (kidnapping, leaving the surveyed route and coming back).
//
// With odometry (surveyed references and travelled distance per frame), sequences are not
// the only evidence: a track whose window match turns unconfident is held by the distance
// travelled for up to max_coast_m, and a global match is trusted only when a second one, from
// a later, non-overlapping sequence, lands where odometry carried the first.

#include <deque>
#include <memory>
#include <optional>

#include "lookup/coarse/coarse_source.h"
#include "lookup/coarse/descriptor_index.h"

namespace lookup::coarse {

class CoarseLocalizer : public CoarseSource {
  public:
    /// Throws common::ConfigError for invalid options, std::invalid_argument when the
    /// references are empty or their descriptor layout differs from `options`.
    CoarseLocalizer(std::shared_ptr<const ReferenceDescriptors> references,
                    const CoarseOptions& options);

    /// CoarseSource: needs query.forward_image (kInvalidInput without it).
    CoarseResult locate(const CoarseQuery& query) override;
    std::string name() const override { return "seqslam"; }

    /// Same as locate() for an image; kInvalidInput when it is empty or its size differs from
    /// the references' images.
    /// `descriptor`: the image's descriptor when the caller computed it (same options).
    CoarseResult process(const mrpt::img::CImage& image, double time_s,
                         std::optional<double> travelled_m = std::nullopt, bool search = true,
                         bool audit = true, const Descriptor* descriptor = nullptr);
    /// With a descriptor computed by the caller (computeDescriptor with the same options).
    /// `search` = false: the frame only joins the sequence (kNotSearched), see CoarseQuery.
    /// `audit` = false: the track audit waits (CoarseQuery::audit).
    CoarseResult processDescriptor(const Descriptor& descriptor, double time_s,
                                   std::optional<double> travelled_m = std::nullopt,
                                   bool search = true, bool audit = true);

    /// Forgets the query history (the next frame is query 0 and starts a global search).
    void reset();
    /// CoarseSource: drops the track (the next search is global), keeps the history.
    void rejectLastMatch() override;
    /// CoarseSource: reset().
    void restart() override { reset(); }

    const CoarseOptions& options() const { return options_; }
    const ReferenceDescriptors& references() const { return *references_; }
    /// True when global searches go through a DescriptorIndex (global_index_min_references).
    bool indexed() const { return index_ != nullptr; }

  private:
    struct Column;
    struct Search;
    struct FramePlan;
    // The steps of processDescriptor.
    /// Pending global matches carried `travelled_m` further, the stale ones dropped (all
    /// without odometry).
    void agePending(const std::optional<double>& travelled_m, std::size_t query_index);
    /// An unsearched frame: the track coasts on odometry (within max_coast_m) or is dropped.
    void skipSearch(const std::optional<double>& travelled_m, double step_m, CoarseResult& r);
    /// The window around the predicted place into `s`; true when its match is confident. An
    /// aliased window with odometry holds the track (`held`, `r` complete).
    bool searchTrack(const FramePlan& plan, bool audit, CoarseResult& r, Search& s, bool& held);
    void holdByOdometry(const FramePlan& plan, long predicted, const Search& s,
                        std::optional<double> far_m, bool audit, CoarseResult& r);
    /// The whole reference, or the index's windows (and the last track's place).
    Search searchGlobally(const FramePlan& plan, int global_cols, CoarseResult& r);
    /// The match `s` into `r`: too few frames, no competitor, not confident, unconfirmed, or
    /// trusted (trust()).
    void judgeMatch(const FramePlan& plan, const Search& s, bool global, int global_cols,
                    bool audit, CoarseResult& r);
    /// A trusted match: tracking from `best`, coasting reset, the audit counted.
    void trust(std::size_t best, bool global, bool odometry, bool audit, CoarseResult& r);
    void ensureComputed(Column& column, long lo, long hi, std::size_t& evaluated) const;
    /// Scores paths through the newest `n_cols` buffered frames (every `stride`-th of them)
    /// ending at the candidates: every reference of the sorted, disjoint `windows`.
    /// Search::probe_score: the best path score ending in [probe_lo, probe_hi].
    Search search(const std::vector<std::pair<long, long>>& windows, bool odometry, int n_cols,
                  int stride, std::size_t& evaluated, long probe_lo = -1, long probe_hi = -2);
    /// Path scores of the candidates lo..hi into scratch_.score / scratch_.slope.
    void scoreWindow(long lo, long hi, bool odometry, int n_cols, int stride,
                     const std::vector<double>& hypotheses, const std::vector<double>& back_m,
                     std::size_t& evaluated);
    /// Candidate windows of a global search: the whole reference, or with an index, the
    /// windows around the places it finds for the scored frames (the most voted
    /// global_index_windows), plus `extra` (a place that must be scored; empty when
    /// first > second), widened by tracking_half_window_refs.
    std::vector<std::pair<long, long>> globalWindows(bool odometry, int n_cols, int stride,
                                                     std::pair<long, long> extra);
    /// Odometry distance from buffered frame k back to the newest frame [m], k < n_cols;
    /// negative where the vehicle reversed since.
    std::vector<double> backDistances(int n_cols) const;
    int strideFor(int frames) const;   ///< stride for a global search over `frames` frames
    std::size_t bufferLength() const;  ///< frames kept: the longest sequence searched
    /// How far a match may lie from where odometry puts it after `travelled_m` [m].
    double odometryTolerance(double travelled_m) const;
    /// Newest buffered frames whose steps all have odometry, stopping before their distance
    /// back from the newest exceeds `max_back_m`.
    int odometryFrames(double max_back_m) const;
    /// min_confidence, given for sequence_length frames, for a path of `frames` frames.
    double minConfidence(int frames) const;
    /// True when a pending global match confirms the confident global match `best`;
    /// otherwise keeps `best` pending and says why in `why`.
    bool confirmGlobal(std::size_t best, std::size_t query_index, std::string& why);
    /// Global searches with odometry against the track: when many places beat the track's own
    /// path, the track is dropped (`r` becomes lost) and a global search follows.
    void auditTrack(CoarseResult& r);

    /// Buffers of search(), kept between frames: a global search over a long reference needs
    /// megabytes, and fresh allocations each frame cost page faults.
    struct Scratch {
        std::vector<std::vector<float>> enhanced;
        std::vector<double> s1, s2;
        std::vector<float> score, slope, sum;
        std::vector<long> index;
        std::vector<long> all_j;
        std::vector<float> all_score, all_slope;
    };
    Scratch scratch_;

    std::shared_ptr<const ReferenceDescriptors> references_;
    CoarseOptions options_;
    /// Null for references shorter than global_index_min_references (searched whole).
    std::shared_ptr<const DescriptorIndex> index_;
    std::deque<std::shared_ptr<Column>> columns_;  ///< newest first, at most d_s
    std::size_t queries_ = 0;
    bool tracking_ = false;
    std::size_t last_match_ = 0;
    double last_velocity_ = 1.0;
    /// Driven (either way) since the last confident match while tracking [m].
    double coasted_m_ = 0;
    double track_arc_m_ = 0;        ///< arc length of the tracked place (odometry) [m]
    std::size_t coast_frames_ = 0;  ///< frames held by odometry since the last confident match
    int frames_since_audit_ = 0;    ///< tracking frames since auditTrack() last ran
    int unconfident_searches_ = 0;  ///< global searches since one was trusted (or scored whole)

    /// A confident global match waiting for its confirmation (CoarseOptions::confirm_global).
    struct PendingMatch {
        std::size_t query_index = 0;
        double arc_m = 0;        ///< arc length of the matched reference [m]
        double travelled_m = 0;  ///< odometry since that query frame [m], signed
        double driven_m = 0;     ///< ... and the distance driven, either way [m]
    };
    std::vector<PendingMatch> pending_;
};

}  // namespace lookup::coarse

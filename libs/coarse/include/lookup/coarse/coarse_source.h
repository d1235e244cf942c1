#pragma once
// The coarse stage's interface to the rest of LookUP (paper Sec. III-D): for each query
// frame, the time stamp of the matched reference image (and, where known, a coarse pose).
// Any coarse localiser can be plugged in behind CoarseSource: the built-in SeqSLAM matcher
// (CoarseLocalizer), a file of query -> reference time stamps, or coarse poses in TUM form.

#include <mrpt/img/CImage.h>
#include <mrpt/poses/CPose3D.h>

#include <cstddef>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "lookup/coarse/reference_sequence.h"

namespace lookup::coarse {

enum class CoarseStatus {
    Tracking,         ///< confident match found in the window around the previous match
    Global,           ///< confident match found by a search over the whole reference
    NotEnoughFrames,  ///< fewer than sequence_length frames seen: match from a shorter
                      ///< sequence, not trusted
    Lost,             ///< best match not confident (aliasing, unknown place, kidnapping)
    InvalidInput,     ///< the query frame could not be used (see reason)
    External,         ///< supplied by an external source (file), no confidence measure
    NotSearched,      ///< frame added to the sequence, search skipped (CoarseQuery::search)
    Odometry,         ///< tracking, window match not confident: reference predicted by the
                      ///< distance travelled since the last confident match
    Unconfirmed,      ///< confident global match waiting for a later one to agree with it
                      ///< (CoarseOptions::confirm_global): not trusted yet
};

/// "tracking", "global", "not_enough_frames", "lost", "invalid_input", "external",
/// "not_searched", "odometry", "unconfirmed".
const char* toString(CoarseStatus status);

struct CoarseQuery {
    double time_s = 0;                                 ///< query time stamp [s]
    const mrpt::img::CImage* forward_image = nullptr;  ///< needed by image-based sources
    /// Odometry distance since the previous query [m], negative while reversing
    /// (common::signedTravel): a reversing vehicle's forward camera sees the survey's views in
    /// the reverse order.
    std::optional<double> travelled_m;
    /// false: the caller needs no match for this frame (e.g. the fine stage is tracking). A
    /// sequence matcher only adds the frame to its sequence; its next search is global.
    bool search = true;
    /// false: the caller verifies the place by other means (LookUP's ceiling match contradicts
    /// a wrong coarse track within frames), so a sequence matcher skips its periodic track
    /// audit, a global search that costs most of its time on a long reference.
    bool audit = true;
    /// Optional: the descriptor of forward_image, computed once by a caller that feeds several
    /// sequence matchers with the same descriptor options (one per survey traverse). Null: each
    /// computes its own.
    const Descriptor* forward_descriptor = nullptr;
};

struct CoarseResult {
    CoarseStatus status = CoarseStatus::Lost;
    std::string reason;  ///< why the status is not tracking/global/external (empty otherwise)

    std::size_t query_index = 0;  ///< 0-based count of queries seen by the source
    double query_time_s = 0;
    static constexpr std::size_t kNone = std::numeric_limits<std::size_t>::max();
    std::size_t reference_index = kNone;  ///< matched reference frame (kNone when none)
    double reference_time_s = std::numeric_limits<double>::quiet_NaN();  ///< the interface
    std::optional<mrpt::poses::CPose3D> coarse_pose;  ///< matched reference pose, if known

    /// Sequence matcher: (second-best - best) sequence score divided by the sequence length,
    /// in units of the locally enhanced confusion matrix (standard deviations); 0 when unknown.
    double confidence = 0;
    double velocity = 0;         ///< best path slope [reference frames / query frame]
    bool used_odometry = false;  ///< speed hypotheses came from odometry

    std::size_t evaluated_references = 0;  ///< descriptor differences computed for this frame
    std::size_t searched_candidates = 0;   ///< reference frames scored as sequence ends
    double descriptor_ms = 0;              ///< wall time of the descriptor [ms]
    double search_ms = 0;                  ///< wall time of the sequence search [ms]

    bool hasMatch() const { return reference_index != kNone; }
    /// A match that LookUP may refine: tracking, odometry, global or external.
    bool usable() const {
        return hasMatch() &&
               (status == CoarseStatus::Tracking || status == CoarseStatus::Odometry ||
                status == CoarseStatus::Global || status == CoarseStatus::External);
    }
};

class CoarseSource {
  public:
    virtual ~CoarseSource() = default;
    /// One query frame, in time order. Never throws for bad frames: the result says why.
    virtual CoarseResult locate(const CoarseQuery& query) = 0;
    virtual std::string name() const = 0;
    /// The consumer could not verify the last usable match (no ceiling match around it for
    /// several frames): a source that tracks drops its track and searches again, keeping its
    /// sequence. It learns only that the place is wrong, never the consumer's pose, so its
    /// matches stay independent of the fine stage.
    virtual void rejectLastMatch() {}
    /// The query jumped (a replay starting again): a source with a query history forgets it,
    /// so its next frames start up as its first ones did.
    virtual void restart() {}
    /// Query times [s] this source has answers for (first, last), when it is a file; nothing
    /// for a source that matches any frame (a sequence matcher).
    virtual std::optional<std::pair<double, double>> queryTimeSpan() const { return {}; }
    /// A source combining several sequences: their results for the last query other than the
    /// one locate() returned (more seeds for a verified acquisition). Empty otherwise.
    virtual std::vector<CoarseResult> otherMatches() const { return {}; }
};

/// Reference time stamps from a text file of `query_time reference_time` rows (seconds;
/// '#' comments and blank lines skipped; rows in increasing query time). A query gets the row
/// nearest in query time, or Lost when none is within `max_time_gap_s`. With `references`,
/// the matched reference index (nearest in time) and its pose are filled in too.
class MatchFileSource : public CoarseSource {
  public:
    /// Throws DescriptorFileError naming the file and line for a missing file or a bad row.
    MatchFileSource(const std::string& path, double max_time_gap_s,
                    std::shared_ptr<const ReferenceDescriptors> references = nullptr);
    CoarseResult locate(const CoarseQuery& query) override;
    std::string name() const override { return "match-file:" + path_; }
    std::optional<std::pair<double, double>> queryTimeSpan() const override;

  private:
    std::string path_;
    double max_time_gap_s_;
    std::shared_ptr<const ReferenceDescriptors> references_;
    std::vector<std::pair<double, double>> rows_;
    std::size_t queries_ = 0;
};

/// Coarse poses from a TUM (or MRPT 7-column) pose file, interpolated at the query time. With
/// `references` that carry poses, the nearest reference (in space) and its time stamp are
/// filled in, so LookUP can use the paper's time-stamp interface.
class PoseFileSource : public CoarseSource {
  public:
    /// Throws common::ConfigError naming the file and line for a bad file.
    PoseFileSource(const std::string& path, double max_gap_s,
                   std::shared_ptr<const ReferenceDescriptors> references = nullptr);
    CoarseResult locate(const CoarseQuery& query) override;
    std::string name() const override { return "pose-file:" + path_; }
    std::optional<std::pair<double, double>> queryTimeSpan() const override;

  private:
    std::string path_;
    double max_gap_s_;
    std::shared_ptr<const ReferenceDescriptors> references_;
    common::PoseTrack track_;
    mrpt::poses::CPose3DInterpolator interpolator_;
    std::size_t queries_ = 0;
};

}  // namespace lookup::coarse

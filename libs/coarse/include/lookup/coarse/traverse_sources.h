#pragma once
// The built-in coarse stage over a survey of several traverses: one sequence matcher per
// traverse, its matches reported with the caller's reference indices, and per frame the most
// trusted, most confident match of all. Laterally offset traverses see the tunnel from
// different places: matched as separate sequences they do not alias each other, and the one
// driven nearest the query's line wins.

#include <cstddef>
#include <memory>
#include <vector>

#include "lookup/coarse/coarse_localizer.h"
#include "lookup/coarse/coarse_source.h"
#include "lookup/coarse/options.h"
#include "lookup/coarse/reference_sequence.h"

namespace lookup::coarse {

/// A sequence matcher whose matches name the caller's reference index (`index[k]` for the
/// matcher's k-th reference frame) instead of the position in its sequence.
class IndexedSequenceSource : public CoarseSource {
  public:
    IndexedSequenceSource(std::unique_ptr<CoarseLocalizer> inner, std::vector<std::size_t> index)
        : inner_(std::move(inner)), index_(std::move(index)) {}
    CoarseResult locate(const CoarseQuery& query) override;
    std::string name() const override { return inner_->name(); }
    void rejectLastMatch() override { inner_->rejectLastMatch(); }
    void restart() override { inner_->restart(); }

  private:
    std::unique_ptr<CoarseLocalizer> inner_;
    std::vector<std::size_t> index_;
};

/// Several sequence matchers fed the same frames; locate() returns the most trusted match
/// (confident > held by odometry > unconfirmed > the rest), ties to the most confident, and
/// otherMatches() the others, most trusted first.
class MultiTraverseSource : public CoarseSource {
  public:
    /// Every source is a sequence matcher with `descriptor_options`.
    MultiTraverseSource(std::vector<std::unique_ptr<CoarseSource>> sources,
                        const CoarseOptions& descriptor_options)
        : sources_(std::move(sources)), descriptor_options_(descriptor_options) {}
    CoarseResult locate(const CoarseQuery& query) override;
    std::vector<CoarseResult> otherMatches() const override { return others_; }
    void rejectLastMatch() override { sources_.at(last_source_)->rejectLastMatch(); }
    void restart() override;
    std::string name() const override;

  private:
    std::vector<std::unique_ptr<CoarseSource>> sources_;
    CoarseOptions descriptor_options_;
    std::size_t last_source_ = 0;
    std::vector<CoarseResult> others_;
};

/// One traverse's forward-image descriptors and, per descriptor, the caller's reference index.
struct TraverseSequence {
    std::shared_ptr<ReferenceDescriptors> descriptors;
    std::vector<std::size_t> reference_index;
};

/// The coarse source over `traverses` (in the order given): a traverse shorter than one query
/// sequence (CoarseOptions::sequence_length) is left out when there are others; a single one
/// is returned without the multi-traverse wrapper. Null when no traverse is left.
std::unique_ptr<CoarseSource> makeTraverseSource(std::vector<TraverseSequence> traverses,
                                                 const CoarseOptions& options);

}  // namespace lookup::coarse

#include "lookup/coarse/traverse_sources.h"

#include <algorithm>

#include "lookup/coarse/descriptor.h"

namespace lookup::coarse {
namespace {

/// Confident match > held by odometry > unconfirmed (an acquisition seed) > the rest.
int trust(const CoarseResult& r) {
    if (!r.hasMatch()) return 0;
    switch (r.status) {
        case CoarseStatus::Tracking:
        case CoarseStatus::Global:
        case CoarseStatus::External:
            return 4;
        case CoarseStatus::Odometry:
            return 3;
        case CoarseStatus::Unconfirmed:
            return 2;
        default:
            return 1;
    }
}

}  // namespace

CoarseResult IndexedSequenceSource::locate(const CoarseQuery& query) {
    auto r = inner_->locate(query);
    if (r.hasMatch()) r.reference_index = index_.at(r.reference_index);
    return r;
}

CoarseResult MultiTraverseSource::locate(const CoarseQuery& query) {
    // One descriptor for all sequences (it was computed once per traverse); a broken image
    // leaves it to each sequence to say why.
    CoarseQuery shared = query;
    Descriptor descriptor;
    if (query.forward_image && !query.forward_descriptor) {
        try {
            if (query.forward_image->isExternallyStored()) query.forward_image->forceLoad();
            descriptor = computeDescriptor(*query.forward_image, descriptor_options_);
        } catch (const std::exception&) {
            descriptor.clear();
        }
        if (!descriptor.empty()) shared.forward_descriptor = &descriptor;
    }
    std::vector<CoarseResult> all;
    for (auto& source : sources_) all.push_back(source->locate(shared));
    last_source_ = 0;
    for (std::size_t k = 1; k < all.size(); ++k) {
        const int rank = trust(all[k]), best_rank = trust(all[last_source_]);
        if (rank > best_rank ||
            (rank == best_rank && all[k].confidence > all[last_source_].confidence)) {
            last_source_ = k;
        }
    }
    CoarseResult best = std::move(all[last_source_]);
    all.erase(all.begin() + static_cast<long>(last_source_));
    std::stable_sort(all.begin(), all.end(), [](const auto& a, const auto& b) {
        return trust(a) != trust(b) ? trust(a) > trust(b) : a.confidence > b.confidence;
    });
    others_ = std::move(all);  // most trusted first
    return best;
}

void MultiTraverseSource::restart() {
    for (auto& source : sources_) source->restart();
    others_.clear();
}

std::string MultiTraverseSource::name() const {
    std::string out;
    for (const auto& s : sources_) out += (out.empty() ? "" : "+") + s->name();
    return out;
}

std::unique_ptr<CoarseSource> makeTraverseSource(std::vector<TraverseSequence> traverses,
                                                 const CoarseOptions& options) {
    std::vector<std::unique_ptr<CoarseSource>> sources;
    for (auto& traverse : traverses) {
        // A traverse shorter than one query sequence cannot be matched; others still can.
        if (traverse.descriptors->size() < static_cast<std::size_t>(options.sequence_length) &&
            traverses.size() > 1) {
            continue;
        }
        sources.push_back(std::make_unique<IndexedSequenceSource>(
            std::make_unique<CoarseLocalizer>(traverse.descriptors, options),
            std::move(traverse.reference_index)));
    }
    if (sources.empty()) return nullptr;
    if (sources.size() == 1) return std::move(sources.front());
    return std::make_unique<MultiTraverseSource>(std::move(sources), options);
}

}  // namespace lookup::coarse

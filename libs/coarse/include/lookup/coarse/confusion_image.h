#pragma once
// Picture of the confusion matrix (references down, queries across) with the matcher's chosen
// path overlaid, as in the SeqSLAM papers: for checking the coarse stage by eye.

#include <cstddef>
#include <string>
#include <vector>

#include "lookup/coarse/coarse_source.h"

namespace lookup::coarse {

struct ConfusionImageOptions {
    int contrast_window_refs = 10;  ///< R_window of the column enhancement [references]
    int max_side_px = 1600;         ///< larger matrices are area-downsampled to fit [px]
};

/// Computes the full confusion matrix of `queries` against `references` (O(N M): offline
/// only), enhances each column locally, maps it with a colour map (bright = similar) and
/// overlays `results` (green: usable match, red: other statuses with a match) and, when given,
/// `truth` (white; reference index per query, CoarseResult::kNone to skip). Writes a PNG.
/// Throws std::runtime_error naming the file when it cannot be written, std::invalid_argument
/// when the sizes disagree.
void writeConfusionImage(const std::string& png_path, const ReferenceDescriptors& references,
                         const std::vector<Descriptor>& queries,
                         const std::vector<CoarseResult>& results,
                         const std::vector<std::size_t>& truth = {},
                         const ConfusionImageOptions& options = {});

}  // namespace lookup::coarse

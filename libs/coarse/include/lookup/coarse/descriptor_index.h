#pragma once
// Approximate nearest-neighbour index of the reference descriptors, the candidate generator of
// a global sequence search over a long reference (in the manner of Fast-SeqSLAM, Siam & Zhang
// 2017): instead of scoring every reference as a sequence end, the search scores windows
// around the places whose thumbnails resemble the buffered query frames.
//
// Descriptors are averaged over 4 x 4 pixel blocks, projected on their principal components
// (cv::PCA, fitted on at most kPcaSamples evenly spaced references) and indexed by randomised
// kd-trees (cv::flann); a query checks a fixed number of leaves, so its cost hardly depends on
// the number of references.

#include <opencv2/core.hpp>
#include <opencv2/flann.hpp>

#include <memory>
#include <vector>

#include "lookup/coarse/descriptor.h"
#include "lookup/coarse/reference_sequence.h"

namespace lookup::coarse {

class DescriptorIndex {
  public:
    /// Indexes every descriptor of `references` (not empty). Throws std::invalid_argument for
    /// an empty sequence.
    explicit DescriptorIndex(const ReferenceDescriptors& references);

    /// Indices of (approximately) the `k` references nearest to `descriptor`, nearest first.
    /// `descriptor` has the references' layout.
    std::vector<long> nearest(const Descriptor& descriptor, int k) const;

    std::size_t size() const { return static_cast<std::size_t>(features_.rows); }
    int dimensions() const { return features_.cols; }

    static constexpr int kPcaSamples = 2000;  ///< references the projection is fitted on
    static constexpr int kDimensions = 32;    ///< principal components kept (at most)
    static constexpr int kTrees = 4;          ///< randomised kd-trees
    static constexpr int kChecks = 64;        ///< leaves visited per query

  private:
    cv::Mat reduce(const Descriptor& descriptor) const;  ///< 1 x blocks, CV_32F

    int width_ = 0, height_ = 0;
    cv::PCA pca_;
    cv::Mat features_;  ///< one projected row per reference (the index keeps a pointer)
    std::unique_ptr<cv::flann::Index> index_;
};

}  // namespace lookup::coarse

#pragma once
// What a PlaceIndex holds, shared by its build, query and file code.

#include <cstdint>
#include <map>
#include <memory>
#include <opencv2/features2d.hpp>
#include <opencv2/flann.hpp>
#include <vector>

#include "binary_lsh.h"
#include "lookup/place/place_index.h"

namespace lookup::place::detail {

/// The pixel scale between a query and a reference a candidate may have: a camera twice as far
/// from the ceiling sees it at half the size.
constexpr double kMaxPixelScale = 2.0;

/// One indexed feature: the reference it belongs to and where it lies in that image.
struct Feature {
    std::uint32_t reference = 0;
    float x = 0, y = 0;
};

struct Impl {
    PlaceIndexOptions options;
    std::uint64_t fingerprint = 0;
    std::size_t database_references = 0;
    std::size_t indexed_references = 0;
    std::vector<Feature> features;
    cv::Mat descriptors;                       ///< one row per feature (CV_8U binary or CV_32F)
    BinaryLsh lsh;                             ///< binary descriptors
    std::unique_ptr<cv::flann::Index> search;  ///< float descriptors (KD-trees)
};

/// Query-to-reference point pairs, per reference.
struct Votes {
    std::map<std::uint32_t, std::vector<std::pair<cv::Point2f, cv::Point2f>>> by_reference;
};

/// What features are detected on: `grey` without its illumination at `illumination_sigma_px`
/// (0: the image as it is), contrast stretched; a noisy one smoothed first (`noisy_*`).
cv::Mat detectionImage(const cv::Mat& grey, const PlaceIndexOptions& o);
/// The strongest `n` features of detectionImage(grey, o), as index and query both detect them.
void detect(const cv::Mat& grey, const PlaceIndexOptions& o, int n,
            std::vector<cv::KeyPoint>& keypoints, cv::Mat& descriptors);
bool isBinary(FeatureType type);
void buildSearch(Impl& impl);
bool hasSearch(const Impl& impl);
Votes vote(const Impl& impl, const std::vector<cv::KeyPoint>& keypoints,
           const cv::Mat& descriptors);
std::vector<PlaceCandidate> fitCandidates(const Impl& impl, const Votes& votes);

}  // namespace lookup::place::detail

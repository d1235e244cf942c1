#include "lookup/coarse/descriptor_index.h"

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <stdexcept>

namespace lookup::coarse {
namespace {
// Block side of the reduction [thumbnail px]: 64 x 48 thumbnails become 16 x 12 values, few
// enough for a quick PCA, still the coarse layout of the tunnel.
constexpr int kBlock = 4;
}  // namespace

DescriptorIndex::DescriptorIndex(const ReferenceDescriptors& references) {
    if (references.empty()) {
        throw std::invalid_argument("DescriptorIndex: the reference sequence is empty");
    }
    width_ = references.layout().thumb_width_px;
    height_ = references.layout().thumb_height_px;
    const int n = static_cast<int>(references.size());
    cv::Mat reduced;
    for (int i = 0; i < n; ++i) {
        const cv::Mat row = reduce(references.descriptor(i));
        if (reduced.empty()) reduced.create(n, row.cols, CV_32F);
        row.copyTo(reduced.row(i));
    }

    // Fitting on an even subsample keeps the start-up cost bounded on a long reference.
    cv::Mat sample;
    const int samples = std::min(n, kPcaSamples);
    for (int s = 0; s < samples; ++s) {
        sample.push_back(reduced.row(static_cast<int>(static_cast<long>(s) * n / samples)));
    }
    const int dims = std::min({kDimensions, reduced.cols, std::max(1, samples - 1)});
    pca_ = cv::PCA(sample, cv::noArray(), cv::PCA::DATA_AS_ROW, dims);
    features_ = pca_.project(reduced);
    index_ = std::make_unique<cv::flann::Index>(features_, cv::flann::KDTreeIndexParams(kTrees),
                                                cvflann::FLANN_DIST_L2);
}

cv::Mat DescriptorIndex::reduce(const Descriptor& descriptor) const {
    const cv::Mat thumb(height_, width_, CV_8U, const_cast<std::uint8_t*>(descriptor.data()));
    cv::Mat small;
    cv::resize(thumb, small, cv::Size(std::max(1, width_ / kBlock), std::max(1, height_ / kBlock)),
               0, 0, cv::INTER_AREA);
    cv::Mat row;
    small.reshape(1, 1).convertTo(row, CV_32F);
    return row;
}

std::vector<long> DescriptorIndex::nearest(const Descriptor& descriptor, int k) const {
    if (descriptor.size() != static_cast<std::size_t>(width_) * height_) {
        throw std::invalid_argument("DescriptorIndex: descriptor has " +
                                    std::to_string(descriptor.size()) + " values, expected " +
                                    std::to_string(width_ * height_));
    }
    k = std::clamp(k, 1, features_.rows);
    const cv::Mat query = pca_.project(reduce(descriptor));
    cv::Mat indices(1, k, CV_32S), distances(1, k, CV_32F);
    index_->knnSearch(query, indices, distances, k, cv::flann::SearchParams(kChecks));
    std::vector<long> out;
    out.reserve(k);
    for (int i = 0; i < k; ++i) {
        const int j = indices.at<int>(0, i);
        if (j >= 0 && j < features_.rows) out.push_back(j);
    }
    return out;
}

}  // namespace lookup::coarse

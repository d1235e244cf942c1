// Votes and the geometric check of a place query.
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <optional>

#include "place_index_impl.h"

namespace lookup::place::detail {

Votes vote(const Impl& impl, const std::vector<cv::KeyPoint>& keypoints,
           const cv::Mat& descriptors) {
    const auto& o = impl.options;
    const int k = std::min<int>(o.neighbours, static_cast<int>(impl.features.size()));
    cv::Mat indices, distances;
    if (isBinary(o.features)) {
        impl.lsh.knn(descriptors, k, o.lsh_max_bucket, indices, distances);
    } else {
        impl.search->knnSearch(descriptors, indices, distances, k,
                               cv::flann::SearchParams(o.search_checks));
    }
    cv::Mat dist;
    distances.convertTo(dist, CV_32F);
    // A float descriptor's distance is L2 squared; the budget applies to binary ones only.
    const bool binary = isBinary(o.features);
    Votes votes;
    for (int q = 0; q < indices.rows; ++q) {
        for (int j = 0; j < k; ++j) {
            const int f = indices.at<int>(q, j);
            if (f < 0 || f >= static_cast<int>(impl.features.size())) continue;
            if (binary && dist.at<float>(q, j) > float(o.max_descriptor_distance)) continue;
            const Feature& feature = impl.features[static_cast<std::size_t>(f)];
            auto& pairs = votes.by_reference[feature.reference];
            // One vote per query feature and reference (its two neighbours may share one).
            if (!pairs.empty() && pairs.back().first == keypoints[std::size_t(q)].pt) continue;
            pairs.emplace_back(keypoints[std::size_t(q)].pt, cv::Point2f(feature.x, feature.y));
        }
    }
    return votes;
}

namespace {

std::optional<PlaceCandidate> fitOne(
    const PlaceIndexOptions& o, std::uint32_t reference,
    const std::vector<std::pair<cv::Point2f, cv::Point2f>>& pairs) {
    std::vector<cv::Point2f> from, to;
    for (const auto& [q, r] : pairs) {
        from.push_back(q);
        to.push_back(r);
    }
    std::vector<uchar> inlier_mask;
    const cv::Mat A = cv::estimateAffinePartial2D(from, to, inlier_mask, cv::RANSAC,
                                                  o.ransac_threshold_px, 500, 0.995, 10);
    if (A.empty()) return std::nullopt;
    PlaceCandidate c;
    c.reference = reference;
    c.votes = static_cast<int>(pairs.size());
    c.inliers = static_cast<int>(std::count(inlier_mask.begin(), inlier_mask.end(), 1));
    for (int r = 0; r < 2; ++r)
        for (int col = 0; col < 3; ++col) c.query_to_reference(r, col) = A.at<double>(r, col);
    c.scale = std::hypot(A.at<double>(0, 0), A.at<double>(1, 0));
    c.rotation_rad = std::atan2(A.at<double>(1, 0), A.at<double>(0, 0));
    // The scale in metres is judged once the cameras' heights are known (vehiclePose).
    if (c.inliers < o.min_inliers || c.scale < 1 / kMaxPixelScale || c.scale > kMaxPixelScale) {
        return std::nullopt;
    }
    return c;
}

}  // namespace

std::vector<PlaceCandidate> fitCandidates(const Impl& impl, const Votes& votes) {
    const auto& o = impl.options;
    std::vector<std::pair<int, std::uint32_t>> ranked;  // (votes, reference)
    for (const auto& [ref, pairs] : votes.by_reference) {
        if (static_cast<int>(pairs.size()) >= o.min_inliers) {
            ranked.emplace_back(static_cast<int>(pairs.size()), ref);
        }
    }
    std::sort(ranked.begin(), ranked.end(), std::greater<>());
    if (static_cast<int>(ranked.size()) > o.rerank_references) {
        ranked.resize(static_cast<std::size_t>(o.rerank_references));
    }
    std::vector<PlaceCandidate> out;
    for (const auto& [n, ref] : ranked) {
        if (auto c = fitOne(o, ref, votes.by_reference.at(ref))) out.push_back(*c);
    }
    std::sort(out.begin(), out.end(), [](const PlaceCandidate& a, const PlaceCandidate& b) {
        return a.inliers > b.inliers;
    });
    return out;
}

}  // namespace lookup::place::detail

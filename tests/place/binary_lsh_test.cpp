// detail::BinaryLsh against a brute-force Hamming search on random descriptors.
#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/core.hpp>
#include <random>
#include <set>

#include "../../libs/place/src/binary_lsh.h"

namespace {

using lookup::place::detail::BinaryLsh;

cv::Mat randomDescriptors(int rows, std::uint32_t seed) {
    cv::Mat d(rows, 32, CV_8U);
    std::mt19937 rng(seed);
    for (int r = 0; r < rows; ++r)
        for (int c = 0; c < 32; ++c) d.at<std::uint8_t>(r, c) = std::uint8_t(rng() & 0xff);
    return d;
}

// `row` with `flips` of its bits flipped (distinct bits).
cv::Mat flipped(const cv::Mat& row, int flips, std::mt19937& rng) {
    cv::Mat out = row.clone();
    std::set<int> done;
    while (static_cast<int>(done.size()) < flips) {
        const int b = static_cast<int>(rng() % 256);
        if (!done.insert(b).second) continue;
        out.at<std::uint8_t>(0, b / 8) ^= std::uint8_t(1u << (b % 8));
    }
    return out;
}

TEST(BinaryLsh, FindsEveryStoredDescriptorAtDistanceZeroFirst) {
    const cv::Mat data = randomDescriptors(5000, 7);
    BinaryLsh lsh;
    lsh.build(data, 3, 12);
    cv::Mat idx, dist;
    lsh.knn(data, 2, 0, idx, dist);
    for (int r = 0; r < data.rows; ++r) {
        ASSERT_EQ(idx.at<int>(r, 0), r);
        ASSERT_EQ(dist.at<int>(r, 0), 0);
        // The second neighbour is another descriptor, and its distance is the true one.
        const int j = idx.at<int>(r, 1);
        if (j >= 0) {
            ASSERT_NE(j, r);
            ASSERT_EQ(dist.at<int>(r, 1), cv::norm(data.row(r), data.row(j), cv::NORM_HAMMING));
        }
    }
}

TEST(BinaryLsh, NeighboursAreTheNearestOfTheCandidatesInDistanceOrder) {
    const cv::Mat data = randomDescriptors(3000, 11);
    BinaryLsh lsh;
    lsh.build(data, 4, 8);  // crowded buckets: many candidates per query
    std::mt19937 rng(3);
    int found = 0;
    for (int q = 0; q < 200; ++q) {
        const int target = static_cast<int>(rng() % 3000);
        const cv::Mat query = flipped(data.row(target), 10, rng);
        cv::Mat idx, dist;
        lsh.knn(query, 4, 0, idx, dist);
        for (int j = 1; j < 4; ++j) {
            if (idx.at<int>(0, j) < 0) continue;
            EXPECT_LE(dist.at<int>(0, j - 1), dist.at<int>(0, j));
        }
        // The true nearest neighbour (10 bits away; random rows are ~128 away) is found in
        // nearly every query: 4 tables of 8 bits miss it only when every key has a flipped bit.
        if (idx.at<int>(0, 0) == target) {
            EXPECT_EQ(dist.at<int>(0, 0), 10);
            ++found;
        }
    }
    EXPECT_GE(found, 190);
}

TEST(BinaryLsh, MultiProbeFindsWhatOneFlippedKeyBitHides) {
    const cv::Mat data = randomDescriptors(2000, 5);
    BinaryLsh plain, probed;
    plain.build(data, 1, 16, 0);
    probed.build(data, 1, 16, 1);
    std::mt19937 rng(9);
    int plain_found = 0, probed_found = 0;
    for (int q = 0; q < 300; ++q) {
        const int target = static_cast<int>(rng() % 2000);
        const cv::Mat query = flipped(data.row(target), 8, rng);
        cv::Mat idx, dist;
        plain.knn(query, 1, 0, idx, dist);
        plain_found += idx.at<int>(0, 0) == target;
        probed.knn(query, 1, 0, idx, dist);
        probed_found += idx.at<int>(0, 0) == target;
    }
    // 8 of 256 bits flipped: a 16-bit key keeps them all with p = 0.59, all but one with 0.32.
    EXPECT_GT(probed_found, plain_found + 50);
}

TEST(BinaryLsh, CrowdedBucketsAreSkippedWhenCapped) {
    cv::Mat data = randomDescriptors(100, 1);
    cv::Mat same = cv::repeat(data.row(0), 50, 1);  // 50 copies: one bucket of 51 per table
    cv::vconcat(data, same, data);
    BinaryLsh lsh;
    lsh.build(data, 2, 16);
    cv::Mat idx, dist;
    lsh.knn(data.row(0), 1, 0, idx, dist);
    EXPECT_EQ(dist.at<int>(0, 0), 0);
    lsh.knn(data.row(0), 1, 40, idx, dist);
    EXPECT_EQ(idx.at<int>(0, 0), -1);
    lsh.knn(data.row(1), 1, 40, idx, dist);  // its own buckets are small
    EXPECT_EQ(idx.at<int>(0, 0), 1);
}

TEST(BinaryLsh, SameSeedSameTablesEmptyInputNoNeighbours) {
    const cv::Mat data = randomDescriptors(1000, 2);
    BinaryLsh a, b, empty;
    a.build(data, 3, 10, 0, 42);
    b.build(data, 3, 10, 0, 42);
    const cv::Mat queries = randomDescriptors(50, 99);
    cv::Mat ia, da, ib, db;
    a.knn(queries, 2, 0, ia, da);
    b.knn(queries, 2, 0, ib, db);
    EXPECT_EQ(cv::countNonZero(ia != ib), 0);
    empty.build(cv::Mat(), 3, 10);
    empty.knn(queries, 2, 0, ia, da);
    EXPECT_EQ(cv::countNonZero(ia != -1), 0);
    EXPECT_EQ(empty.size(), 0u);
}

}  // namespace

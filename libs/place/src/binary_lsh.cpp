#include "binary_lsh.h"

#include <algorithm>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>

#include <opencv2/core/hal/hal.hpp>

namespace lookup::place::detail {

std::uint32_t BinaryLsh::key(const Table& t, const std::uint8_t* row) const {
    std::uint32_t k = 0;
    for (std::size_t i = 0; i < t.bits.size(); ++i) {
        const unsigned b = t.bits[i];
        k |= std::uint32_t((row[b >> 3] >> (b & 7)) & 1u) << i;
    }
    return k;
}

void BinaryLsh::build(const cv::Mat& descriptors, int tables, int key_bits, int probe_level,
                      std::uint32_t seed) {
    CV_Assert(descriptors.empty() || descriptors.type() == CV_8U);
    CV_Assert(key_bits >= 1 && key_bits <= 24 && tables >= 1 && probe_level >= 0);
    tables_.clear();
    probes_ = {0};
    size_ = static_cast<std::size_t>(descriptors.rows);
    bytes_ = descriptors.cols;
    if (descriptors.empty()) return;
    const int bits = bytes_ * 8;
    CV_Assert(key_bits <= bits);
    for (int level = 1; level <= std::min(probe_level, key_bits); ++level) {
        for (std::uint32_t m = 1; m < (std::uint32_t(1) << key_bits); ++m) {
            if (__builtin_popcount(m) == level) probes_.push_back(m);
        }
    }
    std::mt19937 rng(seed);
    std::vector<std::uint16_t> all(static_cast<std::size_t>(bits));
    std::iota(all.begin(), all.end(), std::uint16_t(0));
    const std::size_t buckets = std::size_t(1) << key_bits;
    std::vector<std::uint32_t> keys(size_);
    for (int t = 0; t < tables; ++t) {
        // A partial Fisher-Yates shuffle with the generator's raw output: the same bits on
        // every standard library (std::shuffle's use of the engine is unspecified).
        for (int i = 0; i < key_bits; ++i) {
            const auto j =
                static_cast<std::size_t>(i) + rng() % static_cast<std::uint32_t>(bits - i);
            std::swap(all[static_cast<std::size_t>(i)], all[j]);
        }
        Table table;
        table.bits.assign(all.begin(), all.begin() + key_bits);
        table.offsets.assign(buckets + 1, 0);
        for (std::size_t r = 0; r < size_; ++r) {
            keys[r] = key(table, descriptors.ptr<std::uint8_t>(static_cast<int>(r)));
            ++table.offsets[keys[r] + 1];
        }
        std::partial_sum(table.offsets.begin(), table.offsets.end(), table.offsets.begin());
        table.ids.resize(size_);
        table.rows.create(descriptors.rows, bytes_, CV_8U);
        std::vector<std::uint32_t> fill(table.offsets.begin(), table.offsets.end() - 1);
        for (std::size_t r = 0; r < size_; ++r) {
            const std::uint32_t at = fill[keys[r]]++;
            table.ids[at] = static_cast<std::uint32_t>(r);
            std::memcpy(table.rows.ptr<std::uint8_t>(static_cast<int>(at)),
                        descriptors.ptr<std::uint8_t>(static_cast<int>(r)),
                        static_cast<std::size_t>(bytes_));
        }
        if (buckets > size_) {  // mostly empty: keep the non-empty buckets only
            std::vector<std::uint32_t> starts;
            for (std::size_t b = 0; b < buckets; ++b) {
                if (table.offsets[b + 1] == table.offsets[b]) continue;
                table.keys.push_back(static_cast<std::uint32_t>(b));
                starts.push_back(table.offsets[b]);
            }
            starts.push_back(static_cast<std::uint32_t>(size_));
            table.offsets = std::move(starts);
        }
        tables_.push_back(std::move(table));
    }
}

void BinaryLsh::bucket(const Table& t, std::uint32_t b, std::uint32_t& begin, std::uint32_t& end) {
    if (t.keys.empty()) {
        begin = t.offsets[b];
        end = t.offsets[b + 1];
        return;
    }
    const auto it = std::lower_bound(t.keys.begin(), t.keys.end(), b);
    if (it == t.keys.end() || *it != b) {
        begin = end = 0;
        return;
    }
    const auto i = static_cast<std::size_t>(it - t.keys.begin());
    begin = t.offsets[i];
    end = t.offsets[i + 1];
}

void BinaryLsh::knn(const cv::Mat& queries, int k, int max_bucket, cv::Mat& indices,
                    cv::Mat& distances) const {
    CV_Assert(k >= 1);
    indices.create(queries.rows, k, CV_32S);
    distances.create(queries.rows, k, CV_32S);
    indices.setTo(-1);
    distances.setTo(std::numeric_limits<int>::max());
    if (tables_.empty() || queries.empty()) return;
    CV_Assert(queries.type() == CV_8U && queries.cols == bytes_);
    for (int q = 0; q < queries.rows; ++q) {
        const std::uint8_t* row = queries.ptr<std::uint8_t>(q);
        int* best_id = indices.ptr<int>(q);
        int* best_d = distances.ptr<int>(q);
        for (const Table& t : tables_) {
            const std::uint32_t own = key(t, row);
            for (const std::uint32_t probe : probes_) {
                std::uint32_t begin = 0, end = 0;
                bucket(t, own ^ probe, begin, end);
                if (max_bucket > 0 && end - begin > static_cast<std::uint32_t>(max_bucket)) {
                    continue;
                }
                const std::uint8_t* cand = t.rows.ptr<std::uint8_t>(static_cast<int>(begin));
                for (std::uint32_t i = begin; i < end; ++i, cand += bytes_) {
                    const int d = cv::hal::normHamming(row, cand, bytes_);
                    if (d >= best_d[k - 1]) continue;
                    const int id = static_cast<int>(t.ids[i]);
                    if (std::find(best_id, best_id + k, id) != best_id + k) continue;  // seen
                    int j = k - 1;
                    for (; j > 0 && best_d[j - 1] > d; --j) {
                        best_d[j] = best_d[j - 1];
                        best_id[j] = best_id[j - 1];
                    }
                    best_d[j] = d;
                    best_id[j] = id;
                }
            }
        }
    }
}

std::size_t BinaryLsh::tableBytes() const {
    std::size_t n = 0;
    for (const auto& t : tables_) {
        n += t.bits.size() * sizeof(std::uint16_t) +
             (t.keys.size() + t.offsets.size()) * sizeof(std::uint32_t) +
             t.ids.size() * sizeof(std::uint32_t) + t.rows.total();
    }
    return n;
}

}  // namespace lookup::place::detail

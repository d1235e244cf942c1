#pragma once
// Locality-sensitive hashing of binary descriptors (ORB, AKAZE) under the Hamming distance:
// `tables` hash tables, each keyed by `key_bits` bits of the descriptor chosen at random (a
// fixed seed, so an index answers the same on every machine). A query descriptor is compared
// with the descriptors in its bucket of each table. ORB's bits are correlated, so a few keys
// hold most descriptors of a large database: a query scans such a bucket whole. Each table
// keeps its own copy of the descriptors in bucket order, so a bucket is one contiguous run of
// memory (FLANN's LSH reads each candidate from wherever it lies in the database: a cache miss
// per candidate once the descriptors outgrow the cache). Buckets holding more than
// `max_bucket` descriptors can be skipped (0: none is). `probe_level` > 0 also scans the
// buckets whose keys differ in up to that many bits (multi-probe).

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace lookup::place::detail {

class BinaryLsh {
  public:
    /// `descriptors`: CV_8U, one row per descriptor. Throws cv::Exception on another type.
    void build(const cv::Mat& descriptors, int tables, int key_bits, int probe_level = 0,
               std::uint32_t seed = 1);

    /// The `k` nearest distinct descriptors of each row of `queries` among its buckets:
    /// `indices` (CV_32S, -1 where fewer were found) and `distances` (CV_32S, Hamming bits),
    /// nearest first.
    void knn(const cv::Mat& queries, int k, int max_bucket, cv::Mat& indices,
             cv::Mat& distances) const;

    std::size_t size() const { return size_; }
    /// Bytes of the hash tables and their copies of the descriptors.
    std::size_t tableBytes() const;

  private:
    struct Table {
        std::vector<std::uint16_t> bits;  ///< descriptor bit of each key bit
        /// Dense (`keys` empty): bucket b holds ids[offsets[b], offsets[b+1]). Sparse, when
        /// there are more keys than descriptors: the non-empty buckets' keys, ascending, and
        /// bucket keys[i] holds ids[offsets[i], offsets[i+1]).
        std::vector<std::uint32_t> keys;
        std::vector<std::uint32_t> offsets;
        std::vector<std::uint32_t> ids;  ///< descriptor index, in bucket order
        cv::Mat rows;                    ///< the descriptors, in bucket order
    };
    std::uint32_t key(const Table& t, const std::uint8_t* row) const;
    /// The ids range [begin, end) of bucket `b` (empty when none).
    static void bucket(const Table& t, std::uint32_t b, std::uint32_t& begin, std::uint32_t& end);

    std::size_t size_ = 0;
    int bytes_ = 0;
    std::vector<std::uint32_t> probes_;  ///< key masks scanned (0 first)
    std::vector<Table> tables_;
};

}  // namespace lookup::place::detail

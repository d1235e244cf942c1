#pragma once
// A bounded least-recently-used cache of images read from disk, so memory does not grow with
// the length of the mine. Thread-safe.

#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <list>
#include <mutex>
#include <string>
#include <unordered_map>

namespace lookup::database {

class ImageCache {
  public:
    /// `capacity`: the most images kept in memory (>= 1).
    explicit ImageCache(std::size_t capacity);

    /// The image at `path` as 8-bit grey (cv::IMREAD_GRAYSCALE), from the cache or read from
    /// disk (evicting the least recently used image when full). Throws DatabaseError naming the
    /// file if it cannot be read. The returned Mat shares memory with the cache entry: clone it
    /// before writing into it.
    cv::Mat get(const std::string& path);

    std::size_t capacity() const { return capacity_; }
    std::size_t size() const;
    /// Number of reads from disk so far (cache misses).
    std::size_t diskReads() const;

  private:
    using Entry = std::pair<std::string, cv::Mat>;
    std::size_t capacity_;
    mutable std::mutex mutex_;
    std::list<Entry> lru_;  // front = most recently used
    std::unordered_map<std::string, std::list<Entry>::iterator> index_;
    std::size_t disk_reads_ = 0;
};

}  // namespace lookup::database

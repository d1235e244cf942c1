#include "lookup/database/image_cache.h"

#include <opencv2/imgcodecs.hpp>

#include "lookup/database/reference.h"

namespace lookup::database {

ImageCache::ImageCache(std::size_t capacity) : capacity_(capacity) {
    if (capacity_ == 0) throw DatabaseError("ImageCache: capacity must be >= 1");
}

cv::Mat ImageCache::get(const std::string& path) {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        if (auto it = index_.find(path); it != index_.end()) {
            lru_.splice(lru_.begin(), lru_, it->second);
            return it->second->second;
        }
    }
    // Read outside the lock so other threads are not blocked by disk I/O.
    cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
    if (image.empty()) throw DatabaseError(path + ": cannot read image");
    std::lock_guard<std::mutex> lock(mutex_);
    ++disk_reads_;
    if (auto it = index_.find(path); it != index_.end()) return it->second->second;
    lru_.emplace_front(path, image);
    index_[path] = lru_.begin();
    while (lru_.size() > capacity_) {
        index_.erase(lru_.back().first);
        lru_.pop_back();
    }
    return image;
}

std::size_t ImageCache::size() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return lru_.size();
}

std::size_t ImageCache::diskReads() const {
    std::lock_guard<std::mutex> lock(mutex_);
    return disk_reads_;
}

}  // namespace lookup::database

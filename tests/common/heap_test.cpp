#include "lookup/common/heap.h"

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cstdlib>
#include <vector>

namespace lookup::common {
namespace {

long minorPageFaults() {
    rusage usage{};
    getrusage(RUSAGE_SELF, &usage);
    return usage.ru_minflt;
}

// Fills a cache of `count` images of `bytes` each (allocated and written, as a reference's
// pyramid is), empties it, and returns the page faults that took.
long pageFaultsOfACacheFill(int count, std::size_t bytes) {
    const long before = minorPageFaults();
    std::vector<char*> images;
    for (int i = 0; i < count; ++i) {
        auto* image = static_cast<char*>(std::malloc(bytes));
        for (std::size_t b = 0; b < bytes; b += 512) static_cast<volatile char*>(image)[b] = 1;
        images.push_back(image);
    }
    const long faults = minorPageFaults() - before;
    for (char* image : images) std::free(image);
    return faults;
}

TEST(Heap, ImagesCachedAfterThePrefaultReuseItsPages) {
    // 64 images of 300 kB (a 320 x 240 reference's cached copies): above glibc's mmap
    // threshold, each is a fresh mapping faulted in page by page.
    constexpr int kImages = 64;
    constexpr std::size_t kBytes = 300 * 1000;
    const long without = pageFaultsOfACacheFill(kImages, kBytes);
    EXPECT_GT(without, kImages * 50);
    const std::size_t reserved = std::size_t(32) << 20;
    EXPECT_GE(prefaultHeap(reserved), reserved);
    const long with = pageFaultsOfACacheFill(kImages, kBytes);
    EXPECT_LT(with, without / 10) << "without the prefault: " << without;
    // And again after the cache was emptied: freed pages stay with the process.
    EXPECT_LT(pageFaultsOfACacheFill(kImages, kBytes), without / 10);
}

TEST(Heap, NothingReservedForZeroBytes) { EXPECT_EQ(prefaultHeap(0), 0u); }

}  // namespace
}  // namespace lookup::common

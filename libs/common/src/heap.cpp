#include "lookup/common/heap.h"

#include <malloc.h>
#include <unistd.h>

#include <algorithm>
#include <climits>
#include <cstdlib>
#include <vector>

namespace lookup::common {

std::size_t prefaultHeap(std::size_t bytes) {
    if (bytes == 0) return 0;
    // mallopt takes an int; a cache configured beyond 1 GiB fills the rest as it is used.
    constexpr std::size_t kMaxBytes = std::size_t(1) << 30;
    bytes = std::min(bytes, kMaxBytes);
    // glibc refuses an mmap threshold above HEAP_MAX_SIZE / 2 (32 MiB on 64-bit systems).
    constexpr std::size_t kMaxMmapThreshold = std::size_t(32) << 20;
    mallopt(M_MMAP_THRESHOLD, int(std::min(bytes, kMaxMmapThreshold)));
    // Above the heap's top chunk once all of it is freed: glibc would trim it to nothing.
    mallopt(M_TRIM_THRESHOLD, int(std::min<std::size_t>(2 * bytes, INT_MAX)));
    // Blocks of an image's size, so the freed heap is one top chunk that later blocks split.
    constexpr std::size_t kBlock = std::size_t(256) << 10;
    const std::size_t page = std::size_t(std::max(1L, sysconf(_SC_PAGESIZE)));
    std::vector<void*> blocks;
    std::size_t touched = 0;
    for (; touched < bytes; touched += kBlock) {
        void* b = std::malloc(kBlock);
        if (!b) break;
        blocks.push_back(b);
        // One write per page faults it in; volatile, as the compiler may drop stores to memory
        // that is only freed afterwards.
        auto* bytes_of_b = static_cast<volatile char*>(b);
        for (std::size_t i = 0; i < kBlock; i += page) bytes_of_b[i] = 0;
    }
    for (void* b : blocks) std::free(b);
    return touched;
}

}  // namespace lookup::common

#pragma once
// A minimal parallel loop for independent work items (scan registrations, per-keyframe
// preprocessing): results written by index stay the same whatever the thread count.

#include <cstddef>
#include <functional>

namespace lookup::common {

/// Runs `fn(i)` once for every i in [0, n) on up to `threads` threads (0: one per hardware
/// thread) and returns when all have run. Threads take the next free index, so `fn` must not
/// depend on which thread or in which order indices run. When `fn` throws, no new index is
/// started and the first exception is rethrown here once the running ones are done.
/// `progress`, if given, is called on the calling thread with the number of indices done so
/// far, at the start and about every `progress_period_ms` while the loop runs.
void parallelFor(std::size_t n, unsigned threads, const std::function<void(std::size_t)>& fn,
                 const std::function<void(std::size_t)>& progress = {},
                 int progress_period_ms = 200);

}  // namespace lookup::common

#pragma once
// Real-time start-up of a frame loop that allocates images as it goes (reference images
// loaded into a cache, their pyramids and temporaries). Left to itself glibc serves blocks over
// 128 KiB with fresh mmap()s and returns freed memory to the kernel, so each newly allocated
// image costs a page fault per 4 KiB page on first touch: in a virtual machine, more than the
// image processing itself.

#include <cstddef>

namespace lookup::common {

/// Keeps the heap for the rest of the process (glibc; process-wide, call once on the thread
/// that runs the loop, before it): blocks up to `bytes` (at most 32 MiB) come from the heap,
/// freed memory stays with the process up to `bytes`, and `bytes` of heap (at most 1 GiB) is
/// faulted in now, so the loop reuses pages already mapped. Returns the bytes faulted in.
std::size_t prefaultHeap(std::size_t bytes);

}  // namespace lookup::common

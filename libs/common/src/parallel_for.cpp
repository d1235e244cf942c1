#include "lookup/common/parallel_for.h"

#include <algorithm>
#include <atomic>
#include <chrono>
#include <condition_variable>
#include <exception>
#include <mutex>
#include <thread>
#include <vector>

namespace lookup::common {

void parallelFor(std::size_t n, unsigned threads, const std::function<void(std::size_t)>& fn,
                 const std::function<void(std::size_t)>& progress, int progress_period_ms) {
    if (threads == 0) threads = std::max(1u, std::thread::hardware_concurrency());
    const auto workers = static_cast<unsigned>(std::min<std::size_t>(threads, n));
    if (workers == 0) return;
    std::atomic<std::size_t> next{0}, done{0};
    std::mutex mutex;
    std::condition_variable finished;
    unsigned running = workers;
    std::exception_ptr failure;
    const auto work = [&] {
        try {
            for (std::size_t i; (i = next++) < n;) {
                fn(i);
                ++done;
            }
        } catch (...) {
            // An exception escaping a std::thread would end the process: keep the first.
            const std::lock_guard<std::mutex> lock(mutex);
            if (!failure) failure = std::current_exception();
            next = n;
        }
        const std::lock_guard<std::mutex> lock(mutex);
        if (--running == 0) finished.notify_all();
    };
    std::vector<std::thread> pool;
    for (unsigned t = 0; t < workers; ++t) pool.emplace_back(work);
    {
        std::unique_lock<std::mutex> lock(mutex);
        while (running > 0) {
            if (progress) {
                lock.unlock();
                progress(done);
                lock.lock();
            }
            finished.wait_for(lock, std::chrono::milliseconds(progress_period_ms),
                              [&] { return running == 0; });
        }
    }
    for (auto& t : pool) t.join();
    if (failure) std::rethrow_exception(failure);
}

}  // namespace lookup::common

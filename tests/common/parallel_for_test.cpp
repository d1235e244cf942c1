#include "lookup/common/parallel_for.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <stdexcept>
#include <thread>
#include <vector>

namespace lookup::common {
namespace {

TEST(ParallelFor, RunsEveryIndexExactlyOnce) {
    for (const unsigned threads : {0u, 1u, 2u, 7u}) {
        constexpr std::size_t kN = 1000;
        std::vector<std::atomic<int>> runs(kN);
        parallelFor(kN, threads, [&](std::size_t i) { ++runs[i]; });
        for (std::size_t i = 0; i < kN; ++i) {
            ASSERT_EQ(runs[i], 1) << "index " << i << " with " << threads << " threads";
        }
    }
}

TEST(ParallelFor, NothingToDoReturnsAtOnce) {
    bool called = false;
    parallelFor(0, 4, [&](std::size_t) { called = true; });
    EXPECT_FALSE(called);
}

TEST(ParallelFor, MoreThreadsThanIndices) {
    std::vector<std::atomic<int>> runs(3);
    parallelFor(3, 16, [&](std::size_t i) { ++runs[i]; });
    for (const auto& r : runs) EXPECT_EQ(r, 1);
}

TEST(ParallelFor, ExceptionReachesTheCaller) {
    for (const unsigned threads : {1u, 3u}) {
        std::atomic<int> ran{0};
        try {
            parallelFor(500, threads, [&](std::size_t i) {
                ++ran;
                if (i == 37) throw std::runtime_error("item 37 failed");
                std::this_thread::sleep_for(std::chrono::milliseconds(1));
            });
            FAIL() << "no exception with " << threads << " threads";
        } catch (const std::runtime_error& e) {
            EXPECT_STREQ(e.what(), "item 37 failed");
        }
        // No new index starts after the failure: far fewer than all ran.
        EXPECT_LT(ran, 500);
    }
}

TEST(ParallelFor, ProgressCountsUpToTheEnd) {
    std::vector<std::size_t> seen;
    parallelFor(
        20, 2, [](std::size_t) { std::this_thread::sleep_for(std::chrono::milliseconds(5)); },
        [&](std::size_t done) { seen.push_back(done); }, 10);
    ASSERT_FALSE(seen.empty());
    EXPECT_EQ(seen.front(), 0u);  // before the first item could finish
    for (std::size_t k = 1; k < seen.size(); ++k) EXPECT_LE(seen[k - 1], seen[k]);
    EXPECT_LE(seen.back(), 20u);
}

}  // namespace
}  // namespace lookup::common

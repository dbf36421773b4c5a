#include "base/thread_pool.h"

#include <gtest/gtest.h>

#include <atomic>
#include <cfloat>
#include <cmath>
#include <stdexcept>
#include <vector>

#include "base/error.h"

namespace dejag {
namespace {

TEST(ThreadPool, CoversEveryIndexExactlyOnce) {
    for (int threads : {1, 2, 3}) {
        setThreadCount(threads);
        EXPECT_EQ(threadCount(), threads);
        std::vector<std::atomic<int>> hits(1001);
        parallelFor(0, 1001, 7, [&](int64_t begin, int64_t end) {
            for (int64_t i = begin; i < end; ++i) hits[i]++;
        });
        for (auto& hit : hits) EXPECT_EQ(hit.load(), 1);
    }
    setThreadCount(0);
}

TEST(ThreadPool, NestedCallsRunSerially) {
    setThreadCount(2);
    std::atomic<int> total{0};
    parallelFor(0, 8, 1, [&](int64_t, int64_t) {
        parallelFor(0, 10, 1, [&](int64_t begin, int64_t end) { total += int(end - begin); });
    });
    EXPECT_EQ(total.load(), 80);
    setThreadCount(0);
}

TEST(ThreadPool, RethrowsTheBodysException) {
    setThreadCount(2);
    EXPECT_THROW(parallelFor(0, 100, 1,
                             [&](int64_t begin, int64_t) {
                                 if (begin == 57) throw Error("boom");
                             }),
                 Error);
    // The pool still works afterwards.
    std::atomic<int> count{0};
    parallelFor(0, 100, 1, [&](int64_t, int64_t) { count++; });
    EXPECT_EQ(count.load(), 100);
    setThreadCount(0);
}

TEST(ThreadPool, EmptyRangeDoesNothing) {
    bool called = false;
    parallelFor(5, 5, 1, [&](int64_t, int64_t) { called = true; });
    parallelFor(5, 2, 1, [&](int64_t, int64_t) { called = true; });
    EXPECT_FALSE(called);
}

TEST(ThreadPool, WorkersFlushDenormals) {
    setThreadCount(2);
    std::vector<float> results(64, -1.0f);
    volatile float tiny = FLT_MIN;
    parallelFor(0, 64, 1, [&](int64_t begin, int64_t) { results[begin] = tiny * 0.25f; });
    for (float value : results) EXPECT_EQ(value, 0.0f) << "a denormal survived on a worker thread";
    setThreadCount(0);
}

TEST(ThreadPool, RejectsBadThreadCounts) {
    EXPECT_THROW(setThreadCount(-1), Error);
    EXPECT_THROW(setThreadCount(5000), Error);
}

}  // namespace
}  // namespace dejag

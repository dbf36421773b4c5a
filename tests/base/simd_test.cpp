#include "base/simd.h"

#include <gtest/gtest.h>

#include "base/error.h"
#include "base/peak.h"
#include "base/thread_pool.h"

namespace dejag {
namespace {

TEST(Simd, NamesRoundTrip) {
    for (SimdLevel level : {SimdLevel::Scalar, SimdLevel::Avx2, SimdLevel::Avx512})
        EXPECT_EQ(parseSimdLevel(simdLevelName(level)), level);
    EXPECT_FALSE(parseSimdLevel("sse9").has_value());
}

TEST(Simd, EveryLevelUpToTheCpusCanBeForced) {
    const SimdLevel original = activeSimdLevel();
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        EXPECT_EQ(activeSimdLevel(), SimdLevel(level));
    }
    setSimdLevel(original);
}

TEST(Simd, FmaPeakIsMeasuredOnEveryLevel) {
    const SimdLevel original = activeSimdLevel();
    setThreadCount(1);
    double previous = 0.0;
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        const FmaPeak peak = measureFmaPeak(30.0);
        EXPECT_GT(peak.gmacsTotal, 0.1);
        EXPECT_EQ(peak.threads, 1);
        // Wider vectors give more multiply-adds per second (by far: x8 or x2 lanes).
        if (level > 0) {
            EXPECT_GT(peak.gmacsTotal, previous);
        }
        previous = peak.gmacsTotal;
    }
    setSimdLevel(original);
    setThreadCount(0);
}

}  // namespace
}  // namespace dejag

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
    setSimdLevel(SimdLevel::Scalar);
    // The best of five short measurements: on a loaded machine a single one may lose its core midway.
    auto best = [] {
        FmaPeak top = measureFmaPeak(30.0);
        for (int i = 0; i < 4; ++i) {
            const FmaPeak p = measureFmaPeak(30.0);
            if (p.gmacsTotal > top.gmacsTotal) top = p;
        }
        return top;
    };
    const double scalar = best().gmacsTotal;
    EXPECT_GT(scalar, 0.1);
    for (int level = 1; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        const FmaPeak peak = best();
        EXPECT_EQ(peak.threads, 1);
        EXPECT_EQ(peak.level, SimdLevel(level));
        // 8 or 16 lanes against 1: far more multiply-adds per second, whatever the machine's load. (AVX-512
        // against AVX2 is not compared: some CPUs run 512-bit FMAs at the 256-bit rate.)
        EXPECT_GT(peak.gmacsTotal, 2.0 * scalar) << simdLevelName(SimdLevel(level));
    }
    setSimdLevel(original);
    setThreadCount(0);
}

}  // namespace
}  // namespace dejag

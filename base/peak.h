// dejag/base: the machine's fp32 FMA peak, measured in the same run as the figure it is compared with.
//
// On a shared, noisy machine a datasheet peak says little; benchmarks print their throughput next to
// this measured peak (the median of a few short bursts of independent FMA chains on every thread).
#pragma once

#include "base/simd.h"

namespace dejag {

struct FmaPeak {
    int threads = 1;
    SimdLevel level = SimdLevel::Scalar;
    double gmacsTotal = 0.0;  // multiply-adds per nanosecond, all threads together
    double gmacsPerThread = 0.0;
};

// Measures with the active SIMD level on threadCount() threads for roughly `milliseconds` in total.
FmaPeak measureFmaPeak(double milliseconds = 150.0);

}  // namespace dejag

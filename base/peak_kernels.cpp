// FMA burn loop, compiled once per SIMD level (see base/peak.h).
#include <cstdint>

#include "base/simd_vector.h"

namespace dejag::DEJAG_SIMD_NAMESPACE {

// Runs `iterations` rounds of independent FMA chains (enough to cover FMA latency on two ports) and
// returns the multiply-adds performed. The result is written to `sink` so nothing is optimised away.
// The chains, the scale and the offset must all stay in registers: 16 chains on AVX-512 (32 registers),
// 12 on AVX2 (16 registers: with 16 chains three lived on the stack and the measured peak was 20-40 %
// low, below what the convolutions reach).
uint64_t fmaBurn(int64_t iterations, float* sink) {
    constexpr int kChains = kFloatLanes == 16 ? 16 : 12;
    VFloat acc[kChains];
    for (int i = 0; i < kChains; ++i) acc[i] = splat<VFloat>(0.001f * float(i));
    const VFloat scale = splat<VFloat>(0.999999f);
    const VFloat offset = splat<VFloat>(1e-7f);
    for (int64_t it = 0; it < iterations; ++it) {
#pragma GCC unroll 16
        for (int i = 0; i < kChains; ++i) acc[i] = acc[i] * scale + offset;
    }
    VFloat total = acc[0];
    for (int i = 1; i < kChains; ++i) total += acc[i];
    *sink = horizontalSum(total);
    return uint64_t(iterations) * kChains * kFloatLanes;
}

}  // namespace dejag::DEJAG_SIMD_NAMESPACE

// dejag/data (internal): the SIMD kernels behind data/metrics.h, one copy per SIMD level.
#pragma once

#include <cstddef>
#include <cstdint>

#include "base/simd.h"

namespace dejag {

// SSIM window of spec/metrics.md: Gaussian, sigma 1.5, truncated at 3.5 sigma -> radius 5, 11 taps
// (scipy.ndimage.gaussian_filter's truncation, which scikit-image uses).
inline constexpr int kSsimRadius = 5;
inline constexpr int kSsimTaps = 2 * kSsimRadius + 1;

// One band of output rows of one channel. The five local moments (mean x, mean y, E[x^2], E[y^2],
// E[xy]) are filtered separably: each input row is filtered horizontally into a ring of 11 rows per
// moment, and each output row combines the ring vertically, so a band reads its input once.
// Samples are shifted by -offset before squaring so that sigma^2 = E[x^2] - mean^2 loses little to
// cancellation in float32; the offset is added back to the means. Borders reflect (scipy 'reflect').
struct SsimBand {
    const float* reference;  // (H, W, C) interleaved
    const float* test;       // (H, W, C) interleaved
    int width = 0, height = 0, channels = 1, channel = 0;
    float offset = 0.0f;
    float c1 = 0.0f, c2 = 0.0f;
    const float* weights = nullptr;  // kSsimTaps, normalised
    int rowBegin = 0, rowEnd = 0;
    float* map = nullptr;       // (H, W) SSIM of this channel, or nullptr
    double* rowSums = nullptr;  // (H) sum of SSIM over columns [radius, W - radius), or nullptr
    float* scratch = nullptr;   // ssimScratchFloats(width)
};

inline size_t ssimScratchFloats(int width) {
    return 5 * size_t(width + 2 * kSsimRadius) + 5 * size_t(kSsimTaps) * width + size_t(width);
}

DEJAG_SIMD_DECLARE(
    void ssimBand(const SsimBand& band);
    // Sums over n samples: (test - reference)^2 into *squaredError, reference^2 into *referenceEnergy.
    void sumSquaredError(const float* reference, const float* test, int64_t n, double* squaredError,
                         double* referenceEnergy);)

}  // namespace dejag

// dejag/data (internal): the SIMD kernels behind data/metrics.h, one copy per SIMD level.
#pragma once

#include <cstddef>
#include <cstdint>

#include "base/simd.h"

namespace dejag {

// SSIM window of docs/metrics.md: Gaussian, sigma 1.5, truncated at 3.5 sigma -> radius 5, 11 taps
// (scipy.ndimage.gaussian_filter's truncation, which scikit-image uses).
inline constexpr int kSsimRadius = 5;
inline constexpr int kSsimTaps = 2 * kSsimRadius + 1;

// Columns per tile: the per-channel rings of one tile stay in L2 and one moment's 11 rows in L1.
inline constexpr int kSsimTileWidth = 256;

// One tile (a band of output rows x a range of columns) of every channel. Each input row is read once
// for all channels; the five local moments (mean x, mean y, E[x^2], E[y^2], E[xy]) are filtered
// separably: each input row horizontally into a ring of 11 rows per moment, each output row vertically
// from the ring. Samples are shifted by -offsets[c] before squaring so that sigma^2 = E[x^2] - mean^2
// loses little to float32 cancellation; the offset is added back to the means. Borders reflect (scipy's
// 'reflect' mode, as scikit-image uses).
struct SsimTile {
    const float* reference = nullptr;  // (H, W, C) interleaved
    const float* test = nullptr;       // (H, W, C) interleaved
    int width = 0, height = 0, channels = 1;
    const float* offsets = nullptr;  // (C)
    float c1 = 0.0f, c2 = 0.0f;
    const float* weights = nullptr;  // (kSsimTaps) normalised
    int rowBegin = 0, rowEnd = 0, columnBegin = 0, columnEnd = 0;
    float* maps = nullptr;      // (C, H, W) per-pixel SSIM, or nullptr
    double* rowSums = nullptr;  // (C, H): SSIM summed over this tile's columns inside [radius, W - radius)
    float* scratch = nullptr;   // ssimScratchFloats(channels, columnEnd - columnBegin)
};

inline size_t ssimScratchFloats(int channels, int tileWidth) {
    const size_t padded = size_t(tileWidth + 2 * kSsimRadius);
    return size_t(channels) * 5 * padded + size_t(channels) * 5 * kSsimTaps * tileWidth +
           6 * size_t(tileWidth);
}

DEJAG_SIMD_DECLARE(
    void ssimTile(const SsimTile& tile);
    // Sums over n samples: (test - reference)^2 into *squaredError, reference^2 into *referenceEnergy.
    void sumSquaredError(const float* reference, const float* test, int64_t n, double* squaredError,
                         double* referenceEnergy);)

}  // namespace dejag

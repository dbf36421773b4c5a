// dejag/infer: FXAA's kernels, compiled once per SIMD level (infer/fxaa.cpp dispatches): the luma plane,
// the contrast test of a row, and the edge search and resolve for a list of pixels, kFloatLanes of them
// at a time (the search's bilinear luma reads are gathers).
#pragma once

#include <cstddef>
#include <cstdint>

#include "base/simd.h"

namespace dejag::infer {

// The luma plane keeps kFxaaLumaPad floats left and right of each row; the pixels next to the row's ends
// repeat its border pixels (clamp-to-edge for the 4-neighbourhood).
inline constexpr int kFxaaLumaPad = 16;
inline size_t fxaaLumaStride(int width) {
    return (size_t(width) + 2 * kFxaaLumaPad + 15) / 16 * 16;
}

struct FxaaKernelArgs {
    const float* frame = nullptr;  // (height, width, channels) interleaved, R G B first
    int width = 0, height = 0, channels = 3;
    float* luma = nullptr;  // pixel (x, y) at y * lumaStride + kFxaaLumaPad + x; 64 floats more after
                            // the last row (windowed reads of 32 floats may start at its last pixel)
    size_t lumaStride = 0;
    bool greenAsLuma = false;
    float edgeThreshold = 0, edgeThresholdMin = 0, subpix = 0;
    const float* steps = nullptr;  // the preset's search steps
    int stepCount = 0;
};

DEJAG_SIMD_DECLARE(
    // Luma of row y into dst (pixel 0 of a padded row), pads included.
    void fxaaLumaRow(const FxaaKernelArgs& args, int y, float* dst);
    // The pixels of the row `mid` whose 4-neighbourhood luma range reaches the threshold: their x into
    // xs (room for width entries); returns how many.
    int fxaaEdgesInRow(const FxaaKernelArgs& args, const float* up, const float* mid, const float* down,
                       int32_t* xs);
    // FXAA for the pixels (xs[i], ys[i]), i < count: their new R G B into rgb[3 i ..].
    void fxaaResolve(const FxaaKernelArgs& args, const int32_t* xs, const int32_t* ys, int count,
                     float* rgb);)

}  // namespace dejag::infer

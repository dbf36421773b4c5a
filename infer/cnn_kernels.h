// dejag/infer: the CNN filter's frame rows in and out of the network's planes, compiled once per SIMD
// level (infer/cnn.cpp dispatches). Three-channel frames take the vector path (infer/pixel_simd.h's
// loadRgb / storeRgb); frames with more channels (alpha) go pixel by pixel.
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace dejag::infer {

DEJAG_SIMD_DECLARE(
    // `count` pixels of an interleaved row (`channels` floats per pixel, R G B first) into planes.
    void splitRgbRow(const float* pixels, int channels, int64_t count, float* r, float* g, float* b);
    // `count` pixels of planes, each value clamped to [0, 1], into R G B of an interleaved row; the
    // pixels' other channels are left as they are.
    void joinRgbRowClamped(const float* r, const float* g, const float* b, int64_t count, int channels,
                           float* pixels);
    // R G B of `count` interleaved pixels (`channels` floats each), each value clamped to [0, 1], into
    // the same places of `out` (as joinRgbRowClamped() of the split row writes them); the pixels' other
    // channels are left as they are.
    void clampRgbRow(const float* pixels, int channels, int64_t count, float* out);
    // The gate's test of one row (infer/cnn.h): whether a pixel x in [first, last] has a luma
    // (0.21 R + 0.72 G + 0.07 B) step above `threshold` to its right neighbour or to the pixel below
    // (`below`: the next row, or the row itself on the last one; past the row's end the pixel itself).
    bool rowHasLumaStep(const float* row, const float* below, int channels, int64_t width, int64_t first,
                        int64_t last, float threshold);)

}  // namespace dejag::infer

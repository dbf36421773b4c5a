// dejag/nn: a frame's rows in and out of a network's planes (nn/frame_network.h), compiled once per
// SIMD level. Three-channel frames take the vector path (base/pixel_simd.h's loadRgb / storeRgb); frames
// with more channels (alpha) go pixel by pixel.
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace dejag::nn {

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
    void clampRgbRow(const float* pixels, int channels, int64_t count, float* out);)

}  // namespace dejag::nn

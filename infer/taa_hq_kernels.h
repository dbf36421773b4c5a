// dejag/infer: taa-hq's band kernel (docs/taa-hq.md), compiled once per SIMD level (infer/taa_hq.cpp
// dispatches).
//
// One call filters the rows [y0, y1) in a single pass: the rows it needs (the current frame shifted to the
// in-pixel sample and decoded to linear light, its YCoCg, depth, motion, whether each pixel moved, and the
// output before the sharpen) are made on demand into rings of padded planar rows, so every input is read
// from memory once. Rows just outside the band are recomputed the same way, so the result does not depend
// on how the frame is split or on the thread count.
#pragma once

#include <cstddef>

#include "base/simd.h"

namespace dejag::infer {

struct TaaHqBandInputs {
    int width = 0, height = 0;
    // The frame: sRGB-encoded RGB (interleaved), motion (2 channels, pixels moved since the previous
    // frame), depth and previous depth (1 channel, both or neither).
    const float *colour = nullptr, *motion = nullptr, *depth = nullptr, *previousDepth = nullptr;
    // History planes R, G, B (linear light) and the signed accumulated weight (negative: something moved
    // in the pixel's 3x3 when it was written), at +0, +planeFloats, ...; rows `stride` floats apart. Both
    // buffers hold kTaaHqHistoryTail floats after the last plane (windowed reads may run that far).
    const float* history = nullptr;
    float* nextHistory = nullptr;
    size_t stride = 0, planeFloats = 0;
    float* out = nullptr;        // interleaved sRGB RGB
    int shiftX = 0, shiftY = 0;  // the in-pixel sample of pixel p is the frame's pixel p + shift
    bool fresh = false, catmullRom = true, staticLock = true;
    float clipGamma = 1.25f, maxWeight = 32, clippedWeight = 4, depthTolerance = 0.05f, sharpen = 0;
    float movingMaxWeight = 32;  // the cap where something moved in the pixel's 3x3
};

inline constexpr int kTaaHqHistoryTail = 64;
inline constexpr int kTaaHqRowPad = 16;
inline size_t taaHqRowFloats(int width) {
    return (size_t(width) + 2 * kTaaHqRowPad + 15) / 16 * 16;
}
// Rings of 8 rows: linear RGB 3 planes, YCoCg 3, depth 3 (and its 3-pixel min and max), motion 4 (x, y,
// moved, moved within 3 pixels), the output 3.
inline constexpr int kTaaHqRingRows = 8;
inline constexpr int kTaaHqScratchPlanes = 3 + 3 + 3 + 4 + 3;
inline size_t taaHqScratchFloats(int width) {
    return size_t(kTaaHqRingRows) * kTaaHqScratchPlanes * taaHqRowFloats(width);
}

// sRGB decoding and encoding as the kernel computes them (piecewise cubics, within 3e-6 of the formulas),
// exposed for tests: n values, on the active SIMD level.
DEJAG_SIMD_DECLARE(void taaHqBand(const TaaHqBandInputs& in, int y0, int y1, float* scratch);
                   void srgbToLinearRow(const float* in, float* out, int n);
                   void linearToSrgbRow(const float* in, float* out, int n);)

}  // namespace dejag::infer

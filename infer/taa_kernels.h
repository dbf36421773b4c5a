// dejag/infer: the TAA band kernel, compiled once per SIMD level (infer/taa.cpp dispatches).
//
// One call filters the rows [y0, y1) of a frame in a single pass over the inputs: the rows it needs
// (colour planes, depth, motion, IDs, the Sobel stages, the blended rows) are made on demand into small
// rings of padded planar rows, so every input is read once from memory and the 3x3 neighbourhoods, the
// Sobel's own TAA and the final sharpen are read from cache. Rows just outside the band are recomputed
// (bit-identical to the neighbouring band's), so bands are independent and results do not depend on how
// the frame is split or on the thread count.
#pragma once

#include <cstddef>

#include "base/simd.h"

namespace dejag::infer {

struct TaaBandInputs {
    int width = 0, height = 0;
    // The frame, interleaved like TaaFrame (colour and albedo 3 channels, motion 2, the rest 1).
    const float *colour = nullptr, *albedo = nullptr, *depth = nullptr, *motion = nullptr, *ids = nullptr,
                *previousDepth = nullptr;
    // History planes (R, G, B at +0, +planeFloats, +2 planeFloats; rows `stride` floats apart): read
    // from `history`, written to `nextHistory`. T-TAA's stabilised Sobel: one plane each way.
    // Both buffers hold 32 floats more after their last plane (windowed reads may run that far).
    const float* history = nullptr;
    float* nextHistory = nullptr;
    const float* sobelHistory = nullptr;
    float* nextSobelHistory = nullptr;
    size_t stride = 0, planeFloats = 0;
    float* out = nullptr;  // interleaved RGB, sharpened and clamped to [0, 1]
    bool improved = false, sharpen = true, fresh = false;
    // Read the colour (and T-TAA's albedo) bilinearly at p + (jitterX, jitterY), edges clamped: the
    // thesis' un-jittering, made row by row as the rings need the rows.
    bool unjitter = false;
    float jitterX = 0, jitterY = 0;
    float feedbackMin = 0, feedbackMax = 0, depthThreshold = 0;
};

// Padding each side of a scratch row, and the floats of one band's scratch (any SIMD level).
inline constexpr int kTaaRowPad = 16;
inline size_t taaRowFloats(int width) {
    return (size_t(width) + 2 * kTaaRowPad + 15) / 16 * 16;
}
// Rings: colour 3 planes, depth, motion 2 planes, albedo luma, colour luma, Sobel, stable Sobel, IDs,
// blended 3 planes; 8 rows each.
inline constexpr int kTaaRingRows = 8;
inline constexpr int kTaaScratchPlanes = 3 + 1 + 2 + 1 + 1 + 1 + 1 + 1 + 3;
// (and one interleaved RGB row: the un-jittered frame's row before it is split into planes)
inline size_t taaScratchFloats(int width) {
    return size_t(kTaaRingRows) * kTaaScratchPlanes * taaRowFloats(width) + 3 * taaRowFloats(width);
}

// The optional motion blur of TAA's output (infer/taa.h, TaaOptions::motionBlur): rows [y0, y1) of out
// from source (the unblurred output, interleaved RGB) and the motion (2 channels, pixels).
struct TaaBlurInputs {
    int width = 0, height = 0;
    const float* source = nullptr;
    const float* motion = nullptr;
    float* out = nullptr;
    float scale = 1.0f;
    int maxSamples = 32;
};

DEJAG_SIMD_DECLARE(void taaBand(const TaaBandInputs& in, int y0, int y1, float* scratch);
                   void taaMotionBlurRows(const TaaBlurInputs& in, int y0, int y1);)

}  // namespace dejag::infer

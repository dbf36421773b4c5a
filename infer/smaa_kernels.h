// dejag/infer: SMAA's per-row kernels, compiled once per SIMD level (infer/smaa.cpp dispatches): the luma
// of a row, the edges of a row (luma or colour, with or without predication) and the blending of a row.
#pragma once

#include <cstddef>
#include <cstdint>

#include "base/simd.h"

namespace dejag::infer {

// The luma plane keeps kSmaaLumaPad pixels left and right of each row, copies of the border pixels.
inline constexpr int kSmaaLumaPad = 2;

struct SmaaKernelArgs {
    const float* frame = nullptr;  // (height, width, channels) interleaved, R G B first, sRGB-encoded
    float* out = nullptr;          // the same layout
    int width = 0, height = 0, channels = 3;
    const float* depth = nullptr;  // (height, width), for predication, else null
    float threshold = 0.1f;
    float predicationThreshold = 0, predicationScale = 1, predicationStrength = 0;
    bool colourEdges = false;
    float* luma = nullptr;  // pixel (x, y) at y * lumaStride + kSmaaLumaPad + x
    size_t lumaStride = 0;
    uint8_t* edges = nullptr;  // pixel (x, y) at (y + edgePad) * edgeStride + edgePad + x; zero outside
    size_t edgeStride = 0;
    int edgePad = 0;
    const float* weights = nullptr;  // 4 per pixel (x, y) at 4 (y width + x), valid where it has an edge
    bool linear = true;
};

DEJAG_SIMD_DECLARE(
    // Luma (0.2126 R + 0.7152 G + 0.0722 B of the encoded values) of row y into its padded plane row.
    void smaaLumaRow(const SmaaKernelArgs& args, int y);
    // The edges of row y (bit 0: left boundary, bit 1: top); returns how many of its pixels have one.
    int smaaEdgeRow(const SmaaKernelArgs& args, int y);
    // The blended row y into args.out (every channel of every pixel written).
    void smaaBlendRow(const SmaaKernelArgs& args, int y);)

}  // namespace dejag::infer

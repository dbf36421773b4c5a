// dejag/nn: the blocked activation layout of the fast kernels.
//
// (N, C, H, W) activations are stored as (N, ceil(C / B), H + 2P, W + 2P, B): channels in blocks of
// B = the SIMD width (16 for AVX-512, 8 for AVX2, 1 scalar), so one vector holds one pixel's B
// channels, and a zero border of P pixels, so a k x k convolution with k <= 2P + 1 reads its padding
// without a branch. Channels beyond C in the last block are zero. This is the layout oneDNN calls
// nChw16c (nChw8c for AVX2); the border is dejag's addition (Open Image Denoise pads the same way).
#pragma once

#include <bit>
#include <cstdint>

#include "nn/tensor.h"

namespace dejag::nn {

struct BlockedShape {
    int64_t batch = 1, channels = 1, height = 1, width = 1;
    int block = 16;  // channels per block
    int border = 1;  // zero pixels around each plane

    int64_t channelBlocks() const { return (channels + block - 1) / block; }
    int64_t paddedHeight() const { return height + 2 * border; }
    int64_t paddedWidth() const { return width + 2 * border; }
    int64_t rowStride() const { return paddedWidth() * block; }           // floats per padded row
    int64_t planeStride() const { return paddedHeight() * rowStride(); }  // floats per channel block
    int64_t imageStride() const { return channelBlocks() * planeStride(); }
    int64_t floatCount() const { return batch * imageStride(); }
    // Offset of pixel (y, x) of channel block cb of image n (y, x may be in [-border, size + border)).
    int64_t offset(int64_t n, int64_t cb, int64_t y, int64_t x) const {
        return n * imageStride() + cb * planeStride() + (y + border) * rowStride() + (x + border) * block;
    }
};

// bfloat16: the upper half of a float's bits. Rounded to nearest even (as vcvtneps2bf16); NaN stays NaN.
inline uint16_t toBf16(float value) {
    const uint32_t bits = std::bit_cast<uint32_t>(value);
    if ((bits & 0x7fffffffu) > 0x7f800000u) return uint16_t((bits >> 16) | 0x40u);
    return uint16_t((bits + 0x7fffu + ((bits >> 16) & 1u)) >> 16);
}
inline float fromBf16(uint16_t value) {
    return std::bit_cast<float>(uint32_t(value) << 16);
}

// A zeroed tensor holding a blocked activation.
Tensor allocateBlocked(const BlockedShape& shape);
// (N, C, H, W) -> blocked (border and unused channels stay zero) and back.
void toBlocked(float* blocked, const float* plain, const BlockedShape& shape);
void fromBlocked(float* plain, const float* blocked, const BlockedShape& shape);

// The inference plan's slice and warp (nn/layers.h) on blocked activations (any block sizes; the
// channels past the count stay zero). Rows split across the thread pool.
void blockedSlice(float* out, const BlockedShape& os, const float* in, const BlockedShape& is, int from);
enum class WarpFilter;
void blockedWarp(float* out, const BlockedShape& os, const float* image, const BlockedShape& is,
                 const float* motion, const BlockedShape& ms, WarpFilter filter);

}  // namespace dejag::nn

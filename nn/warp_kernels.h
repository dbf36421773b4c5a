// dejag/nn (internal): the inference warp of up to 4 channels stored 4 floats a pixel (warpInterleaved,
// nn/layers.h), a band of output rows at a time, compiled once per SIMD level. Where all of a pixel's taps
// lie inside the image, a row of taps is one contiguous load of 4 (cubic) or 2 (bilinear) pixels and the
// pixel costs one multiply-add per tap row; at the borders the taps are clamped one by one.
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace dejag::nn {

struct WarpRowsArgs {
    float* const* out = nullptr;    // [channels] planes of width x height
    const float* image = nullptr;   // image[(y width + x) 4 + c]
    const float* motion = nullptr;  // motion[2 (y width + x) + {0, 1}]
    int64_t width = 0, height = 0;
    int channels = 4;     // 1 .. 4: the planes written
    bool planar = false;  // one channel stored as a plane (image[y width + x]); channels 1
    int taps = 4;         // 2: bilinear; 4: cubic convolution of parameter `a`
    float a = -0.5f;
    int64_t firstRow = 0, lastRow = 0;  // the output rows [firstRow, lastRow)
};

DEJAG_SIMD_DECLARE(void warpInterleavedRows(const WarpRowsArgs& args);)

}  // namespace dejag::nn

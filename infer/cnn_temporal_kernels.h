// dejag/infer: the temporal network's fused path's per-row preparation (infer/cnn_temporal.cpp), compiled
// once per SIMD level: the frame's interleaved pixels into planes, the motion and depth rows copied, the
// still gate's motion flags, each row padded to the fused path's width by repeating its last pixel.
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace dejag::infer {

struct TemporalPrepassRow {
    const float* colour = nullptr;  // the frame's row: frameWidth pixels of `channels` floats
    int channels = 3;
    int64_t frameWidth = 0, width = 0;  // the frame's, and the padded planes' (width >= frameWidth)
    float* planes[3] = {nullptr, nullptr, nullptr};  // R, G, B rows of `width` floats
    const float* motion = nullptr;                   // frameWidth pairs
    float* motionOut = nullptr;                      // width pairs (null: not copied)
    uint8_t* moving = nullptr;  // width flags (null: none): 1 where |motion| > stillMotion in an axis or NaN
    float stillMotion = 0.0f;
    // Depth rows (frameWidth floats; null: zeros) copied to depthOut and previousDepthOut (null: none).
    const float* depth = nullptr;
    const float* previousDepth = nullptr;
    float* depthOut = nullptr;
    float* previousDepthOut = nullptr;
};

DEJAG_SIMD_DECLARE(void temporalPrepassRow(const TemporalPrepassRow& row);)

}  // namespace dejag::infer

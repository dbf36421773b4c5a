// dejag/nn (internal): one output row of a pixel shuffle in the blocked layout (nn/blocked.h) by SIMD
// permutes, compiled once per SIMD level: each output pixel's lanes are one permute of the two source
// blocks its column phase reads, zeros past the shuffle's channels, stored under a lane mask (the lanes
// before `from` belong to another tensor of a concatenation in place and are left alone).
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace dejag::nn {

struct ShuffleRowArgs {
    // Source row: lane l of block b of source pixel s at source + b * blockStride + s * lanes + l
    // (elements); output pixel x's lanes at out + x * lanes. lanes = the level's float lanes.
    const void* source = nullptr;
    int64_t blockStride = 0;
    void* out = nullptr;
    int64_t width = 0;        // output pixels
    int factor = 2;           // output pixel x reads source pixel x / factor in column phase x % factor
    bool bf16 = false;        // elements are bf16 (uint16_t) on both sides, else float
    int from = 0, valid = 0;  // lanes [from, valid) are the shuffle's, [valid, lanes) zero
    // Per column phase: the two source blocks read, and each output lane's source lane in them (lanes of
    // the first block 0 .. lanes - 1, of the second lanes .. 2 lanes - 1).
    int64_t firstBlock[16] = {}, secondBlock[16] = {};
    int32_t lane[16][16] = {};
};

// Whether this level has the vector path for args (AVX-512: float and bf16; AVX2: float); if not, the
// caller shuffles element by element.
DEJAG_SIMD_DECLARE(bool shuffleRow(const ShuffleRowArgs& args);)

}  // namespace dejag::nn

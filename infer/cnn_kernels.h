// dejag/infer: the CNN filter's gate test of a row, compiled once per SIMD level (infer/cnn.cpp
// dispatches). Three-channel frames take the vector path; frames with more channels go pixel by pixel.
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace dejag::infer {

DEJAG_SIMD_DECLARE(
    // The gate's test of one row (infer/cnn.h): whether a pixel x in [first, last] has a luma
    // (0.21 R + 0.72 G + 0.07 B) step above `threshold` to its right neighbour or to the pixel below
    // (`below`: the next row, or the row itself on the last one; past the row's end the pixel itself).
    bool rowHasLumaStep(const float* row, const float* below, int channels, int64_t width, int64_t first,
                        int64_t last, float threshold);)

}  // namespace dejag::infer

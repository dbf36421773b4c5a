// dejag/nn (internal): the kernel filter of a kernel-predicting network's output (nn/layers.h), one row
// at a time, one copy per SIMD level. The inference plan feeds it planar rows.
#pragma once

#include <cstdint>

#include "base/simd.h"

namespace dejag::nn {

struct KernelFilterRowArgs {
    float* const* out = nullptr;  // [C] output rows of `width` floats
    const float* const* in =
        nullptr;                    // [C * kernel]: row y + dy (clamped) of channel c at c * kernel + dy + r
    const float* logits = nullptr;  // [kernel^2][width]: the row's logits, tap-major
    int64_t width = 0;
    int channels = 0, kernel = 3;
    float centreBias = 0.0f;
};

DEJAG_SIMD_DECLARE(void kernelFilterRow(const KernelFilterRowArgs& args);)

}  // namespace dejag::nn

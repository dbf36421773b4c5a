// dejag/nn (internal): the SIMD micro-kernels behind nn/fast_conv.h, one copy per SIMD level.
#pragma once

#include <cstdint>

#include "base/simd.h"
#include "nn/blocked.h"
#include "nn/layers.h"

namespace dejag::nn {

struct ConvRowsArgs {
    const float* in = nullptr;  // blocked input (border >= kernel / 2)
    BlockedShape inShape;
    float* out = nullptr;  // blocked output
    BlockedShape outShape;
    const float* weights = nullptr;  // [Cout blocks][Cin blocks][k][k][B ci][B co]
    const float* bias = nullptr;     // [Cout blocks * B]
    int kernel = 3;
    ActivationDesc activation;  // None, ReLU, LeakyReLU or Clamp (fused into the store)
    int64_t image = 0;
    int64_t outBlockBegin = 0, outBlockEnd = 0;  // output channel blocks of this work item
    int64_t rowBegin = 0, rowEnd = 0;            // output rows of this work item
};

DEJAG_SIMD_DECLARE(void convForwardRows(const ConvRowsArgs& args);)

}  // namespace dejag::nn

// dejag/nn (internal): the SIMD micro-kernels behind nn/fast_conv.h, one copy per SIMD level.
#pragma once

#include <cstdint>

#include "base/simd.h"
#include "nn/blocked.h"
#include "nn/layers.h"

namespace dejag::nn {

// One pass of a direct convolution over a lattice of output pixels: output (outY0 + r * outStepY,
// outX0 + j * outStepX) reads input pixels (inY0 + r * inStepY, inX0 + j * inStepX) + each tap's
// offset. A stride-s Conv2D is one pass (in steps s, out steps 1); a stride-s ConvTranspose2D is s^2
// passes, one per output parity class, each with the kernel taps that reach that class.
struct ConvPass {
    int64_t rows = 0, columns = 0;  // lattice size
    int64_t outY0 = 0, outStepY = 1, outX0 = 0, outStepX = 1;
    int64_t inY0 = 0, inStepY = 1, inX0 = 0, inStepX = 1;
    int taps = 0;
    const int64_t* tapOffsets = nullptr;  // float offset of each tap's input pixel from the base pixel
    const float* weights = nullptr;       // [Cout blocks][Cin blocks][taps][Bi ci][B co], Bi = input block
    // For layers with at most narrowMaxOutputChannels() outputs and a blocked input (null otherwise):
    // [Cin blocks][taps][Cout][B ci], read by the kernel that puts input channels in the lanes.
    const float* narrowWeights = nullptr;
    // For a bf16 input (inference on AVX-512 BF16): the weights rounded to bf16 in input-channel pairs,
    // [Cout blocks][Cin blocks][taps][B / 2 pairs][B co][2], read by vdpbf16ps (null otherwise).
    const uint16_t* pairWeights = nullptr;
};

// Above this many bytes as stored, a layer's output is streamed past the caches by default
// (BlockedConv::setStreamedOutputBytes tells why).
inline constexpr int64_t kDefaultStreamedOutputBytes = int64_t(32) << 20;

struct ConvRowsArgs {
    const float* in = nullptr;  // blocked input; every tap of the lattice lies inside its border
    BlockedShape inShape;
    float* out = nullptr;  // blocked output
    BlockedShape outShape;
    ConvPass pass;
    const float* bias = nullptr;  // [Cout blocks * B]
    ActivationDesc activation;    // None, ReLU, LeakyReLU or Clamp (fused into the store)
    int64_t image = 0;
    int64_t outBlockBegin = 0, outBlockEnd = 0;  // output channel blocks of this work item
    int64_t rowBegin = 0, rowEnd = 0;            // lattice rows of this work item (pooled rows if pool2x2)
    // Fused 2x2 max pooling (stride 2) of a stride-1 pass: the output holds the pooled lattice.
    bool pool2x2 = false;
    // bf16 activations (AVX-512 BF16 only, bf16Available()): `in` and/or `out` then point to uint16_t
    // elements in the same blocked layout (offsets count elements). A bf16 input needs pass.pairWeights
    // and a blocked (block B) input; a bf16 output is rounded to nearest even after the activation.
    bool inBf16 = false, outBf16 = false;
    // Columns to compute (null: all): lattice row r needs columns [g * keepGroup, (g + 1) * keepGroup)
    // where keep[r * keepRowStride + g] is non-zero; the wide kernel skips the others (their outputs are
    // left as they were), other kernels compute everything.
    const uint8_t* keep = nullptr;
    int64_t keepRowStride = 0, keepGroup = 0;
    // Outputs of more bytes than this (as stored: bf16 or float) are streamed past the caches.
    int64_t streamBytes = kDefaultStreamedOutputBytes;
};

// Weight gradient of one (pass, tap, output block, input block): for every image and lattice point,
// dw[ci][co] += in[base + tap][ci] * dout[out][co], a B x B block (B accumulators of one vector each).
struct WeightGradArgs {
    const float* in = nullptr;  // blocked forward input
    BlockedShape inShape;
    const float* dout = nullptr;  // blocked gradient of the forward output (before its activation)
    BlockedShape outShape;
    ConvPass pass;
    int tap = 0;
    int64_t outBlock = 0, inBlock = 0;
    float* dw = nullptr;  // [Bi ci][B co], overwritten (Bi: the input's block size)
};

DEJAG_SIMD_DECLARE(void convForwardRows(const ConvRowsArgs& args);
                   void convWeightGradient(const WeightGradArgs& args);
                   // The most output channels the narrow kernel takes (0: none, on the scalar path).
                   int narrowMaxOutputChannels();)

}  // namespace dejag::nn

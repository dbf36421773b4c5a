// dejag/nn: the fast convolution kernels (issue "nn: fast CPU kernels"), on the blocked layout of
// nn/blocked.h. They are tested against the reference kernels of nn/layers.h on every SIMD path.
//
// Design, measured against oneDNN in `dejag bench nn`: a register-blocked direct convolution. One
// micro-kernel computes a tile of TW output pixels x B output channels (TW accumulators of one vector
// each); for every input channel and kernel tap it loads one vector of B weights and multiplies it
// with TW broadcast input values. Every weight vector is reused TW times and every input value B times,
// so the loop is FMA-bound rather than load-bound, with no im2col copy and no packing of activations.
#pragma once

#include <vector>

#include "nn/blocked.h"
#include "nn/layers.h"

namespace dejag::nn {

// A Conv2D (stride 1, odd square kernel, 'same' padding) ready to run: weights packed once as
// [Cout blocks][Cin blocks][ky][kx][ci in block][co in block], bias padded to whole blocks.
class FastConv2d {
  public:
    // Throws dejag::Error if the descriptor is not one the fast path supports (see supports()).
    FastConv2d(const Conv2dDesc& desc, const float* weight, const float* bias, Activation activation);
    static bool supports(const Conv2dDesc& desc);

    // Shapes of the blocked input and output this convolution reads and writes. The input's border
    // must be at least kernel / 2; the output's border is `outputBorder` (for the next layer).
    BlockedShape inputShape(int border) const;
    BlockedShape outputShape(int border) const;
    // in: blocked (N, Cin, H, W) with border >= k / 2; out: blocked (N, Cout, H, W), border untouched.
    void forward(float* out, const BlockedShape& outShape, const float* in,
                 const BlockedShape& inShape) const;

    int block() const { return block_; }
    const Conv2dDesc& desc() const { return desc_; }

  private:
    Conv2dDesc desc_;
    Activation activation_;
    int block_;
    std::vector<float, std::allocator<float>> packedWeights_, paddedBias_;
};

}  // namespace dejag::nn

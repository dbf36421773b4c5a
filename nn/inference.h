// dejag/nn: a model compiled for fast inference at one input size.
//
// The plan packs every convolution's weights for the fast kernels (nn/fast_conv.h), keeps every
// activation in the blocked layout, and places all of them in one arena whose regions are reused once a
// tensor's last consumer has run (Open Image Denoise plans its activations the same way). After
// construction, run() allocates nothing: no allocation per frame. Build a new plan for another input
// size, another SIMD level, or after the weights change.
#pragma once

#include <memory>

#include "nn/model.h"
#include "nn/tensor.h"

namespace dejag::nn {

class InferencePlan {
  public:
    // inputShape: (N, Cin, H, W). Throws dejag::Error if the model cannot take it.
    InferencePlan(const Model& model, const Shape& inputShape);
    InferencePlan(InferencePlan&&) noexcept;
    InferencePlan& operator=(InferencePlan&&) noexcept;
    ~InferencePlan();

    // input must have the plan's shape and be finite; the result lives until the next run().
    const Tensor& run(const Tensor& input);
    // As run(), without the finiteness check (the caller has checked).
    const Tensor& runUnchecked(const Tensor& input);

    const Shape& inputShape() const;
    const Shape& outputShape() const;
    size_t arenaBytes() const;     // all activations together
    size_t unpackedBytes() const;  // what one buffer per activation would need
    int64_t macs() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace dejag::nn

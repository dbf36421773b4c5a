// The scalar reference TAA (tests/infer/taa_reference.cpp): the oracle the SIMD kernels are checked against.
#pragma once

#include <vector>

#include "infer/taa.h"

namespace dejag::infer::reference {

class ReferenceTaa {
  public:
    explicit ReferenceTaa(const TaaOptions& options = {});
    // Filters one frame into out (3 channels, sRGB-encoded) and keeps its history. The first frame, a
    // size change or reset() starts a new history. Multithreaded, independent of the thread count.
    void apply(const TaaFrame& frame, float* out);
    void reset() { width_ = height_ = 0; }

  private:
    TaaOptions options_;
    int width_ = 0, height_ = 0;
    std::vector<float> history_;                           // 3 channels, unsharpened
    std::vector<float> sobel_, sobelHistory_, nextSobel_;  // 1 channel (T-TAA)
    std::vector<float> blended_;                           // this frame before the sharpen
    std::vector<float> albedoLuma_, colourLuma_;           // T-TAA's Sobel inputs
};

}  // namespace dejag::infer::reference

// The scalar reference taa-hq (tests/infer/taa_hq_reference.cpp): the oracle infer/taa_hq_kernels.cpp's
// SIMD band kernel is checked against, written straight from docs/taa-hq.md one pixel at a time.
#pragma once

#include <cstdint>
#include <vector>

#include "infer/taa_hq.h"

namespace dejag::infer::reference {

class ReferenceTaaHq {
  public:
    explicit ReferenceTaaHq(const TaaHqOptions& options = {}) : options_(options) {}
    // As TaaHq::apply (infer/taa_hq.h), with the sRGB formulas of data/image.h.
    void apply(int width, int height, const float* colour, const float* motion, const float* depth,
               const float* previousDepth, float jitterX, float jitterY, float* out);

  private:
    TaaHqOptions options_;
    int width_ = 0, height_ = 0, frame_ = 0;
    std::vector<float> history_, nextHistory_;  // linear RGB + accumulated weight per pixel
    std::vector<uint8_t> moved_, nextMoved_;    // per pixel: something moved in its 3x3
};

}  // namespace dejag::infer::reference

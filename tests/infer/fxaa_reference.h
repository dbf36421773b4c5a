// The scalar reference FXAA (tests/infer/fxaa_reference.cpp): the oracle the SIMD kernels are checked
// against.
#pragma once

#include <cstdint>
#include <vector>

#include "infer/fxaa.h"

namespace dejag::infer::reference {

class ReferenceFxaa {
  public:
    // Throws dejag::Error for an unknown preset or thresholds outside [0, 1].
    explicit ReferenceFxaa(const FxaaOptions& options = {});

    // frame: (height, width, channels) interleaved, channels >= 3, the first three R G B in [0, 1]
    // (sRGB-encoded); other channels are left alone. Filters in place: every pixel reads the original
    // frame (changes are collected per band and written once all bands are done), so the result equals
    // the out-of-place one and does not depend on the thread count. Allocates only when the frame or its
    // number of edge pixels grows.
    void applyInPlace(float* frame, int width, int height, int channels);
    // Out of place: copies in to out, then filters out.
    void apply(const float* in, float* out, int width, int height, int channels);

    const FxaaOptions& options() const { return options_; }
    // Fraction of pixels of the last apply() that passed the contrast test (were processed).
    double processedFraction() const { return processedFraction_; }

  private:
    FxaaOptions options_;
    struct Change {
        int64_t offset;  // of the pixel's first float
        float rgb[3];
    };
    struct Band {
        std::vector<Change> changes;
        std::vector<uint8_t> edge;
        int64_t processed = 0;
    };
    std::vector<float> steps_;  // the preset's search steps, P0..P(n-1)
    std::vector<Band> bands_;
    std::vector<float> luma_;  // luma plane of the frame (+1 float of margin each side)
    double processedFraction_ = 0;
};

}  // namespace dejag::infer::reference

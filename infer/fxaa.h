// dejag/infer: FXAA 3.11 (Timothy Lottes, NVIDIA, 2011), the "quality" PC algorithm, on the CPU.
//
// A pixel whose 4-neighbourhood luma range is below max(edgeThresholdMin, edgeThreshold * local max)
// is left alone. Otherwise FXAA picks the edge direction from the 3x3 luma, searches along the edge in
// both directions (steps of the preset's table) for where it ends, and moves its sample across the edge
// by the fraction of the span it lies at (plus a sub-pixel term), then reads the colour there bilinearly.
// The image is display-referred (sRGB-encoded) colour, as FXAA expects.
#pragma once

#include <cstdint>
#include <vector>

#include "infer/filter.h"

namespace dejag::infer {

struct FxaaOptions {
    int preset = 39;                   // 12, 23 or 39 (the highest quality)
    float subpix = 0.75f;              // amount of sub-pixel aliasing removal
    float edgeThreshold = 0.166f;      // minimum local contrast, relative to the local maximum
    float edgeThresholdMin = 0.0833f;  // ... and absolute (skips dark areas)
    bool greenAsLuma = false;          // luma = green instead of 0.299 R + 0.587 G + 0.114 B
};

class Fxaa {
  public:
    // Throws dejag::Error for an unknown preset or thresholds outside [0, 1].
    explicit Fxaa(const FxaaOptions& options = {});

    // frame: (height, width, channels) interleaved, channels >= 3, the first three R G B in [0, 1]
    // (sRGB-encoded); other channels are left alone. Filters in place: every pixel reads the original
    // frame (changes are collected per band and written once all bands are done), so the result equals
    // the out-of-place one and does not depend on the thread count. SIMD across pixels (the contrast test
    // along rows, the edge search over the list of pixels that passed it). Allocates only when the frame
    // or its number of edge pixels grows.
    void applyInPlace(float* frame, int width, int height, int channels);
    // Out of place: copies in to out, then filters out.
    void apply(const float* in, float* out, int width, int height, int channels);

    const FxaaOptions& options() const { return options_; }
    // Fraction of pixels of the last apply() that passed the contrast test (were processed).
    double processedFraction() const { return processedFraction_; }

  private:
    FxaaOptions options_;
    struct Band {  // the pixels of a band of rows that passed the contrast test, and their new colours
        std::vector<int32_t> xs, ys;
        std::vector<float> rgb;
        std::vector<float> spare;  // the luma rows just above and below the band
        int count = 0;
    };
    std::vector<float> steps_;  // the preset's search steps, P0..P(n-1)
    std::vector<Band> bands_;
    std::vector<float> luma_;  // luma plane, padded rows (infer/fxaa_kernels.h)
    double processedFraction_ = 0;
};

// The search steps P0..P(n-1) of FXAA 3.11's quality preset 12, 23 or 39 (throws dejag::Error otherwise).
std::vector<float> fxaaPresetSteps(int preset);

// The method "fxaa" of infer/filter.h: parameters preset, green-luma, subpix, edge-threshold,
// edge-threshold-min (FxaaOptions); no buffers.
MethodSpec fxaaMethod();
// The options the method's parameters give (shared with its GPU form, infer/glsl_filter.h).
FxaaOptions fxaaOptions(const MethodParameters& parameters);

}  // namespace dejag::infer

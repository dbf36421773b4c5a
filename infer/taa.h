// dejag/infer: temporal anti-aliasing as docs/taa.md describes it — U-TAA, the Uncharted 4 / INSIDE
// style baseline, and T-TAA, the Sobel-improved variant (Sobel of albedo, lit luma and depth stabilised
// by its own 1-channel TAA, object-ID and depth pseudo-variance terms that shrink the colour box to the
// current colour where a pixel is not aliased, and a normalised sharpen).
//
// Colour is display-referred (sRGB-encoded, [0, 1]) like the thesis' render targets; the history is
// float. Depth is linear depth divided by the far plane ([0, 1]); the thesis' depth threshold 0.002 is
// in those units (its code used n = 1, f = 10000 with the same normalisation).
#pragma once

#include <cstddef>
#include <cstdint>
#include <vector>

#include "infer/filter.h"

namespace dejag::infer {

struct TaaOptions {
    bool improved = false;          // false: U-TAA, true: T-TAA
    float feedbackMin = 0.925f;     // history weight where current and history lumas differ
    float feedbackMax = 0.979f;     // ... and where they agree (docs/taa.md, from the thesis' code)
    float depthThreshold = 0.002f;  // pseudo-variances vanish below this 3x3 depth spread
    bool sharpen = true;
    // Un-jitter the current frame before it is used: colour (and albedo) read bilinearly at p + jitter,
    // where the sample of p's centre lies, as the thesis author's shaders do (docs/infer.md). Only for a
    // frame that carries its jitter (TaaFrame::hasJitter); others are used as they are.
    bool unjitter = true;
    // Step 7 of docs/taa.md, off by default: the output (not the history) blurred along each pixel's
    // motion as Chapman's per-object motion blur does, which the thesis used to hide ghosting. The motion
    // is scaled by motionBlurScale (the frame rate over the target frame rate: the shutter), a pixel
    // moving s pixels averages clamp(int(s), 1, motionBlurMaxSamples) bilinear samples spread over
    // -1/2 .. +1/2 of its scaled motion.
    bool motionBlur = false;
    float motionBlurScale = 1.0f;
    int motionBlurMaxSamples = 32;
};

// One frame's inputs, all (height, width, k) interleaved floats; improved needs every buffer.
struct TaaFrame {
    int width = 0, height = 0;
    const float* colour = nullptr;         // 3 channels, sRGB-encoded
    const float* albedo = nullptr;         // 3 channels, sRGB-encoded (T-TAA)
    const float* depth = nullptr;          // 1 channel, linear depth / far
    const float* motion = nullptr;         // 2 channels, pixels moved since the previous frame, +y down
    const float* ids = nullptr;            // 1 channel, object IDs (T-TAA)
    const float* previousDepth = nullptr;  // 1 channel, the previous frame's depth / far (T-TAA)
    bool hasJitter = false;                // the frame's jitter: the image's shift, pixels, +y down
    float jitter[2] = {0, 0};
};

class Taa {
  public:
    explicit Taa(const TaaOptions& options = {});
    // Filters one frame into out (3 channels, sRGB-encoded) and keeps its history. The first frame, a
    // size change or reset() starts a new history. One pass over the inputs per frame, in row bands on
    // the thread pool, SIMD across pixels (infer/taa_kernels.h); the result does not depend on the
    // thread count. Allocates only when the frame size or the thread count changes.
    void apply(const TaaFrame& frame, float* out);
    void reset() { width_ = height_ = 0; }

  private:
    void blurAlongMotion(const TaaFrame& frame, float* out);

    TaaOptions options_;
    int width_ = 0, height_ = 0;
    size_t stride_ = 0;                         // floats per row of the history planes
    std::vector<float> history_, nextHistory_;  // 3 planes each, unsharpened
    std::vector<float> sobel_, nextSobel_;      // T-TAA's stabilised Sobel, 1 plane each
    std::vector<float> scratch_;                // one block of rows per band
    std::vector<float> unblurred_;              // the output before the motion blur (when on)
    int bands_ = 0;
};

// The methods "taa" (U-TAA) and "taa-sobel" (T-TAA) of infer/filter.h: parameters sharpen, unjitter,
// motion-blur, motion-blur-scale, feedback-min, feedback-max, depth-threshold (TaaOptions); they need
// depth and motion, T-TAA albedo, ids and the previous depth as well, and use each frame's jitter.
MethodSpec taaMethod(bool improved);
// The options the method's parameters give (shared with its GPU form, infer/glsl_filter.h).
TaaOptions taaOptions(const MethodParameters& parameters, bool improved);

}  // namespace dejag::infer

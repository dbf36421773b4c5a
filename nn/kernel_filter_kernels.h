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
    // Pass-through (null: off): per group of kPassGroup output columns, 1 where the group is passed
    // through — each pixel its centre input, bit for bit — as kernelFlatGroups() marks them.
    const uint8_t* flatGroups = nullptr;
    // A history (null: none): [C] rows at the output's row. The logits then have kernel^2 + 1 rows, the
    // last one weighting the history's own pixel (kernel_filter with a history, nn/layers.h); with
    // flatGroups, those groups pass their centre input through (a guided kpn: the guide lies within the
    // flat neighbourhood's range). Accumulate has no pass-through.
    const float* const* history = nullptr;
    // Accumulate (null: off; needs a history, kernel 1 or 3): the row of accumulate (nn/layers.h). The
    // logits' last row is then the trust, the softmax spans the kernel^2 taps only, the history's rows
    // are in linear light, `out` gets the colour shown (sRGB-encoded), `kept` the colour kept (linear),
    // and `nextConfidence` s' from the history's `confidence`. The sRGB curves by a polynomial logarithm
    // and exponential: within 1e-6 of the reference.
    float* const* kept = nullptr;  // [C] rows
    const float* confidence = nullptr;
    float* nextConfidence = nullptr;
    float maxCount = 32.0f;
    // Accumulate's outputs as pixels (3 channels; null: as rows above). keptInterleaved: the kept mean
    // and the next confidence, 4 floats a pixel, `width` of them (kept and nextConfidence unused; either
    // it or kept selects accumulate).
    // shownInterleaved: the colour shown clamped to [0, 1], shownChannels (3 or 4) floats a pixel, the
    // first shownWidth pixels of the row; with 4, the 4th is shownPass's (4 floats a pixel). `out` unused.
    float* keptInterleaved = nullptr;
    float* shownInterleaved = nullptr;
    const float* shownPass = nullptr;
    int shownChannels = 3;
    int64_t shownWidth = 0;
    bool clip = false;  // accumulate's clip: the history clamped to the taps' range (AccumulateDesc::clip)
    // The still gate (null: off; accumulate, kernel 3, at most 4 channels): where still[x] is 1 (nothing
    // moves around the pixel), the trust logit is at least stillLogit and the history's every colour lies
    // within the taps' range widened by stillTolerance (linear), the pixel keeps its whole history: full
    // trust (rho = 1) and no clip.
    const float* still = nullptr;
    float stillLogit = 0.0f, stillTolerance = 0.0f;
};

// Output columns per pass-through group.
inline constexpr int kPassGroup = 32;

// The logits of one output row computed from the features a 1x1 convolution would have turned into
// them (the convolution and the pixel shuffle fused, so the logit tensor is never stored): the logit of
// tap j at column x is bias + weights . features at source pixel x / factor, for the row's phase.
struct KernelLogitsRowArgs {
    // The source row's features, blocked: channel c of source pixel s at
    // features + (c / block) * blockStride + s * block + c % block.
    const float* features = nullptr;
    int64_t blockStride = 0;
    int block = 1, inChannels = 0;
    const float* weights =
        nullptr;                  // [taps][factor][inChannels]: this row phase's 1x1 weights, by column phase
    const float* bias = nullptr;  // [taps][factor]
    int taps = 9, factor = 2;
    int64_t width = 0;        // output columns (factor * source columns)
    float* logits = nullptr;  // [taps][width]
    // Groups of kPassGroup output columns whose logits are not needed (null: all are); their logits are
    // left as they were.
    const uint8_t* flatGroups = nullptr;
};

DEJAG_SIMD_DECLARE(void kernelFilterRow(const KernelFilterRowArgs& args);
                   void kernelLogitsRow(const KernelLogitsRowArgs& args);
                   // Marks in flat[g] (one per group of kPassGroup output columns) the groups whose every
                   // pixel's kernel x kernel input neighbourhood (args.in, edges repeated) spans at most
                   // `span` in every channel: the filter, a convex combination of that neighbourhood, would
                   // move such a pixel by no more than span. Returns how many groups are marked.
                   int64_t kernelFlatGroups(const KernelFilterRowArgs& args, float span, uint8_t* flat);
                   // One input row's share of that test, for rows seen one at a time (a streamed frame's
                   // bands): per group g of kPassGroup output columns and channel c, the least and the
                   // greatest value of rows[c] over the group's columns widened by radius (clamped to the
                   // row), at low/high[g * channels + c], and bad[g] = 1 when one of them is a NaN or an
                   // infinity. The group is flat in a row when, over its kernel rows, no row is bad and in
                   // every channel the greatest high minus the least low is at most the span: the same
                   // floats kernelFlatGroups() compares, so the same decision.
                   void kernelRowRanges(const float* const* rows, int channels, int64_t width, int radius,
                                        float* low, float* high, uint8_t* bad);)

}  // namespace dejag::nn

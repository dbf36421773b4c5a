// dejag/infer: the CNN anti-aliasing filter — a trained network (models/*.safetensors) run over a frame
// in tiles, and only on the tiles that can hold aliasing.
//
// Tiles: the frame is cut into tiles of `tileSize` pixels; each runs with a halo of the network's
// receptive field around it (clipped at the frame's border, where the network pads as it would on the
// whole frame), so the result equals the whole-frame one to float rounding and memory stays bounded
// whatever the frame size. Tile origins are multiples of the network's total stride.
//
// Gating: a tile is processed only if aliasing can exist in it — a luma step between 4-neighbours above
// the gate threshold (the jaggies of an edge, a texture at Nyquist), or, when buffers are given, an
// object-ID change or a depth jump. Skipped tiles are copied through bit for bit. Inside a processed
// tile, a kernel-predicting network also passes through the flat runs of pixels (CnnOptions::passSpan).
//
// How the network meets the frame (colour planes or luma, padding, clamping, a grey model's change on
// R G B) is nn/frame_network.h's, the same contract training's validation and the model card use.
//
// After the first frame of a size, apply() allocates nothing: plans and tile buffers are kept.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "infer/filter.h"
#include "nn/frame_network.h"
#include "nn/inference.h"
#include "nn/model.h"

namespace dejag::infer {

struct CnnOptions {
    int tileSize = 2048;          // core tile side (rounded up to a multiple of the network's stride)
    bool gate = true;             // false: every tile runs
    float gateThreshold = 0.04f;  // luma step (sRGB-encoded, [0, 1]) that marks a tile as needing work
    // Gated, inside processed tiles, a kernel-predicting network passes through (the input, bit for bit)
    // each group of 32 pixels of a row whose 3x3 neighbourhoods span at most this in every channel: its
    // filter, a convex combination of that neighbourhood, could move them by no more (nn/inference.h,
    // InferencePlan::setPassThrough). 0 turns it off.
    float passSpan = 1.0f / 1024.0f;
    // The network's arithmetic (nn/inference.h): Float32, or BFloat16 (AVX-512 BF16 CPUs only; the
    // constructor refuses it elsewhere). cnnPrecision("auto") picks BFloat16 where the CPU has it.
    nn::InferencePrecision precision = nn::InferencePrecision::Float32;
};

// "fp32", "bf16" or "auto" (bf16 where bf16Available(), else fp32); throws dejag::Error naming the
// choices for anything else, or for "bf16" on a CPU without AVX-512 BF16.
nn::InferencePrecision cnnPrecision(const std::string& name);
const char* precisionName(nn::InferencePrecision precision);

// Optional G-buffers for gating (each width x height, row-major), any may be null.
struct CnnBuffers {
    const float* depth = nullptr;
    const float* ids = nullptr;
    // A guided model's guide: its guide method's result on the frame, in the frame's layout (required
    // for such a model: nn/frame_network.h).
    const float* guide = nullptr;
};

class CnnFilter {
  public:
    // Throws dejag::Error if the model does not take and return 1 or 3 channels of the same count.
    CnnFilter(nn::Model model, const CnnOptions& options = {});
    ~CnnFilter();
    CnnFilter(CnnFilter&&) noexcept;
    CnnFilter& operator=(CnnFilter&&) noexcept;

    // frame: (height, width, channels) interleaved, channels >= 3, R G B first, sRGB-encoded in [0, 1];
    // other channels (alpha) pass through. A grey model filters the luma and adds its change to R, G
    // and B. Out of place; in and out must not overlap.
    void apply(const float* in, float* out, int width, int height, int channels,
               const CnnBuffers& buffers = {});

    const nn::Model& model() const;
    const CnnOptions& options() const;
    int halo() const;                  // pixels of context around each tile
    int alignment() const;             // the network's total stride
    double processedFraction() const;  // of the last apply(): tiles run / tiles
    // Of the last apply(): the share of the processed tiles' pixels passed through (0 ungated).
    double passedThroughFraction() const;
    int tilesProcessed() const;
    int tileCount() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

// The method "cnn" of infer/filter.h: parameters model, gate (off | auto | a luma threshold), tile,
// precision, pass-span; uses the depth and id buffers for gating when the frame has them. A model trained
// after an input method runs after it; a guided one reads its guide method's result beside the frame.
// Both methods run on the whole frame, gated tiles included.
MethodSpec cnnMethod();

}  // namespace dejag::infer

// dejag/nn: how a model meets a frame — the one contract that training's validation, the model card, the
// CNN filter and the benchmarks all run a network through, so a card measures what users run.
//
// A frame is (height, width, channels) interleaved floats, channels >= 3, R G B first, sRGB-encoded in
// [0, 1]. An RGB network sees planes of R, G and B; a grey network sees the luma (base/luma.h) and its
// change of the luma is added to R, G and B. The frame is padded to a multiple of the network's total
// stride by repeating its last row and column, as a tile near the border is padded. Outputs are clamped
// to [0, 1]; channels after R G B are not touched (run() copies them through).
//
// A guided network (a kpn model built with a guide, its architecture naming "guide_method") takes six
// channels: the frame's R G B and the guide's, another method's result on the same frame, which the
// caller makes and passes beside the frame (interleaved, the frame's channel count, R G B first).
//
// A region of the frame (a tile) runs with a halo of the network's receptive field around it, clipped at
// the padded frame's border, so a tiled run equals the whole-frame one to float rounding.
#pragma once

#include <map>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "nn/inference.h"
#include "nn/model.h"

namespace dejag::nn {

// How many input pixels on each side of a pixel can change its output, and the product of the model's
// strides. Exact for conv, transposed conv, pooling, resampling and shuffles; unbounded through a warp.
struct ReceptiveField {
    int radius = 0;
    int stride = 1;
    bool bounded = true;  // false: a warp reads wherever the motion points (radius is then 0)
};
ReceptiveField receptiveField(const Model& model);

// What a filter of frames needs of its weights, checked when a model is loaded rather than in the middle
// of a frame: finite weights, and on a test pattern in [0, 1] (a hard edge, a ramp and a checkerboard) a
// finite output within 4 of that range (weights that are finite but huge, 1e38, give infinities there as
// they would on every frame). Throws dejag::Error naming the model.
void checkWeightsForFrames(const Model& model);

class FrameNetwork {
  public:
    // Throws dejag::Error unless the model takes and returns 1 (luma) or 3 (RGB) channels of the same
    // count (or, guided, takes 6 and returns 3), at the size it is given (a super-resolution or downscaling
    // graph is no anti-aliasing filter), or for BFloat16 on a CPU without AVX-512 BF16.
    explicit FrameNetwork(Model model, InferencePrecision precision = InferencePrecision::Float32);
    // Runs a model it does not own (training's validation: the model under training, which must outlive
    // it and keep its weights while it runs).
    static FrameNetwork borrowing(const Model& model,
                                  InferencePrecision precision = InferencePrecision::Float32);
    ~FrameNetwork();
    FrameNetwork(FrameNetwork&&) noexcept;
    FrameNetwork& operator=(FrameNetwork&&) noexcept;

    const Model& model() const;
    bool grey() const;
    // The method whose result a guided network reads beside the frame ("": none).
    const std::string& guideMethod() const;
    int halo() const;       // the receptive field, rounded up to the stride
    int alignment() const;  // the total stride: regions start at multiples of it
    InferencePrecision precision() const;

    // The frame the next regions are cut from (a grey network's luma is computed here). `in` must stay
    // valid until the last runRegion() of the frame, and so must `guide` (a guided network's; its layout
    // is the frame's; required for a guided network, ignored otherwise).
    void beginFrame(const float* in, int width, int height, int channels, const float* guide = nullptr);
    // Runs the core [x0, x1) x [y0, y1) of the frame begun (x0, y0 multiples of alignment()) with its
    // halo and writes R G B of those pixels of `out`. passSpan: a kernel-predicting network passes
    // through flat runs of pixels (InferencePlan::setPassThrough; 0: off). Returns the pixels made (the
    // region's rows of the core, halo columns included) and how many of them were passed through.
    struct RegionFigures {
        double madePixels = 0, passedPixels = 0;
    };
    RegionFigures runRegion(float* out, int x0, int y0, int x1, int y1, float passSpan = 0);
    // The whole frame at once, channels after R G B copied from `in` (in and out must not overlap).
    void run(const float* in, float* out, int width, int height, int channels, const float* guide = nullptr);

  private:
    struct Impl;
    explicit FrameNetwork(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

}  // namespace dejag::nn

// dejag/infer: U-TAA and T-TAA (infer/taa.h, docs/taa.md) as GLSL 430 compute passes, in the order of
// their CPU band kernel (infer/taa_kernels.cpp): the current frame un-jittered; for T-TAA the Sobel of
// albedo luma, luma and depth and its own stabilising TAA; the blend (the colour box of the cross and the
// 3x3, the nearest depth's motion, the bilinear history, INSIDE's clip toward the box centre, the luma
// feedback); the sharpen of the output. The histories stay on the GPU. The optional motion blur of the
// output has no GPU form.
#pragma once

#include <string>
#include <vector>

#include "infer/taa.h"
#include "render/gl.h"

namespace dejag::infer {

class GlslTaa {
  public:
    // Throws dejag::Error for options Taa refuses, and for the motion blur.
    GlslTaa(render::GlContext& context, const TaaOptions& options);
    ~GlslTaa();
    GlslTaa(const GlslTaa&) = delete;
    GlslTaa& operator=(const GlslTaa&) = delete;

    // The five passes' sources (the current frame, the Sobel, the Sobel's TAA, the blend, the sharpen;
    // U-TAA's second and third are empty).
    static std::vector<std::string> sources(const TaaOptions& options);
    // Storage buffers in infer::Frame's layouts (albedo, ids and previousDepth for T-TAA, else 0); out
    // (H, W, 3) sRGB. The first frame, a size change or reset() starts a new history.
    void dispatch(const TaaFrame& buffers, unsigned colour, unsigned albedo, unsigned depth, unsigned motion,
                  unsigned ids, unsigned previousDepth, unsigned out);
    void reset() { width_ = height_ = 0; }

  private:
    render::GlContext& context_;
    TaaOptions options_;
    unsigned programs_[5] = {0, 0, 0, 0, 0};  // current, sobel, stable sobel, blend, sharpen
    unsigned current_ = 0, sobel_ = 0, sobelHistory_[2] = {0, 0}, history_[2] = {0, 0}, blended_ = 0,
             empty_ = 0;
    int width_ = 0, height_ = 0, read_ = 0;
    size_t pixels_ = 0;
};

}  // namespace dejag::infer

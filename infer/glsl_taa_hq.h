// dejag/infer: taa-hq as GLSL 430 compute passes, the steps of infer/taa_hq.h in the order of its CPU band
// kernel (infer/taa_hq_kernels.cpp): the in-pixel sample decoded to linear light, the history fetched
// where the nearest surface was (Catmull-Rom, deringed), rejected on a depth disocclusion, clipped in
// YCoCg unless nothing moved, accumulated by 1 / weight; the output encoded to sRGB and sharpened on the
// output only. The history (linear R G B and the signed weight per pixel) stays on the GPU.
#pragma once

#include <string>
#include <vector>

#include "infer/taa_hq.h"
#include "render/gl.h"

namespace dejag::infer {

class GlslTaaHq {
  public:
    GlslTaaHq(render::GlContext& context, const TaaHqOptions& options);
    ~GlslTaaHq();
    GlslTaaHq(const GlslTaaHq&) = delete;
    GlslTaaHq& operator=(const GlslTaaHq&) = delete;

    // The three passes' sources: the current samples, the resolve, the sharpen (docs/glsl.md).
    static std::vector<std::string> sources(const TaaHqOptions& options);
    // Storage buffers in infer::Frame's layouts: colour (H, W, 3) sRGB, motion (H, W, 2), depth and
    // previousDepth (H, W) or both 0; out (H, W, 3) sRGB. jitter: the frame's image shift (pixels, +y
    // down). The first frame, a size change or reset() starts a new history.
    void dispatch(unsigned colour, unsigned motion, unsigned depth, unsigned previousDepth, float jitterX,
                  float jitterY, unsigned out, int width, int height);
    void reset() { width_ = height_ = 0, frame_ = 0; }

  private:
    render::GlContext& context_;
    TaaHqOptions options_;
    unsigned programs_[3] = {0, 0, 0};  // prepare, resolve, sharpen
    unsigned current_ = 0, history_[2] = {0, 0}, unsharpened_ = 0, empty_ = 0;
    int width_ = 0, height_ = 0, frame_ = 0, read_ = 0;
    size_t pixels_ = 0;
};

}  // namespace dejag::infer

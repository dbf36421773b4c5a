// dejag/infer: FXAA 3.11 as a GLSL 430 compute shader, the same algorithm as infer/fxaa.h step for step
// (every operation `precise`, so no multiply-add is fused where the CPU kernels fuse none), for an engine's
// post-process chain and the viewer. `dejag export --glsl fxaa` writes it; Glsl.Fxaa* run it through
// OSMesa against the CPU filter.
#pragma once

#include <string>

#include "infer/fxaa.h"
#include "render/gl.h"

namespace dejag::infer {

// The shader for frames of `channels` interleaved float channels (R, G, B first; the others copied): binding
// 1 the frame, binding 4 the result (the same layout), uniform ivec2 size; one invocation per pixel, work
// groups of 8 x 8. Throws dejag::Error for options Fxaa would refuse.
std::string fxaaGlslSource(const FxaaOptions& options, int channels);

class GlslFxaa {
  public:
    GlslFxaa(render::GlContext& context, const FxaaOptions& options, int channels);
    ~GlslFxaa();
    GlslFxaa(const GlslFxaa&) = delete;
    GlslFxaa& operator=(const GlslFxaa&) = delete;
    // in, out: (height, width, channels) interleaved floats.
    void apply(const float* in, float* out, int width, int height);
    // The same on storage buffers already on the GPU (in != out), with nothing read back.
    void dispatch(unsigned in, unsigned out, int width, int height);

  private:
    render::GlContext& context_;
    int channels_;
    unsigned program_ = 0, buffers_[2] = {0, 0};
    size_t capacity_ = 0;
};

}  // namespace dejag::infer

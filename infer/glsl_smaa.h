// dejag/infer: SMAA 1x as three GLSL 430 compute passes, the CPU filter's algorithm (infer/smaa.h) step for
// step: edges, blending weights (the same run searches, the areas from tables of infer/smaa_area.h
// uploaded once), blending in linear light by base/srgb.h's curves. Every decision is computed `precise`
// in the CPU's order, so the edges and weights are the CPU's; the blend's arithmetic may round
// differently where the CPU's SIMD kernels fuse multiply-adds (docs/glsl.md has the measured difference).
#pragma once

#include <string>
#include <vector>

#include "infer/smaa.h"
#include "render/gl.h"

namespace dejag::infer {

class GlslSmaa {
  public:
    // Throws dejag::Error for options Smaa refuses, and for predication (GPU frames carry no depth).
    GlslSmaa(render::GlContext& context, const SmaaOptions& options);
    ~GlslSmaa();
    GlslSmaa(const GlslSmaa&) = delete;
    GlslSmaa& operator=(const GlslSmaa&) = delete;
    // The three passes' sources (edges, weights, blending), and the area tables they read at bindings 5
    // (orthogonal: [pattern 16][left 2 steps + 1][right 2 steps + 1][2]) and 6 (diagonal: [16][20][20][2]).
    static std::vector<std::string> sources(const SmaaOptions& options);
    static std::vector<float> orthogonalAreas(const SmaaOptions& options);
    static std::vector<float> diagonalAreas();
    // in, out: storage buffers of (height, width, 3) interleaved sRGB-encoded floats; in != out.
    void dispatch(unsigned in, unsigned out, int width, int height);

  private:
    render::GlContext& context_;
    SmaaOptions options_;
    unsigned programs_[3] = {0, 0, 0};
    unsigned edges_ = 0, weights_ = 0, orthogonal_ = 0, diagonal_ = 0;
    size_t pixels_ = 0;
};

}  // namespace dejag::infer

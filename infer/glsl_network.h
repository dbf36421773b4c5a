// dejag/infer: runs a network exported as GLSL compute shaders (nn/glsl.h) in an OpenGL 4.3+ context: the
// check that what an engine would run computes what the CPU filter does (OSMesa's llvmpipe in the tests),
// and the viewer's GPU path where a GPU exists.
#pragma once

#include <utility>
#include <vector>

#include "nn/glsl.h"
#include "render/gl.h"

namespace dejag::infer {

class GlslNetworkRunner {
  public:
    // Compiles every pass in the current context of `context`; throws dejag::Error with the compiler's log
    // naming the pass that failed, or if the context has no compute shaders.
    GlslNetworkRunner(render::GlContext& context, nn::GlslNetwork network);
    ~GlslNetworkRunner();
    GlslNetworkRunner(const GlslNetworkRunner&) = delete;
    GlslNetworkRunner& operator=(const GlslNetworkRunner&) = delete;

    // input: planar (C, H, W) float32, the model's input; returns the output planar (Cout, H, W). The
    // width and height must be multiples of the network's size divisor. Buffers are made once per size.
    std::vector<float> run(const float* input, int width, int height);
    // The same in steps, for inputs already on the GPU: prepare() makes the buffers for a size (once per
    // size) and returns the input's storage buffer, planar (C, H, W); dispatch() runs every pass on it and
    // returns the output's storage buffer, planar (Cout, H, W); nothing is read back.
    unsigned prepare(int width, int height);
    unsigned dispatch();
    const nn::GlslNetwork& network() const { return network_; }
    // Wall time of the last run (upload, passes, read back; on llvmpipe the GPU is the CPU).
    double lastMilliseconds() const { return lastMs_; }

  private:
    std::pair<int, int> sizeOf(size_t buffer) const;  // a buffer's width and height at the prepared size
    render::GlContext& context_;
    nn::GlslNetwork network_;
    std::vector<unsigned> programs_;
    std::vector<unsigned> buffers_;  // one per network buffer, in network_.buffers' order
    unsigned weights_ = 0;
    int width_ = 0, height_ = 0;
    double lastMs_ = 0;
};

}  // namespace dejag::infer

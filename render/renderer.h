// dejag/render: draws a Scene into float buffers with OpenGL (OSMesa by default): lit colour, unlit
// albedo, linear depth, motion vectors, object IDs and the previous frame's depth; and the accumulated
// ground truth (N Halton-jittered renders of one pose, optionally adaptive per tile).
#pragma once

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "render/gl.h"
#include "render/scene.h"

namespace dejag::render {

// Which buffers a frame holds. Channel names (docs/render.md):
//   colour R G B (linear lit colour) · albedo.R albedo.G albedo.B · depth.Z (view-space distance along
//   the view axis, scene units; background = far plane) · motion.X motion.Y (pixels moved since the
//   previous frame, +x right, +y down; history is at pixel - motion) · id.ID (object ID, 0 = background)
//   · prevdepth.Z (depth.Z of the previous frame).
struct BufferSet {
    bool colour = true, albedo = false, depth = false, motion = false, id = false, previousDepth = false;
    static BufferSet all();
    // "color,albedo,depth,motion,id,prevdepth" (any subset; "colour" is accepted too).
    static BufferSet parse(const std::string& list);
    std::vector<std::string> channelNames() const;
    std::string describe() const;
};

// Float image, (H, W, C) interleaved, row 0 at the top.
struct Frame {
    int width = 0, height = 0;
    std::vector<std::string> channelNames;
    std::vector<float> pixels;
    int channels() const { return int(channelNames.size()); }
};

// The textures of a frame left on the GPU (FrameRequest::readBack = false), OpenGL's rows (row 0 at the
// bottom): colour and albedo RGBA32F in linear light, depth, id and previous depth R32F, motion RG32F; in
// the units of the channels above.
struct GpuBuffers {
    GLuint colour = 0, albedo = 0, depth = 0, motion = 0, id = 0, previousDepth = 0;
};

struct FrameRequest {
    double time = 0;           // scene time (frame index)
    double previousTime = -1;  // for motion vectors and prevdepth
    Vec2 jitter;               // sub-pixel shift of the image in pixels, +x right, +y up (render/halton.h)
    Vec2 previousJitter;       // the previous frame's, for prevdepth
    BufferSet buffers;
    // Multisampling of the lit colour (1 = off, or 2, 4, 8): resolved by averaging, a cheaper reference
    // for edges only (no help for texture or shading aliasing). The other buffers stay single-sample.
    int msaa = 1;
    // false: the buffers stay on the GPU (colourTexture()) and the Frame returned holds no pixels; what a
    // post-process pass on the GPU reads (dejag view).
    bool readBack = true;
};

enum class PixelFilter { Box, Gaussian };

struct TruthOptions {
    int samples = 128;
    PixelFilter filter = PixelFilter::Box;  // box: uniform over the pixel; Gaussian: sigma 0.5 px, radius 1.5
    bool adaptive = false;
    // Adaptive: a tile has converged when doubling its samples moved its mean by less than `tolerance`
    // (RMS over the tile) and the standard error of every pixel's mean is below `pixelTolerance`.
    double tolerance = 1e-3;
    double pixelTolerance = 2e-3;
    int tileSize = 8;
    int firstRound = 16;  // adaptive: samples every tile gets before the first convergence test
};

struct TruthStats {
    int samples = 0;              // the most any tile received
    int64_t tileSamples = 0;      // sum over tiles of the samples each received
    int64_t fullTileSamples = 0;  // tiles x samples, the non-adaptive cost
    int tiles = 0, rounds = 0;
    double milliseconds = 0;
    double saving() const { return tileSamples > 0 ? double(fullTileSamples) / double(tileSamples) : 1.0; }
};

class Renderer {
  public:
    // The context must stay current and alive while the renderer is used.
    Renderer(const GlContext& context, const Scene& scene, int width, int height);
    ~Renderer();
    Renderer(const Renderer&) = delete;
    Renderer& operator=(const Renderer&) = delete;

    Frame render(const FrameRequest& request);
    // Lit colour (R G B) accumulated over Halton-jittered renders of the pose at `time`.
    Frame renderTruth(double time, const TruthOptions& options, TruthStats* stats = nullptr);

    bool anisotropySupported() const { return anisotropy_; }
    // The texture (RGBA32F, linear light, OpenGL's rows: row 0 at the bottom) holding the lit colour of the
    // last render(); valid until the next call.
    GLuint colourTexture() const;
    // Every buffer's texture, as the last render() left them.
    GpuBuffers textures() const;

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
    bool anisotropy_ = false;
};

}  // namespace dejag::render

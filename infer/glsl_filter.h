// dejag/infer: the methods' GPU forms, one face for all — what an engine's post-process chain runs, and
// what `dejag view` runs on the frame it renders without a round trip through the CPU (docs/view.md).
//
// A GPU frame is a shader storage buffer of (height, width, 3) interleaved floats, R G B sRGB-encoded in
// [0, 1], row 0 at the top: the layout and encoding the CPU filters read (infer/filter.h), so a method's
// GPU form and its CPU form can be compared value for value. GlslFrameImport makes one from the renderer's
// linear colour texture.
//
// Which methods have a GPU form, and with which parameters, is the table in glsl_filter.cpp; every form is
// checked against its CPU filter in tests/infer/glsl_filter_test.cpp.
#pragma once

#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <utility>
#include <vector>

#include "infer/filter.h"
#include "render/gl.h"
#include "render/renderer.h"

namespace dejag::infer {

// A frame on the GPU: storage buffers in the layouts of infer/frame.h's Frame, 0 where a buffer is absent.
struct GlslFrame {
    int width = 0, height = 0;
    unsigned colour = 0;         // (height, width, 3): R G B, sRGB-encoded
    unsigned albedo = 0;         // (height, width, 3), sRGB-encoded
    unsigned depth = 0;          // (height, width): linear depth / far
    unsigned motion = 0;         // (height, width, 2): pixels moved since the previous frame, +y down
    unsigned ids = 0;            // (height, width)
    unsigned previousDepth = 0;  // (height, width): the previous frame's depth / far
    bool hasJitter = false;      // the frame's jitter: the image's shift, pixels, +y down
    float jitter[2] = {0, 0};
};

class GlslFilter {
  public:
    virtual ~GlslFilter() = default;
    const std::string& name() const { return name_; }
    // Filters frame.colour into out (a storage buffer of (height, width, 3), written whole, not
    // frame.colour). Runs in the context the filter was made in; nothing is read back. Throws dejag::Error
    // naming a buffer the method needs that the frame lacks.
    virtual void run(const GlslFrame& frame, unsigned out) = 0;
    virtual bool temporal() const { return false; }
    virtual void reset() {}  // a temporal method starts a new history
    // What the CPU form does that this one does not (e.g. a network's gating), "" if nothing.
    const std::string& differences() const { return differences_; }

  protected:
    explicit GlslFilter(std::string name, std::string differences = "")
        : name_(std::move(name)), differences_(std::move(differences)) {}

  private:
    std::string name_, differences_;
};

// The GPU form of one method (not a chain) with `parameters`, in `context` (OpenGL 4.3 compute), or
// nullptr with the reason in *whyNot when the method has none (T-TAA, the temporal network, SMAA with
// predication). Throws dejag::Error as makeFilter does for an unknown method or a bad or unread parameter,
// and if the context has no compute shaders.
std::unique_ptr<GlslFilter> makeGlslFilter(render::GlContext& context, const std::string& method,
                                           const FilterParameters& parameters, std::string* whyNot);

// A storage buffer of `floats` floats (grown, never shrunk); 0 until the first call.
class GlslBuffer {
  public:
    explicit GlslBuffer(render::GlContext& context) : context_(context) {}
    ~GlslBuffer();
    GlslBuffer(const GlslBuffer&) = delete;
    GlslBuffer& operator=(const GlslBuffer&) = delete;
    unsigned ensure(size_t floats);
    unsigned id() const { return buffer_; }

  private:
    render::GlContext& context_;
    unsigned buffer_ = 0;
    size_t bytes_ = 0;
};

// The renderer's textures (render/renderer.h's GpuBuffers) as a GPU frame, as frameFromImage reads a
// rendered frame: rows flipped; colour and albedo sRGB-encoded (data/image.h's curve, bit for bit) and
// clamped to [0, 1]; depth and previous depth divided by `depthFar`. `wanted`: the buffers besides the
// colour.
class GlslFrameImport {
  public:
    explicit GlslFrameImport(render::GlContext& context);
    ~GlslFrameImport();
    GlslFrameImport(const GlslFrameImport&) = delete;
    GlslFrameImport& operator=(const GlslFrameImport&) = delete;
    // The frame's buffers are this object's, valid until the next run().
    const GlslFrame& run(const render::GpuBuffers& textures, int width, int height, BufferSet wanted = 0,
                         float depthFar = 1.0f);

  private:
    void import(unsigned texture, int channels, bool encode, float divisor, GlslBuffer& out);
    render::GlContext& context_;
    unsigned program_ = 0;
    GlslBuffer colour_, albedo_, depth_, motion_, ids_, previousDepth_;
    GlslFrame frame_;
};

// A method's GPU form as files an engine loads: each pass's source, the tables some passes read, and a
// description (network.json): the buffers, each pass's bindings and uniforms, the dispatch, and what is
// kept from one frame to the next.
struct GlslMethodFiles {
    std::vector<std::pair<std::string, std::string>> passes;         // file name (.comp), source
    std::vector<std::pair<std::string, std::vector<float>>> tables;  // file name (.bin), float32 values
    nlohmann::json description;
};

// fxaa, smaa, taa, taa-sobel or taa-hq with `parameters` (checked as makeFilter checks them). Throws
// dejag::Error for another method (a network is exported from its model, nn/glsl.h) and for settings its
// GPU form does not take.
GlslMethodFiles glslMethodFiles(const std::string& method, const FilterParameters& parameters);

}  // namespace dejag::infer

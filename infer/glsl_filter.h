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
#include <string>

#include "infer/filter.h"
#include "render/gl.h"

namespace dejag::infer {

class GlslFilter {
  public:
    virtual ~GlslFilter() = default;
    const std::string& name() const { return name_; }
    // in, out: storage buffers of GPU frames of width x height (out is written whole; in != out). Runs in
    // the context the filter was made in; nothing is read back.
    virtual void run(unsigned in, unsigned out, int width, int height) = 0;
    // What the CPU form does that this one does not (e.g. a network's gating), "" if nothing.
    const std::string& differences() const { return differences_; }

  protected:
    explicit GlslFilter(std::string name, std::string differences = "")
        : name_(std::move(name)), differences_(std::move(differences)) {}

  private:
    std::string name_, differences_;
};

// The GPU form of one method (not a chain) with `parameters`, in `context` (OpenGL 4.3 compute), or
// nullptr with the reason in *whyNot when the method has none (a temporal method, a guided network).
// Throws dejag::Error as makeFilter does for an unknown method or a bad or unread parameter, and if the
// context has no compute shaders.
std::unique_ptr<GlslFilter> makeGlslFilter(render::GlContext& context, const std::string& method,
                                           const FilterParameters& parameters, std::string* whyNot);

// The renderer's colour (an RGBA32F texture of linear light, OpenGL's rows: row 0 at the bottom) as a GPU
// frame: rows flipped, R G B sRGB-encoded and clamped to [0, 1] as frameFromImage encodes a linear image.
class GlslFrameImport {
  public:
    explicit GlslFrameImport(render::GlContext& context);
    ~GlslFrameImport();
    GlslFrameImport(const GlslFrameImport&) = delete;
    GlslFrameImport& operator=(const GlslFrameImport&) = delete;
    void run(unsigned texture, unsigned out, int width, int height);

  private:
    render::GlContext& context_;
    unsigned program_ = 0;
};

// A storage buffer for a GPU frame of width x height (grown, never shrunk); 0 until the first call.
class GlslFrameBuffer {
  public:
    explicit GlslFrameBuffer(render::GlContext& context) : context_(context) {}
    ~GlslFrameBuffer();
    GlslFrameBuffer(const GlslFrameBuffer&) = delete;
    GlslFrameBuffer& operator=(const GlslFrameBuffer&) = delete;
    unsigned ensure(int width, int height);
    unsigned id() const { return buffer_; }

  private:
    render::GlContext& context_;
    unsigned buffer_ = 0;
    size_t bytes_ = 0;
};

}  // namespace dejag::infer

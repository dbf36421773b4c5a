// The methods' GPU forms: see infer/glsl_filter.h.
#include "infer/glsl_filter.h"

#include <algorithm>
#include <functional>
#include <map>
#include <utility>

#include "base/error.h"
#include "base/luma.h"
#include "infer/fxaa.h"
#include "infer/glsl_fxaa.h"
#include "infer/glsl_network.h"
#include "infer/glsl_smaa.h"
#include "infer/glsl_srgb.h"
#include "infer/glsl_taa.h"
#include "infer/glsl_taa_hq.h"
#include "infer/smaa.h"
#include "infer/taa_hq.h"
#include "nn/glsl.h"
#include "nn/model.h"

namespace dejag::infer {
namespace {

// "none": the frame copied.
class GlslNone final : public GlslFilter {
  public:
    explicit GlslNone(render::GlContext& context) : GlslFilter("none"), context_(context) {}
    void run(const GlslFrame& frame, unsigned out) override {
        const render::GlFunctions& gl = context_.compute();
        render::timedPass(context_, "copy", [&] {
            gl.BindBuffer(GL_COPY_READ_BUFFER, frame.colour);
            gl.BindBuffer(GL_COPY_WRITE_BUFFER, out);
            gl.CopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, 0, 0,
                                 GLsizeiptr(size_t(frame.width) * size_t(frame.height) * 3 * sizeof(float)));
        });
    }

  private:
    render::GlContext& context_;
};

// A single-frame method's GPU form: its passes (GlslFxaa, GlslSmaa) on the frame's colour.
template <class Passes>
class GlslColourFilter final : public GlslFilter {
  public:
    template <class... Arguments>
    GlslColourFilter(const std::string& name, render::GlContext& context, Arguments&&... arguments)
        : GlslFilter(name), passes_(context, std::forward<Arguments>(arguments)...) {}
    void run(const GlslFrame& frame, unsigned out) override {
        passes_.dispatch(frame.colour, out, frame.width, frame.height);
    }

  private:
    Passes passes_;
};

class GlslTaaFilter final : public GlslFilter {
  public:
    GlslTaaFilter(render::GlContext& context, const TaaOptions& options)
        : GlslFilter(options.improved ? "taa-sobel" : "taa"), taa_(context, options) {}
    void run(const GlslFrame& frame, unsigned out) override {
        TaaFrame f;
        f.width = frame.width, f.height = frame.height;
        f.hasJitter = frame.hasJitter, f.jitter[0] = frame.jitter[0], f.jitter[1] = frame.jitter[1];
        taa_.dispatch(f, frame.colour, frame.albedo, frame.depth, frame.motion, frame.ids,
                      frame.previousDepth, out);
    }
    bool temporal() const override { return true; }
    void reset() override { taa_.reset(); }

  private:
    GlslTaa taa_;
};

class GlslTaaHqFilter final : public GlslFilter {
  public:
    GlslTaaHqFilter(render::GlContext& context, const TaaHqOptions& options)
        : GlslFilter("taa-hq"), taa_(context, options) {}
    void run(const GlslFrame& frame, unsigned out) override {
        if (!frame.motion) throw Error("taa-hq needs the frame's motion buffer");
        const bool depth = frame.depth && frame.previousDepth;
        taa_.dispatch(frame.colour, frame.motion, depth ? frame.depth : 0, depth ? frame.previousDepth : 0,
                      frame.hasJitter ? frame.jitter[0] : 0.0f, frame.hasJitter ? frame.jitter[1] : 0.0f, out,
                      frame.width, frame.height);
    }
    bool temporal() const override { return true; }
    void reset() override { taa_.reset(); }

  private:
    GlslTaaHq taa_;
};

// The frame as the network's input, as nn/frame_network.h meets it: planes of R, G, B (or the luma of a
// grey network; or, for a guided network, R G B and then the guide's R G B), padded to a multiple of the
// network's stride by repeating the last row and column.
constexpr const char* kPackShader = R"(#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 1) readonly buffer Frame { float frame[]; };
layout(std430, binding = 2) readonly buffer Guide { float guide[]; };
layout(std430, binding = 4) writeonly buffer Planes { float planes[]; };
uniform ivec2 size;    // the frame's
uniform ivec2 padded;  // the network's input
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= padded.x || p.y >= padded.y) return;
    int s = (min(p.y, size.y - 1) * size.x + min(p.x, size.x - 1)) * 3, d = p.y * padded.x + p.x;
    if (GREY) {
        precise float l = LUMA_R * frame[s] + LUMA_G * frame[s + 1] + LUMA_B * frame[s + 2];
        planes[d] = l;
    } else {
        for (int c = 0; c < 3; ++c) planes[c * padded.x * padded.y + d] = frame[s + c];
        if (GUIDE)
            for (int c = 0; c < 3; ++c) planes[(3 + c) * padded.x * padded.y + d] = guide[s + c];
    }
}
)";

// The network's output back into a frame, clamped to [0, 1]: R G B, or a grey network's change of the
// luma added to each of them.
constexpr const char* kUnpackShader = R"(#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 1) readonly buffer Planes { float planes[]; };
layout(std430, binding = 2) readonly buffer Frame { float frame[]; };
layout(std430, binding = 4) writeonly buffer Result { float result[]; };
uniform ivec2 size;
uniform ivec2 padded;
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int o = (p.y * size.x + p.x) * 3, s = p.y * padded.x + p.x;
    if (GREY) {
        precise float l = LUMA_R * frame[o] + LUMA_G * frame[o + 1] + LUMA_B * frame[o + 2];
        precise float change = planes[s] - l;
        for (int c = 0; c < 3; ++c) {
            precise float v = frame[o + c] + change;
            result[o + c] = clamp(v, 0.0, 1.0);
        }
    } else {
        for (int c = 0; c < 3; ++c) result[o + c] = clamp(planes[c * padded.x * padded.y + s], 0.0, 1.0);
    }
}
)";

std::string withGrey(const char* body, bool grey, bool guide) {
    std::string source = body;
    const size_t line = source.find('\n') + 1;
    source.insert(line, std::string("const bool GREY = ") + (grey ? "true" : "false") +
                            ", GUIDE = " + (guide ? "true" : "false") + ";\nconst float LUMA_R = " +
                            nn::glslFloat(kLumaRed) + ", LUMA_G = " + nn::glslFloat(kLumaGreen) +
                            ", LUMA_B = " + nn::glslFloat(kLumaBlue) + ";\n");
    return source;
}

// "cnn": the network's passes (nn/glsl.h) between the two above, on the whole frame; after its input
// method's GPU form, and beside its guide method's, for a network trained so.
class GlslCnn final : public GlslFilter {
  public:
    GlslCnn(render::GlContext& context, const nn::Model& model, const std::string& differences,
            std::unique_ptr<GlslFilter> input, std::unique_ptr<GlslFilter> guide)
        : GlslFilter("cnn", differences),
          context_(context),
          runner_(context, nn::exportGlsl(model)),
          input_(std::move(input)),
          guide_(std::move(guide)),
          inputFrame_(context),
          guideFrame_(context) {
        const render::GlFunctions& gl = context_.compute();
        grey_ = runner_.network().inputChannels == 1;
        const bool guided = guide_ != nullptr;
        pack_ = render::compileComputeProgram(gl, withGrey(kPackShader, grey_, guided),
                                              "the network's input pass");
        unpack_ = render::compileComputeProgram(gl, withGrey(kUnpackShader, grey_, guided),
                                                "the network's output pass");
    }
    ~GlslCnn() override {
        const render::GlFunctions& gl = context_.gl();
        gl.DeleteProgram(pack_);
        gl.DeleteProgram(unpack_);
    }
    void run(const GlslFrame& frame, unsigned out) override {
        const render::GlFunctions& gl = context_.compute();
        const int width = frame.width, height = frame.height;
        unsigned in = frame.colour;
        const int d = runner_.network().sizeDivisor;
        const int pw = (width + d - 1) / d * d, ph = (height + d - 1) / d * d;
        const unsigned planes = runner_.prepare(pw, ph);
        GlslFrame through = frame;
        const size_t floats = size_t(width) * size_t(height) * 3;
        if (input_) {
            input_->run(frame, inputFrame_.ensure(floats));
            through.colour = in = inputFrame_.id();
        }
        if (guide_) guide_->run(through, guideFrame_.ensure(floats));
        gl.UseProgram(pack_);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, in);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, guide_ ? guideFrame_.id() : in);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, planes);
        gl.Uniform2i(gl.GetUniformLocation(pack_, "size"), width, height);
        gl.Uniform2i(gl.GetUniformLocation(pack_, "padded"), pw, ph);
        render::dispatchPass(context_, "network input", pw, ph);
        const unsigned result = runner_.dispatch();
        gl.UseProgram(unpack_);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, result);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, in);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, out);
        gl.Uniform2i(gl.GetUniformLocation(unpack_, "size"), width, height);
        gl.Uniform2i(gl.GetUniformLocation(unpack_, "padded"), pw, ph);
        render::dispatchPass(context_, "network output", width, height);
    }

  private:
    render::GlContext& context_;
    GlslNetworkRunner runner_;
    std::unique_ptr<GlslFilter> input_, guide_;
    GlslBuffer inputFrame_, guideFrame_;
    bool grey_ = false;
    unsigned pack_ = 0, unpack_ = 0;
};

std::unique_ptr<GlslFilter> makeTaa(MethodParameters& p, render::GlContext& c, std::string* whyNot,
                                    bool improved) {
    const TaaOptions options = taaOptions(p, improved);
    if (options.motionBlur) {
        *whyNot = "TAA's motion blur has no GPU form";
        return nullptr;
    }
    return std::make_unique<GlslTaaFilter>(c, options);
}

// "cnn-temporal": the recurrent network's passes on an input assembled as the CPU filter assembles it
// (infer/cnn_temporal.h): the frame, the network's previous output (kept here, on the GPU), the motion,
// the jitter and the depths, padded to the network's stride by repeating the last row and column; on a
// fresh start the colour stands in for the shown history, nothing is kept and the motion is 0.
constexpr const char* kTemporalPackShader = R"(#version 430
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 0) readonly buffer Colour { float colour[]; };
layout(std430, binding = 1) readonly buffer Motion { float motion[]; };
layout(std430, binding = 2) readonly buffer Depth { float depth[]; };
layout(std430, binding = 3) readonly buffer PreviousDepth { float previousDepth[]; };
layout(std430, binding = 5) readonly buffer State { float state[]; };
layout(std430, binding = 4) writeonly buffer Planes { float planes[]; };
uniform ivec2 size;
uniform ivec2 padded;
uniform bool fresh;
uniform bool hasDepth;
uniform vec2 jitter;
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= padded.x || p.y >= padded.y) return;
    int s = min(p.y, size.y - 1) * size.x + min(p.x, size.x - 1), d = p.y * padded.x + p.x;
    int plane = padded.x * padded.y;
    for (int c = 0; c < 3; ++c) planes[c * plane + d] = colour[3 * s + c];
    for (int c = 0; c < STATE; ++c)
        planes[(3 + c) * plane + d] = !fresh ? state[c * plane + d] : c < 3 ? colour[3 * s + c] : 0.0;
    planes[(3 + STATE) * plane + d] = fresh ? 0.0 : motion[2 * s];
    planes[(4 + STATE) * plane + d] = fresh ? 0.0 : motion[2 * s + 1];
    planes[(5 + STATE) * plane + d] = jitter.x;
    planes[(6 + STATE) * plane + d] = jitter.y;
    if (DEPTH) {
        planes[(7 + STATE) * plane + d] = hasDepth ? depth[s] : 0.0;
        planes[(8 + STATE) * plane + d] = !hasDepth ? 0.0 : fresh ? depth[s] : previousDepth[s];
    }
}
)";

class GlslCnnTemporal final : public GlslFilter {
  public:
    GlslCnnTemporal(render::GlContext& context, const nn::Model& model, const std::string& differences)
        : GlslFilter("cnn-temporal", differences),
          context_(context),
          runner_(context, nn::exportGlsl(model)),
          state_(context),
          empty_(context) {
        const int inputs = runner_.network().inputChannels;
        stateChannels_ = runner_.network().outputChannels;
        depth_ = inputs == 3 + stateChannels_ + 6;
        if (stateChannels_ < 3 || (inputs != 3 + stateChannels_ + 4 && !depth_))
            throw Error("model '" + model.name() + "' is not a temporal network");
        std::string pack = kTemporalPackShader;
        pack.insert(pack.find('\n') + 1, "const int STATE = " + std::to_string(stateChannels_) +
                                             ";\nconst bool DEPTH = " + (depth_ ? "true" : "false") + ";\n");
        const render::GlFunctions& gl = context_.compute();
        pack_ = render::compileComputeProgram(gl, pack, "the temporal network's input pass");
        unpack_ = render::compileComputeProgram(gl, withGrey(kUnpackShader, false, false),
                                                "the temporal network's output pass");
        empty_.ensure(1);
    }
    ~GlslCnnTemporal() override {
        const render::GlFunctions& gl = context_.gl();
        gl.DeleteProgram(pack_);
        gl.DeleteProgram(unpack_);
    }
    bool temporal() const override { return true; }
    void reset() override { fresh_ = true; }
    void run(const GlslFrame& frame, unsigned out) override {
        if (!frame.motion) throw Error("cnn-temporal needs the frame's motion buffer");
        const render::GlFunctions& gl = context_.compute();
        const int W = frame.width, H = frame.height, d = runner_.network().sizeDivisor;
        const int pw = (W + d - 1) / d * d, ph = (H + d - 1) / d * d;
        if (W != width_ || H != height_) width_ = W, height_ = H, fresh_ = true;
        const size_t stateFloats = size_t(stateChannels_) * size_t(pw) * size_t(ph);
        const unsigned planes = runner_.prepare(pw, ph);
        const bool hasDepth = frame.depth && frame.previousDepth;
        gl.UseProgram(pack_);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, frame.colour);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, frame.motion);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, hasDepth ? frame.depth : empty_.id());
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, hasDepth ? frame.previousDepth : empty_.id());
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, state_.ensure(stateFloats));
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, planes);
        gl.Uniform2i(gl.GetUniformLocation(pack_, "size"), W, H);
        gl.Uniform2i(gl.GetUniformLocation(pack_, "padded"), pw, ph);
        gl.Uniform1i(gl.GetUniformLocation(pack_, "fresh"), fresh_ ? 1 : 0);
        gl.Uniform1i(gl.GetUniformLocation(pack_, "hasDepth"), hasDepth ? 1 : 0);
        gl.Uniform2f(gl.GetUniformLocation(pack_, "jitter"), frame.hasJitter ? frame.jitter[0] : 0.0f,
                     frame.hasJitter ? frame.jitter[1] : 0.0f);
        render::dispatchPass(context_, "network input", pw, ph);
        const unsigned result = runner_.dispatch();
        // The whole output is the next frame's history; its R G B, clamped, the frame shown.
        gl.BindBuffer(GL_COPY_READ_BUFFER, result);
        gl.BindBuffer(GL_COPY_WRITE_BUFFER, state_.id());
        gl.CopyBufferSubData(GL_COPY_READ_BUFFER, GL_COPY_WRITE_BUFFER, 0, 0,
                             GLsizeiptr(stateFloats * sizeof(float)));
        gl.UseProgram(unpack_);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, result);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, frame.colour);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, out);
        gl.Uniform2i(gl.GetUniformLocation(unpack_, "size"), W, H);
        gl.Uniform2i(gl.GetUniformLocation(unpack_, "padded"), pw, ph);
        render::dispatchPass(context_, "network output", W, H);
        fresh_ = false;
    }

  private:
    render::GlContext& context_;
    GlslNetworkRunner runner_;
    GlslBuffer state_, empty_;
    int stateChannels_ = 0, width_ = 0, height_ = 0;
    bool depth_ = false, fresh_ = true;
    unsigned pack_ = 0, unpack_ = 0;
};

using Maker = std::function<std::unique_ptr<GlslFilter>(MethodParameters&, render::GlContext&, std::string*)>;

// The GPU forms: one line per method that has one.
const std::map<std::string, Maker>& glslMethods() {
    static const std::map<std::string, Maker> table = {
        {"none",
         [](MethodParameters&, render::GlContext& c, std::string*) -> std::unique_ptr<GlslFilter> {
             return std::make_unique<GlslNone>(c);
         }},
        {"fxaa",
         [](MethodParameters& p, render::GlContext& c, std::string*) -> std::unique_ptr<GlslFilter> {
             return std::make_unique<GlslColourFilter<GlslFxaa>>("fxaa", c, fxaaOptions(p), 3);
         }},
        {"taa",
         [](MethodParameters& p, render::GlContext& c, std::string* whyNot) -> std::unique_ptr<GlslFilter> {
             return makeTaa(p, c, whyNot, false);
         }},
        {"taa-sobel",
         [](MethodParameters& p, render::GlContext& c, std::string* whyNot) -> std::unique_ptr<GlslFilter> {
             return makeTaa(p, c, whyNot, true);
         }},
        {"cnn-temporal",
         [](MethodParameters& p, render::GlContext& c, std::string* whyNot) -> std::unique_ptr<GlslFilter> {
             const std::string path = p.path("model");
             const nn::Model model = nn::loadModel(path);
             if (const std::string clip = p.text("clip"); clip != "auto") {
                 *whyNot = "clip=" + clip + " has no GPU form (the network's own setting runs)";
                 return nullptr;
             }
             // The CPU form's still gate and bf16 have no counterpart here: every pixel runs, in float32.
             const bool same = p.text("gate") == "off";
             try {
                 return std::make_unique<GlslCnnTemporal>(
                     c, model,
                     same ? "" : "every pixel runs (the CPU form's still gate keeps converged still pixels)");
             } catch (const Error& e) {
                 throw Error("--model '" + path + "': " + e.what());
             }
         }},
        {"taa-hq",
         [](MethodParameters& p, render::GlContext& c, std::string*) -> std::unique_ptr<GlslFilter> {
             return std::make_unique<GlslTaaHqFilter>(c, taaHqOptions(p));
         }},
        {"smaa",
         [](MethodParameters& p, render::GlContext& c, std::string* whyNot) -> std::unique_ptr<GlslFilter> {
             const SmaaOptions options = smaaOptions(p);
             if (options.predication) {
                 *whyNot = "SMAA's predication reads depth, which a GPU frame does not carry";
                 return nullptr;
             }
             return std::make_unique<GlslColourFilter<GlslSmaa>>("smaa", c, options);
         }},
        {"cnn",
         [](MethodParameters& p, render::GlContext& c, std::string* whyNot) -> std::unique_ptr<GlslFilter> {
             const std::string path = p.path("model");
             nn::Model model = nn::loadModel(path);
             // A network trained after or beside another method runs after or beside that method's GPU form
             // (with its default parameters, as the CPU form runs it).
             std::unique_ptr<GlslFilter> before[2];
             const char* const roles[2] = {"input_method", "guide_method"};
             for (int k = 0; k < 2; ++k) {
                 const std::string method = model.architecture().value(roles[k], "");
                 if (method.empty()) continue;
                 std::string why;
                 before[k] = makeGlslFilter(c, method, {}, &why);
                 if (!before[k]) {
                     *whyNot = "'" + path + "' reads " + method + "'s result, and " + why;
                     return nullptr;
                 }
             }
             // The CPU form's gate and precision have no counterpart here: the whole frame runs in float32.
             const bool ungated = p.text("gate") == "off";
             return std::make_unique<GlslCnn>(
                 c, model,
                 ungated ? "" : "the whole frame runs (the CPU form skips the tiles its gate passes)",
                 std::move(before[0]), std::move(before[1]));
         }},
    };
    return table;
}

// The one method named (an unknown method or a chain is makeFilter's error, or `chain`'s).
const MethodSpec& singleMethod(const std::string& method, const FilterParameters& parameters,
                               const std::string& chain) {
    const MethodSpec* spec = findMethod(method);
    if (!spec) {
        makeFilter(method, parameters);  // its one line: an unknown method, or a chain
        throw Error("'" + method + "' " + chain);
    }
    return *spec;
}

// Every parameter checked as the CPU form checks it (a GPU form ignores those it has no use for), and
// none given that the method does not take.
void requireParametersRead(const MethodSpec& spec, const MethodParameters& view,
                           const FilterParameters& parameters) {
    std::string accepted;
    for (const ParameterSpec& p : spec.parameters) {
        view.text(p.name);
        accepted += (accepted.empty() ? "" : ", ") + p.name;
    }
    parameters.requireAllUsed(spec.name, accepted);
}

}  // namespace

std::unique_ptr<GlslFilter> makeGlslFilter(render::GlContext& context, const std::string& method,
                                           const FilterParameters& parameters, std::string* whyNot) {
    const MethodSpec& spec = singleMethod(method, parameters, "has no GPU form: only single methods have");
    MethodParameters view(spec, parameters);
    const auto found = glslMethods().find(method);
    std::unique_ptr<GlslFilter> filter;
    std::string reason = "'" + method + "' has no GPU form yet";
    if (found != glslMethods().end()) filter = found->second(view, context, &reason);
    requireParametersRead(spec, view, parameters);
    if (!filter && whyNot) *whyNot = reason;
    return filter;
}

namespace {

// A texture's first `channels` channels into a buffer, rows flipped: encoded as data/image.h's
// linearToSrgb on max(v, 0) and clamped to [0, 1] (base/srgb.h's curve in the same float operations,
// precise: the same bits), or divided by `divisor` (in double, as frameFromImage divides).
std::string importShader() {
    return "#version 430\n" + glslSrgbFunctions(7, 7) + R"(
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 4) writeonly buffer Result { float result[]; };
uniform sampler2D image;
uniform ivec2 size;
uniform int channels;
uniform bool encoded;
uniform float divisor;
// data/image.h's linearToSrgb on max(v, 0), clamped to [0, 1] (from 1 on, 1).
float encode(float x) {
    x = max(x, 0.0);
    return x >= 1.0 ? 1.0 : clamp(encodeSrgb(x), 0.0, 1.0);
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    vec4 texel = texelFetch(image, ivec2(p.x, size.y - 1 - p.y), 0);
    int o = (p.y * size.x + p.x) * channels;
    for (int k = 0; k < channels; ++k) {
        float v = texel[k];
        result[o + k] = encoded ? encode(v) : divisor == 1.0 ? v : float(double(v) / double(divisor));
    }
}
)";
}

}  // namespace

GlslFrameImport::GlslFrameImport(render::GlContext& context)
    : context_(context),
      colour_(context),
      albedo_(context),
      depth_(context),
      motion_(context),
      ids_(context),
      previousDepth_(context) {
    program_ = render::compileComputeProgram(context_.compute(), importShader(), "the frame import pass");
}

GlslFrameImport::~GlslFrameImport() {
    context_.gl().DeleteProgram(program_);
}

void GlslFrameImport::import(unsigned texture, int channels, bool encode, float divisor, GlslBuffer& out) {
    const render::GlFunctions& gl = context_.compute();
    const int width = frame_.width, height = frame_.height;
    out.ensure(size_t(width) * size_t(height) * size_t(channels));
    gl.UseProgram(program_);
    gl.ActiveTexture(GL_TEXTURE0);
    gl.BindTexture(GL_TEXTURE_2D, texture);
    gl.Uniform1i(gl.GetUniformLocation(program_, "image"), 0);
    gl.Uniform2i(gl.GetUniformLocation(program_, "size"), width, height);
    gl.Uniform1i(gl.GetUniformLocation(program_, "channels"), channels);
    gl.Uniform1i(gl.GetUniformLocation(program_, "encoded"), encode ? 1 : 0);
    gl.Uniform1f(gl.GetUniformLocation(program_, "divisor"), divisor);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, out.id());
    render::dispatchPass(context_, "import", width, height);
}

const GlslFrame& GlslFrameImport::run(const render::GpuBuffers& textures, int width, int height,
                                      BufferSet wanted, float depthFar) {
    frame_ = GlslFrame{};
    frame_.width = width, frame_.height = height;
    import(textures.colour, 3, true, 1.0f, colour_);
    frame_.colour = colour_.id();
    if (contains(wanted, Buffer::Albedo)) {
        import(textures.albedo, 3, true, 1.0f, albedo_);
        frame_.albedo = albedo_.id();
    }
    if (contains(wanted, Buffer::Depth)) {
        import(textures.depth, 1, false, depthFar, depth_);
        frame_.depth = depth_.id();
    }
    if (contains(wanted, Buffer::Motion)) {
        import(textures.motion, 2, false, 1.0f, motion_);
        frame_.motion = motion_.id();
    }
    if (contains(wanted, Buffer::Ids)) {
        import(textures.id, 1, false, 1.0f, ids_);
        frame_.ids = ids_.id();
    }
    if (contains(wanted, Buffer::PreviousDepth)) {
        import(textures.previousDepth, 1, false, depthFar, previousDepth_);
        frame_.previousDepth = previousDepth_.id();
    }
    return frame_;
}

GlslBuffer::~GlslBuffer() {
    if (buffer_) context_.gl().DeleteBuffers(1, &buffer_);
}

unsigned GlslBuffer::ensure(size_t floats) {
    const render::GlFunctions& gl = context_.compute();
    const size_t bytes = std::max<size_t>(floats, 1) * sizeof(float);
    if (!buffer_) gl.GenBuffers(1, &buffer_);
    if (bytes > bytes_) {
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffer_);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(bytes), nullptr, GL_DYNAMIC_COPY);
        bytes_ = bytes;
    }
    return buffer_;
}

namespace {

using nlohmann::json;

// One pass of a method's description: its shader, what each binding holds, its uniforms.
json passJson(const std::string& shader, const json& bindings, const json& uniforms,
              const std::string& grid) {
    return {{"shader", shader}, {"bindings", bindings}, {"uniforms", uniforms}, {"dispatch", grid}};
}

}  // namespace

GlslMethodFiles glslMethodFiles(const std::string& method, const FilterParameters& parameters) {
    const MethodSpec& spec =
        singleMethod(method, parameters, "is not one method: export a chain's methods one by one");
    MethodParameters view(spec, parameters);
    const std::string perPixel = "ceil(size / 8) work groups of 8 x 8, one invocation per pixel";
    const json sizeUniform = {{"size", "ivec2: the frame's width and height"}};
    GlslMethodFiles files;
    json& d = files.description;
    d["format"] = "dejag-glsl-1";
    d["method"] = method;
    d["layout"] =
        "storage buffers of float32, rows packed top row first; a frame (height, width, 3) interleaved R G "
        "B, "
        "sRGB-encoded in [0, 1]; depth and previous depth linear depth / far (height, width); motion "
        "(height, "
        "width, 2): pixels moved since the previous frame, +y down";
    d["between passes"] = "glMemoryBarrier(GL_SHADER_STORAGE_BARRIER_BIT)";
    if (method == "fxaa") {
        const FxaaOptions options = fxaaOptions(view);
        files.passes.push_back({"fxaa.comp", fxaaGlslSource(options, 3)});
        d["preset"] = options.preset;
        d["buffers"] = {{"frame", "the frame"}, {"result", "the frame anti-aliased"}};
        d["passes"] = {passJson("fxaa.comp", {{"1", "frame"}, {"4", "result"}}, sizeUniform, perPixel)};
    } else if (method == "smaa") {
        const SmaaOptions options = smaaOptions(view);
        const std::vector<std::string> sources = GlslSmaa::sources(options);
        const char* const names[3] = {"0_edges.comp", "1_weights.comp", "2_blending.comp"};
        for (int k = 0; k < 3; ++k) files.passes.push_back({names[k], sources[size_t(k)]});
        files.tables.push_back({"orthogonal_areas.bin", GlslSmaa::orthogonalAreas(options)});
        files.tables.push_back({"diagonal_areas.bin", GlslSmaa::diagonalAreas()});
        d["buffers"] = {{"frame", "the frame"},
                        {"edges", "int32 per pixel: bit 0 its left boundary, bit 1 its top"},
                        {"weights", "4 floats per pixel"},
                        {"orthogonal", "orthogonal_areas.bin, loaded once"},
                        {"diagonal", "diagonal_areas.bin, loaded once"},
                        {"result", "the frame anti-aliased"}};
        d["passes"] = {
            passJson(names[0], {{"1", "frame"}, {"2", "edges"}}, sizeUniform, perPixel),
            passJson(names[1], {{"2", "edges"}, {"3", "weights"}, {"5", "orthogonal"}, {"6", "diagonal"}},
                     sizeUniform, perPixel),
            passJson(names[2], {{"1", "frame"}, {"2", "edges"}, {"3", "weights"}, {"4", "result"}},
                     sizeUniform, perPixel)};
    } else if (method == "taa-hq") {
        const TaaHqOptions options = taaHqOptions(view);
        if (!options.jitterList.empty())
            throw Error("taa-hq's GPU form reads each frame's jitter (jitter=frames)");
        const std::vector<std::string> sources = GlslTaaHq::sources(options);
        const char* const names[3] = {"0_current.comp", "1_resolve.comp", "2_sharpen.comp"};
        for (int k = 0; k < 3; ++k)
            if (k < 2 || options.sharpen > 0) files.passes.push_back({names[k], sources[size_t(k)]});
        d["buffers"] = {
            {"colour", "the frame"},
            {"motion", "the motion"},
            {"depth",
             "optional, with previous depth (bind a 1-float buffer and set useDepth and haveDepth false)"},
            {"previous depth", "optional, the previous frame's depth"},
            {"current", "6 floats per pixel"},
            {"history A, history B",
             "4 floats per pixel each (linear R G B, the signed weight), used in turn"},
            {"unsharpened", "a frame, when the sharpen is on"},
            {"result", "the frame anti-aliased"}};
        const std::string resolveOut = options.sharpen > 0 ? "unsharpened" : "result";
        d["passes"] = {passJson(names[0], {{"1", "colour"}, {"2", "motion"}, {"5", "current"}},
                                {{"size", "ivec2: width, height"},
                                 {"shift",
                                  "ivec2: -floor(-jitter + 0.5) per axis, clamped to the size (jitter: the "
                                  "frame's image shift, pixels, +y down)"}},
                                perPixel),
                       passJson(names[1],
                                {{"3", "depth"},
                                 {"4", "previous depth"},
                                 {"5", "current"},
                                 {"6", "the history read (A on even frames)"},
                                 {"7", "the history written (B on even frames)"},
                                 {"0", resolveOut}},
                                {{"size", "ivec2: width, height"},
                                 {"fresh", "bool: the first frame of a history (a cut, a new size)"},
                                 {"useDepth", "bool: depth and previous depth bound"},
                                 {"haveDepth", "bool: depth bound"}},
                                perPixel)};
        if (options.sharpen > 0)
            d["passes"].push_back(
                passJson(names[2], {{"1", "unsharpened"}, {"0", "result"}}, sizeUniform, perPixel));
        d["between frames"] = "the history written is the next frame's history read";
    } else if (method == "taa" || method == "taa-sobel") {
        const TaaOptions options = taaOptions(view, method == "taa-sobel");
        const std::vector<std::string> sources = GlslTaa::sources(options);
        const char* const names[5] = {"0_current.comp", "1_sobel.comp", "2_sobel_taa.comp", "3_blend.comp",
                                      "4_sharpen.comp"};
        const bool sobel = options.improved;
        for (int k = 0; k < 5; ++k)
            if (!sources[size_t(k)].empty()) files.passes.push_back({names[k], sources[size_t(k)]});
        d["buffers"] = {{"colour", "the frame"},
                        {"albedo", "the albedo, sRGB-encoded (T-TAA)"},
                        {"depth", "the depth"},
                        {"motion", "the motion"},
                        {"ids", "object IDs, a float per pixel (T-TAA)"},
                        {"previous depth", "the previous frame's depth (T-TAA)"},
                        {"current", "5 floats per pixel"},
                        {"sobel", "1 float per pixel (T-TAA)"},
                        {"sobel history A, B", "1 float per pixel each, used in turn (T-TAA)"},
                        {"history A, B", "a frame each (unsharpened), used in turn"},
                        {"result", "the frame anti-aliased"}};
        const json fresh = {{"size", "ivec2: width, height"},
                            {"fresh", "bool: the first frame of a history (a cut, a new size)"}};
        d["passes"] = json::array();
        d["passes"].push_back(passJson(
            names[0], {{"1", "colour"}, {"2", "albedo (T-TAA)"}, {"5", "current"}},
            {{"size", "ivec2: width, height"},
             {"unjitter", "bool: the frame has a non-zero jitter (and unjitter is on)"},
             {"offset", "ivec2: floor(jitter)"},
             {"weights",
              "vec4: (1 - fx)(1 - fy), fx (1 - fy), (1 - fx) fy, fx fy of f = jitter - floor(jitter)"}},
            perPixel));
        if (sobel) {
            d["passes"].push_back(passJson(names[1], {{"3", "depth"}, {"5", "current"}, {"6", "sobel"}},
                                           sizeUniform, perPixel));
            d["passes"].push_back(passJson(names[2],
                                           {{"4", "motion"},
                                            {"6", "sobel"},
                                            {"7", "the Sobel history read (A on even frames)"},
                                            {"0", "the Sobel history written"}},
                                           fresh, perPixel));
        }
        d["passes"].push_back(passJson(names[3],
                                       {{"1", "ids (T-TAA)"},
                                        {"2", "previous depth (T-TAA)"},
                                        {"3", "depth"},
                                        {"4", "motion"},
                                        {"5", "current"},
                                        {"6", "the Sobel history written this frame (T-TAA)"},
                                        {"7", "the history read (A on even frames)"},
                                        {"0", "the history written"}},
                                       fresh, perPixel));
        d["passes"].push_back(
            passJson(names[4], {{"7", "the history written"}, {"0", "result"}}, sizeUniform, perPixel));
        d["between frames"] = "the histories written are the next frame's histories read";
    } else {
        throw Error("'" + method + "' has no GLSL export of its own: " +
                    (method == "cnn" || method == "cnn-temporal"
                         ? "export its network (dejag export --glsl MODEL)"
                         : "the method has no GPU form"));
    }
    requireParametersRead(spec, view, parameters);
    return files;
}

}  // namespace dejag::infer

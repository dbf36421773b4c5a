// FXAA 3.11 in GLSL: see infer/glsl_fxaa.h. The shader follows the CPU's scalar reference line by line
// (tests/infer/fxaa_reference.cpp is the oracle the SIMD kernels are checked against).
#include "infer/glsl_fxaa.h"

#include <sstream>
#include <vector>

#include "base/error.h"
#include "nn/glsl.h"

namespace dejag::infer {
namespace {

const char* const kBody = R"(
int at(int x, int y) {
    return (clamp(y, 0, size.y - 1) * size.x + clamp(x, 0, size.x - 1)) * CHANNELS;
}
float lumaAt(int x, int y) {
    int i = at(x, y);
    precise float l = GREEN ? frame[i + 1] : 0.299 * frame[i] + 0.587 * frame[i + 1] + 0.114 * frame[i + 2];
    return l;
}
float lumaBilinear(float x, float y) {
    precise float fx = x - 0.5, fy = y - 0.5;
    int x0 = int(floor(fx)), y0 = int(floor(fy));
    precise float tx = fx - float(x0), ty = fy - float(y0);
    float a = lumaAt(x0, y0), b = lumaAt(x0 + 1, y0), c = lumaAt(x0, y0 + 1), d = lumaAt(x0 + 1, y0 + 1);
    precise float top = a + tx * (b - a), bottom = c + tx * (d - c);
    precise float v = top + ty * (bottom - top);
    return v;
}
vec3 colourBilinear(float x, float y) {
    precise float fx = x - 0.5, fy = y - 0.5;
    int x0 = int(floor(fx)), y0 = int(floor(fy));
    precise float tx = fx - float(x0), ty = fy - float(y0);
    int a = at(x0, y0), b = at(x0 + 1, y0), c = at(x0, y0 + 1), d = at(x0 + 1, y0 + 1);
    precise vec3 rgb;
    for (int k = 0; k < 3; ++k) {
        precise float top = frame[a + k] + tx * (frame[b + k] - frame[a + k]);
        precise float bottom = frame[c + k] + tx * (frame[d + k] - frame[c + k]);
        rgb[k] = top + ty * (bottom - top);
    }
    return rgb;
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int x = p.x, y = p.y, self = at(x, y);
    for (int k = 0; k < CHANNELS; ++k) result[self + k] = frame[self + k];
    float lumaM = lumaAt(x, y);
    float lumaS = lumaAt(x, y + 1), lumaE = lumaAt(x + 1, y), lumaN = lumaAt(x, y - 1), lumaW = lumaAt(x - 1, y);
    precise float hi = max(max(max(lumaN, lumaS), max(lumaW, lumaE)), lumaM);
    precise float lo = min(min(min(lumaN, lumaS), min(lumaW, lumaE)), lumaM);
    precise float range = hi - lo;
    if (!(range >= max(EDGE_THRESHOLD_MIN, hi * EDGE_THRESHOLD))) return;
    float lumaNW = lumaAt(x - 1, y - 1), lumaSE = lumaAt(x + 1, y + 1), lumaNE = lumaAt(x + 1, y - 1),
          lumaSW = lumaAt(x - 1, y + 1);
    precise float lumaNS = lumaN + lumaS, lumaWE = lumaW + lumaE;
    precise float subpixRcpRange = 1.0 / range;
    precise float subpixNSWE = lumaNS + lumaWE;
    precise float edgeHorz1 = -2.0 * lumaM + lumaNS, edgeVert1 = -2.0 * lumaM + lumaWE;
    precise float lumaNESE = lumaNE + lumaSE, lumaNWNE = lumaNW + lumaNE;
    precise float edgeHorz2 = -2.0 * lumaE + lumaNESE, edgeVert2 = -2.0 * lumaN + lumaNWNE;
    precise float lumaNWSW = lumaNW + lumaSW, lumaSWSE = lumaSW + lumaSE;
    precise float edgeHorz4 = abs(edgeHorz1) * 2.0 + abs(edgeHorz2);
    precise float edgeVert4 = abs(edgeVert1) * 2.0 + abs(edgeVert2);
    precise float edgeHorz3 = -2.0 * lumaW + lumaNWSW, edgeVert3 = -2.0 * lumaS + lumaSWSE;
    precise float edgeHorz = abs(edgeHorz3) + edgeHorz4, edgeVert = abs(edgeVert3) + edgeVert4;
    precise float subpixNWSWNESE = lumaNWSW + lumaNESE;
    bool horzSpan = edgeHorz >= edgeVert;
    float lengthSign = 1.0;
    precise float subpixA = subpixNSWE * 2.0 + subpixNWSWNESE;
    if (!horzSpan) { lumaN = lumaW; lumaS = lumaE; }
    precise float subpixB = subpixA * (1.0 / 12.0) - lumaM;
    precise float gradientN = lumaN - lumaM, gradientS = lumaS - lumaM;
    precise float lumaNN = lumaN + lumaM;
    precise float lumaSS = lumaS + lumaM;
    bool pairN = abs(gradientN) >= abs(gradientS);
    float gradient = max(abs(gradientN), abs(gradientS));
    if (pairN) lengthSign = -lengthSign;
    precise float subpixC = clamp(abs(subpixB) * subpixRcpRange, 0.0, 1.0);
    precise float centreX = float(x) + 0.5, centreY = float(y) + 0.5;
    precise float bx = centreX, by = centreY;
    float offX = horzSpan ? 1.0 : 0.0, offY = horzSpan ? 0.0 : 1.0;
    if (!horzSpan) bx += lengthSign * 0.5;
    if (horzSpan) by += lengthSign * 0.5;
    precise float nx = bx - offX * STEPS[0], ny = by - offY * STEPS[0];
    precise float px = bx + offX * STEPS[0], py = by + offY * STEPS[0];
    precise float subpixD = -2.0 * subpixC + 3.0;
    precise float lumaEndN = lumaBilinear(nx, ny);
    precise float subpixE = subpixC * subpixC;
    precise float lumaEndP = lumaBilinear(px, py);
    if (!pairN) lumaNN = lumaSS;
    precise float gradientScaled = gradient * 0.25;
    precise float lumaMM = lumaM - lumaNN * 0.5;
    precise float subpixF = subpixD * subpixE;
    bool lumaMLTZero = lumaMM < 0.0;
    lumaEndN -= lumaNN * 0.5;
    lumaEndP -= lumaNN * 0.5;
    bool doneN = abs(lumaEndN) >= gradientScaled, doneP = abs(lumaEndP) >= gradientScaled;
    if (STEP_COUNT > 1) {
        if (!doneN) { nx -= offX * STEPS[1]; ny -= offY * STEPS[1]; }
        if (!doneP) { px += offX * STEPS[1]; py += offY * STEPS[1]; }
    }
    for (int i = 2; i < STEP_COUNT && (!doneN || !doneP); ++i) {
        if (!doneN) lumaEndN = lumaBilinear(nx, ny) - lumaNN * 0.5;
        if (!doneP) lumaEndP = lumaBilinear(px, py) - lumaNN * 0.5;
        doneN = abs(lumaEndN) >= gradientScaled;
        doneP = abs(lumaEndP) >= gradientScaled;
        if (!doneN) { nx -= offX * STEPS[i]; ny -= offY * STEPS[i]; }
        if (!doneP) { px += offX * STEPS[i]; py += offY * STEPS[i]; }
    }
    precise float dstN = horzSpan ? centreX - nx : centreY - ny;
    precise float dstP = horzSpan ? px - centreX : py - centreY;
    bool goodSpanN = (lumaEndN < 0.0) != lumaMLTZero;
    bool goodSpanP = (lumaEndP < 0.0) != lumaMLTZero;
    precise float spanLength = dstP + dstN;
    bool directionN = dstN < dstP;
    precise float dst = min(dstN, dstP);
    bool goodSpan = directionN ? goodSpanN : goodSpanP;
    precise float subpixG = subpixF * subpixF;
    precise float pixelOffset = dst * (-1.0 / spanLength) + 0.5;
    precise float subpixH = subpixG * SUBPIX;
    float pixelOffsetGood = goodSpan ? pixelOffset : 0.0;
    float pixelOffsetSubpix = max(pixelOffsetGood, subpixH);
    precise float sx = centreX, sy = centreY;
    if (!horzSpan) sx += pixelOffsetSubpix * lengthSign;
    if (horzSpan) sy += pixelOffsetSubpix * lengthSign;
    vec3 rgb = colourBilinear(sx, sy);
    result[self] = rgb.r;
    result[self + 1] = rgb.g;
    result[self + 2] = rgb.b;
}
)";

}  // namespace

std::string fxaaGlslSource(const FxaaOptions& options, int channels) {
    for (const float v : {options.subpix, options.edgeThreshold, options.edgeThresholdMin})
        if (!(v >= 0.0f && v <= 1.0f)) throw Error("FXAA: subpix and edge thresholds must be in [0, 1]");
    if (channels < 3) throw Error("FXAA needs an image with R, G, B channels");
    const std::vector<float> s = fxaaPresetSteps(options.preset);
    std::ostringstream src;
    src << "#version 430\n// dejag: FXAA 3.11, quality preset " << options.preset
        << " (infer/fxaa.h; docs/glsl.md)\nlayout(local_size_x = 8, local_size_y = 8) in;\n"
           "layout(std430, binding = 1) readonly buffer Frame { float frame[]; };\n"
           "layout(std430, binding = 4) writeonly buffer Result { float result[]; };\n"
           "uniform ivec2 size;  // width, height\n"
        << "const int CHANNELS = " << channels << ";\n"
        << "const bool GREEN = " << (options.greenAsLuma ? "true" : "false") << ";\n"
        << "const float EDGE_THRESHOLD = " << nn::glslFloat(options.edgeThreshold)
        << ", EDGE_THRESHOLD_MIN = " << nn::glslFloat(options.edgeThresholdMin)
        << ", SUBPIX = " << nn::glslFloat(options.subpix) << ";\nconst int STEP_COUNT = " << s.size()
        << ";\nconst float STEPS[STEP_COUNT] = float[](";
    for (size_t i = 0; i < s.size(); ++i) src << (i ? ", " : "") << nn::glslFloat(s[i]);
    src << ");\n" << kBody;
    return src.str();
}

GlslFxaa::GlslFxaa(render::GlContext& context, const FxaaOptions& options, int channels)
    : context_(context), channels_(channels) {
    const render::GlFunctions& gl = context_.compute();
    program_ = render::compileComputeProgram(gl, fxaaGlslSource(options, channels), "GLSL FXAA");
    gl.GenBuffers(2, buffers_);
}

GlslFxaa::~GlslFxaa() {
    const render::GlFunctions& gl = context_.gl();
    gl.DeleteBuffers(2, buffers_);
    gl.DeleteProgram(program_);
}

void GlslFxaa::apply(const float* in, float* out, int width, int height) {
    if (width < 1 || height < 1) throw Error("FXAA needs a non-empty image");
    const render::GlFunctions& gl = context_.compute();
    const size_t bytes = size_t(width) * size_t(height) * size_t(channels_) * sizeof(float);
    for (unsigned b : buffers_) {
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, b);
        if (bytes > capacity_)
            gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(bytes), nullptr, GL_DYNAMIC_COPY);
    }
    capacity_ = std::max(capacity_, bytes);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffers_[0]);
    gl.BufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(bytes), in);
    dispatch(buffers_[0], buffers_[1], width, height);
    gl.MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffers_[1]);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(bytes), out);
    if (const GLenum error = gl.GetError(); error != GL_NO_ERROR)
        throw Error("GLSL FXAA: OpenGL error " + std::to_string(error));
}

void GlslFxaa::dispatch(unsigned in, unsigned out, int width, int height) {
    if (width < 1 || height < 1) throw Error("FXAA needs a non-empty image");
    const render::GlFunctions& gl = context_.compute();
    gl.UseProgram(program_);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, in);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, out);
    gl.Uniform2i(gl.GetUniformLocation(program_, "size"), width, height);
    render::dispatchPass(context_, "fxaa", width, height);
}

}  // namespace dejag::infer

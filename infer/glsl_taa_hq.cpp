// taa-hq in GLSL: see infer/glsl_taa_hq.h. The passes follow infer/taa_hq_kernels.cpp's Band (the
// comments name its steps); the sRGB curves are its own (base/srgb.h's, degree 5 to decode, 6 to encode).
#include "infer/glsl_taa_hq.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "base/error.h"
#include "infer/glsl_srgb.h"
#include "nn/glsl.h"

namespace dejag::infer {
namespace {

constexpr const char* kCommon = R"(
layout(local_size_x = 8, local_size_y = 8) in;
uniform ivec2 size;
int clampedPixel(int x, int y) { return clamp(y, 0, size.y - 1) * size.x + clamp(x, 0, size.x - 1); }
)";

// The frame's in-pixel sample (pixel p + shift's) in linear light, the motion snapped to 0 below 1e-3 in
// both, and whether it moved (a motion that is not a number counts as moving).
constexpr const char* kPrepare = R"(
layout(std430, binding = 1) readonly buffer Colour { float colour[]; };
layout(std430, binding = 2) readonly buffer Motion { float motion[]; };
layout(std430, binding = 5) writeonly buffer Current { float current[]; };  // r g b, mx my, moved
uniform ivec2 shift;
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int i = p.y * size.x + p.x, s = clampedPixel(p.x + shift.x, p.y + shift.y);
    for (int k = 0; k < 3; ++k) current[6 * i + k] = decodeSrgb(colour[3 * s + k]);
    float mx = motion[2 * i], my = motion[2 * i + 1];
    bool none = abs(mx) < 1e-3 && abs(my) < 1e-3;
    current[6 * i + 3] = none ? 0.0 : mx;
    current[6 * i + 4] = none ? 0.0 : my;
    current[6 * i + 5] = none ? 0.0 : 1.0;
}
)";

// Steps 1-6 for one pixel.
constexpr const char* kResolve = R"(
layout(std430, binding = 3) readonly buffer Depth { float depth[]; };
layout(std430, binding = 4) readonly buffer PreviousDepth { float previousDepth[]; };
layout(std430, binding = 5) readonly buffer Current { float current[]; };
layout(std430, binding = 6) readonly buffer History { float history[]; };  // r g b, signed weight
layout(std430, binding = 7) writeonly buffer NextHistory { float nextHistory[]; };
layout(std430, binding = 0) writeonly buffer Result { float result[]; };
uniform bool fresh;
uniform bool useDepth;    // depth and the previous depth
uniform bool haveDepth;   // depth
vec3 ycocg(vec3 c) {
    precise float y = 0.25 * c.r + 0.5 * c.g + 0.25 * c.b, co = 0.5 * (c.r - c.b);
    precise float cg = -0.25 * c.r + 0.5 * c.g - 0.25 * c.b;
    return vec3(y, co, cg);
}
vec4 catmullRom(float t) {
    precise float t2 = t * t, t3 = t2 * t;
    precise float w0 = -0.5 * t3 + t2 - 0.5 * t, w1 = 1.5 * t3 - 2.5 * t2 + 1.0;
    precise float w2 = -1.5 * t3 + 2.0 * t2 + 0.5 * t, w3 = 0.5 * t3 - 0.5 * t2;
    return vec4(w0, w1, w2, w3);
}
// The history's R G B at pixel coordinates (hx, hy): 4x4 Catmull-Rom (or bilinear) deringed to the 2x2
// bilinear footprint's range.
vec3 resampleHistory(float hx, float hy) {
    precise float u = hx - 0.5, v = hy - 0.5;
    int ix = int(floor(u)), iy = int(floor(v));
    precise float fx = u - float(ix), fy = v - float(iy);
    vec4 wx, wy;
    if (CATMULL_ROM) {
        wx = catmullRom(fx);
        wy = catmullRom(fy);
    } else {
        precise float ax = 1.0 - fx, ay = 1.0 - fy;
        wx = vec4(0.0, ax, fx, 0.0);
        wy = vec4(0.0, ay, fy, 0.0);
    }
    precise vec3 acc = vec3(0.0);
    vec3 lo = vec3(1e30), hi = vec3(-1e30);
    for (int j = 0; j < 4; ++j) {
        vec3 t[4];
        for (int i = 0; i < 4; ++i) {
            int q = clampedPixel(ix - 1 + i, iy - 1 + j);
            t[i] = vec3(history[4 * q], history[4 * q + 1], history[4 * q + 2]);
        }
        precise vec3 horizontal = wx[0] * t[0] + wx[1] * t[1] + wx[2] * t[2] + wx[3] * t[3];
        acc = acc + wy[j] * horizontal;
        if (j == 1 || j == 2) {
            lo = min(lo, min(t[1], t[2]));
            hi = max(hi, max(t[1], t[2]));
        }
    }
    return clamp(acc, lo, hi);
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int x = p.x, y = p.y, i = y * size.x + x;
    // 1. The current sample, and whether anything moved in the 3x3 (the static lock's test).
    vec3 c = vec3(current[6 * i], current[6 * i + 1], current[6 * i + 2]);
    bool movedNow = false;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) movedNow = movedNow || current[6 * clampedPixel(x + dx, y + dy) + 5] > 0.5;
    // 2. Where the pixel was: the motion of the nearest surface in the 3x3 (none if none moved); the
    // 3x3's depth range.
    float vx = current[6 * i + 3], vy = current[6 * i + 4];
    float curLo = 0.0, curHi = 0.0;
    if (haveDepth && (movedNow || useDepth)) {
        float closest = depth[i];
        curLo = closest;
        curHi = closest;
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                int q = clampedPixel(x + dx, y + dy);
                float d = depth[q];
                if (movedNow && d < closest) {
                    closest = d;
                    vx = current[6 * q + 3];
                    vy = current[6 * q + 4];
                }
                curLo = min(curLo, d);
                curHi = max(curHi, d);
            }
    }
    precise float centreX = float(x) + 0.5, centreY = float(y) + 0.5;
    precise float hx = centreX - vx, hy = centreY - vy;
    bool valid = hx >= 0.0 && hy >= 0.0 && hx <= float(size.x) && hy <= float(size.y);
    float weight = 0.0;
    vec3 h = c;
    if (!fresh && valid) {
        int nx = clamp(int(hx), 0, size.x - 1), ny = clamp(int(hy), 0, size.y - 1);
        int n = ny * size.x + nx;
        float stored = history[4 * n + 3];
        weight = abs(stored);
        bool movedThen = stored < 0.0;
        // 3. Disocclusion: the previous 3x3's depths all nearer, or all farther, than the current 3x3's.
        if (useDepth) {
            float prevLo = 1e30, prevHi = -1e30;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx) {
                    float d = previousDepth[clampedPixel(nx + dx, ny + dy)];
                    prevLo = min(prevLo, d);
                    prevHi = max(prevHi, d);
                }
            precise float nearLimit = curLo * (1.0 - DEPTH_TOLERANCE), farLimit = curHi * (1.0 + DEPTH_TOLERANCE);
            if (prevHi < nearLimit || prevLo > farLimit) weight = 0.0;
        }
        if (weight > 0.0) {
            if (hx == float(nx) + 0.5 && hy == float(ny) + 0.5)
                h = vec3(history[4 * n], history[4 * n + 1], history[4 * n + 2]);  // on texels
            else
                h = resampleHistory(hx, hy);
            // 4. Variance clipping in YCoCg, except under the static lock.
            if (!STATIC_LOCK || movedNow || movedThen) {
                precise vec3 sum = vec3(0.0), sum2 = vec3(0.0);
                vec3 lo = vec3(1e9), hi = vec3(-1e9);
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        int q = clampedPixel(x + dx, y + dy);
                        vec3 v = ycocg(vec3(current[6 * q], current[6 * q + 1], current[6 * q + 2]));
                        sum = sum + v;
                        sum2 = sum2 + v * v;
                        lo = min(lo, v);
                        hi = max(hi, v);
                    }
                vec3 cur = ycocg(c), his = ycocg(h);
                precise vec3 mean = sum * NINTH;
                precise vec3 sigma = sqrt(max(vec3(0.0), sum2 * NINTH - mean * mean));
                precise vec3 boxLo = min(max(lo, mean - GAMMA * sigma), cur);
                precise vec3 boxHi = max(min(hi, mean + GAMMA * sigma), cur);
                precise vec3 centre = 0.5 * (boxLo + boxHi);
                precise vec3 extent = 0.5 * (boxHi - boxLo) + 1e-6;
                precise vec3 off = his - centre;
                precise vec3 ratio = abs(off) / extent;
                float a = max(max(max(0.0, ratio.x), ratio.y), ratio.z);
                if (a > 1.0) {
                    precise float shrink = 1.0 / a;
                    precise vec3 q = centre + off * shrink;
                    precise vec3 rgb = vec3(q.x + q.y - q.z, q.x + q.z, q.x - q.y - q.z);
                    h = rgb;
                    weight = min(weight, CLIPPED_WEIGHT);
                }
            }
        }
    }
    // 5. One more sample; the history moves toward it by 1 / weight.
    precise float grown = weight + 1.0;
    weight = min(grown, movedNow ? MOVING_MAX_WEIGHT : MAX_WEIGHT);
    precise float share = 1.0 / weight;
    precise vec3 next = h + share * (c - h);
    nextHistory[4 * i] = next.r;
    nextHistory[4 * i + 1] = next.g;
    nextHistory[4 * i + 2] = next.b;
    nextHistory[4 * i + 3] = movedNow ? -weight : weight;
    // 6. The output in sRGB.
    for (int k = 0; k < 3; ++k) result[3 * i + k] = encodeSrgb(next[k]);
}
)";

// The output-only sharpen: the cross's Laplacian, limited to the cross's range.
constexpr const char* kSharpen = R"(
layout(std430, binding = 1) readonly buffer Unsharpened { float unsharpened[]; };
layout(std430, binding = 0) writeonly buffer Result { float result[]; };
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int i = p.y * size.x + p.x;
    int around4[4] = int[](clampedPixel(p.x, p.y - 1), clampedPixel(p.x, p.y + 1), clampedPixel(p.x - 1, p.y),
                           clampedPixel(p.x + 1, p.y));
    for (int k = 0; k < 3; ++k) {
        float c = unsharpened[3 * i + k], lo = c, hi = c;
        precise float around = 0.0;
        for (int n = 0; n < 4; ++n) {
            float q = unsharpened[3 * around4[n] + k];
            lo = min(lo, q);
            hi = max(hi, q);
            around = around + q;
        }
        precise float s = c + SHARPEN * (c - 0.25 * around);
        result[3 * i + k] = clamp(s, lo, hi);
    }
}
)";

}  // namespace

std::vector<std::string> GlslTaaHq::sources(const TaaHqOptions& options) {
    TaaHq check(options);  // its range checks and their messages
    std::string constants = "#version 430\n// dejag: taa-hq (infer/taa_hq.h; docs/glsl.md)\n";
    constants += glslSrgbFunctions(5, 6);  // the CPU band kernel's degrees
    constants += "const float GAMMA = " + nn::glslFloat(options.clipGamma) +
                 ", NINTH = " + nn::glslFloat(1.0f / 9.0f) +
                 ", CLIPPED_WEIGHT = " + nn::glslFloat(options.clippedSamples) +
                 ", MAX_WEIGHT = " + nn::glslFloat(float(options.maxSamples)) + ", MOVING_MAX_WEIGHT = " +
                 nn::glslFloat(float(std::min(options.movingSamples, options.maxSamples))) +
                 ", DEPTH_TOLERANCE = " + nn::glslFloat(options.depthTolerance) +
                 ", SHARPEN = " + nn::glslFloat(options.sharpen) + ";\n";
    constants += std::string("const bool CATMULL_ROM = ") + (options.catmullRom ? "true" : "false") +
                 ", STATIC_LOCK = " + (options.staticLock ? "true" : "false") + ";\n";
    return {constants + kCommon + kPrepare, constants + kCommon + kResolve, constants + kCommon + kSharpen};
}

GlslTaaHq::GlslTaaHq(render::GlContext& context, const TaaHqOptions& options)
    : context_(context), options_(options) {
    const std::vector<std::string> passes = sources(options);
    const render::GlFunctions& gl = context_.compute();
    const char* const names[3] = {"GLSL taa-hq: the current sample", "GLSL taa-hq: the resolve",
                                  "GLSL taa-hq: the sharpen"};
    for (int k = 0; k < 3; ++k) programs_[k] = render::compileComputeProgram(gl, passes[size_t(k)], names[k]);
    unsigned buffers[5];
    gl.GenBuffers(5, buffers);
    current_ = buffers[0], history_[0] = buffers[1], history_[1] = buffers[2], unsharpened_ = buffers[3];
    empty_ = buffers[4];
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, empty_);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(sizeof(float)), nullptr, GL_STATIC_DRAW);
}

GlslTaaHq::~GlslTaaHq() {
    const render::GlFunctions& gl = context_.gl();
    const unsigned buffers[5] = {current_, history_[0], history_[1], unsharpened_, empty_};
    gl.DeleteBuffers(5, buffers);
    for (unsigned program : programs_) gl.DeleteProgram(program);
}

void GlslTaaHq::dispatch(unsigned colour, unsigned motion, unsigned depth, unsigned previousDepth,
                         float jitterX, float jitterY, unsigned out, int W, int H) {
    if (W < 1 || H < 1) throw Error("taa-hq needs a non-empty frame");
    if (!colour || !motion) throw Error("taa-hq needs the frame's motion");
    const render::GlFunctions& gl = context_.compute();
    const size_t pixels = size_t(W) * size_t(H);
    if (pixels > pixels_) {
        const size_t sizes[4] = {6 * pixels, 4 * pixels, 4 * pixels, 3 * pixels};
        const unsigned buffers[4] = {current_, history_[0], history_[1], unsharpened_};
        for (int k = 0; k < 4; ++k) {
            gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffers[k]);
            gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(sizes[k] * sizeof(float)), nullptr,
                          GL_DYNAMIC_COPY);
        }
        pixels_ = pixels;
    }
    const bool fresh = W != width_ || H != height_;
    if (fresh) width_ = W, height_ = H, frame_ = 0;
    if (!options_.jitterList.empty()) {
        const auto& j = options_.jitterList[size_t(frame_) % options_.jitterList.size()];
        jitterX = j.first, jitterY = j.second;
    }
    ++frame_;
    const int shiftX = std::clamp(-int(std::floor(-jitterX + 0.5f)), -W, W);
    const int shiftY = std::clamp(-int(std::floor(-jitterY + 0.5f)), -H, H);
    const bool useDepth = depth && previousDepth;
    const auto grid = [&](const char* pass) { render::dispatchPass(context_, pass, W, H); };
    // The current samples.
    gl.UseProgram(programs_[0]);
    gl.Uniform2i(gl.GetUniformLocation(programs_[0], "size"), W, H);
    gl.Uniform2i(gl.GetUniformLocation(programs_[0], "shift"), shiftX, shiftY);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, colour);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, motion);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, current_);
    grid("taa-hq current");
    // The resolve: the history read, the next written.
    const unsigned resolved = options_.sharpen > 0 ? unsharpened_ : out;
    gl.UseProgram(programs_[1]);
    gl.Uniform2i(gl.GetUniformLocation(programs_[1], "size"), W, H);
    gl.Uniform1i(gl.GetUniformLocation(programs_[1], "fresh"), fresh ? 1 : 0);
    gl.Uniform1i(gl.GetUniformLocation(programs_[1], "useDepth"), useDepth ? 1 : 0);
    gl.Uniform1i(gl.GetUniformLocation(programs_[1], "haveDepth"), depth ? 1 : 0);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, depth ? depth : empty_);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, useDepth ? previousDepth : empty_);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, current_);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, history_[read_]);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 7, history_[1 - read_]);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, resolved);
    grid("taa-hq resolve");
    read_ = 1 - read_;
    if (options_.sharpen > 0) {
        gl.UseProgram(programs_[2]);
        gl.Uniform2i(gl.GetUniformLocation(programs_[2], "size"), W, H);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, unsharpened_);
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 0, out);
        grid("taa-hq sharpen");
    }
}

}  // namespace dejag::infer

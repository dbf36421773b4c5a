// U-TAA and T-TAA in GLSL: see infer/glsl_taa.h. Each pass names the CPU kernel's function it follows.
#include "infer/glsl_taa.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "base/error.h"
#include "nn/glsl.h"

namespace dejag::infer {
namespace {

constexpr const char* kCommon = R"(
layout(local_size_x = 8, local_size_y = 8) in;
uniform ivec2 size;
int clampedPixel(int x, int y) { return clamp(y, 0, size.y - 1) * size.x + clamp(x, 0, size.x - 1); }
float clamp01(float v) { return min(max(v, 0.0), 1.0); }
float mixf(float a, float b, float t) {
    precise float v = a + (b - a) * t;
    return v;
}
float luma601(vec3 c) {
    precise float l = 0.299 * c.r + 0.587 * c.g + 0.114 * c.b;
    return l;
}
// History weight from the luma difference of current and history (docs/taa.md).
float feedback(float current, float history) {
    precise float d = abs(current - history) / max(max(current, history), 0.2);
    precise float w = (1.0 - d) * (1.0 - d);
    precise float k = FEEDBACK_MIN + FEEDBACK_SPAN * clamp01(w);
    return k;
}
)";

// rgbRow (un-jittered: bilinear at p + jitter, the weights made on the CPU) and, for T-TAA, the Rec. 601
// lumas of the albedo and of the un-jittered colour. current: r g b, albedo luma, colour luma.
constexpr const char* kCurrent = R"(
layout(std430, binding = 1) readonly buffer Colour { float colour[]; };
layout(std430, binding = 2) readonly buffer Albedo { float albedo[]; };
layout(std430, binding = 5) writeonly buffer Current { float current[]; };
uniform bool unjitter;
uniform ivec2 offset;  // floor(jitter)
uniform vec4 weights;  // w00, w01, w10, w11
vec3 unjittered(int x, int y, bool fromAlbedo) {
    if (!unjitter) {
        int i = 3 * (y * size.x + x);
        return fromAlbedo ? vec3(albedo[i], albedo[i + 1], albedo[i + 2]) : vec3(colour[i], colour[i + 1], colour[i + 2]);
    }
    int a = 3 * clampedPixel(x + offset.x, y + offset.y), b = 3 * clampedPixel(x + offset.x + 1, y + offset.y);
    int c = 3 * clampedPixel(x + offset.x, y + offset.y + 1), d = 3 * clampedPixel(x + offset.x + 1, y + offset.y + 1);
    precise vec3 v;
    for (int k = 0; k < 3; ++k) {
        if (fromAlbedo)
            v[k] = weights.x * albedo[a + k] + weights.y * albedo[b + k] + weights.z * albedo[c + k] + weights.w * albedo[d + k];
        else
            v[k] = weights.x * colour[a + k] + weights.y * colour[b + k] + weights.z * colour[c + k] + weights.w * colour[d + k];
    }
    return v;
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int i = p.y * size.x + p.x;
    vec3 c = unjittered(p.x, p.y, false);
    current[5 * i] = c.r;
    current[5 * i + 1] = c.g;
    current[5 * i + 2] = c.b;
    if (IMPROVED) {
        current[5 * i + 3] = luma601(unjittered(p.x, p.y, true));
        current[5 * i + 4] = luma601(c);
    }
}
)";

// sobelRow: g = clamp(0.3 Sobel(albedo luma) + 0.7 Sobel(luma) + Sobel(depth)), sobel = sqrt(g^2 (3 - 2g)).
constexpr const char* kSobel = R"(
layout(std430, binding = 3) readonly buffer Depth { float depth[]; };
layout(std430, binding = 5) readonly buffer Current { float current[]; };
layout(std430, binding = 6) writeonly buffer Sobel { float sobel[]; };
float tap(int which, int x, int y) {
    int q = clampedPixel(x, y);
    return which == 2 ? depth[q] : current[5 * q + 3 + which];
}
float sobelMagnitude(int which, int x, int y) {
    precise float gx = -tap(which, x - 1, y - 1) + tap(which, x + 1, y - 1) - 2.0 * tap(which, x - 1, y) +
                       2.0 * tap(which, x + 1, y) - tap(which, x - 1, y + 1) + tap(which, x + 1, y + 1);
    precise float gy = tap(which, x - 1, y - 1) + 2.0 * tap(which, x, y - 1) + tap(which, x + 1, y - 1) -
                       tap(which, x - 1, y + 1) - 2.0 * tap(which, x, y + 1) - tap(which, x + 1, y + 1);
    precise float m = sqrt(gx * gx + gy * gy);
    return m;
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    precise float sum = 0.3 * sobelMagnitude(0, p.x, p.y) + 0.7 * sobelMagnitude(1, p.x, p.y) + sobelMagnitude(2, p.x, p.y);
    float g = clamp01(sum);
    precise float s = sqrt(g * g * (3.0 - 2.0 * g));
    sobel[p.y * size.x + p.x] = s;
}
)";

// historyBilinear: a plane of `channels` interleaved values at pixel coordinates, clamp to edge.
constexpr const char* kBilinear = R"(
vec3 bilinear(int channels, float px, float py) {
    precise float fx = px - 0.5, fy = py - 0.5;
    int x0 = int(floor(fx)), y0 = int(floor(fy));
    precise float tx = fx - float(x0), ty = fy - float(y0);
    int a = clampedPixel(x0, y0), b = clampedPixel(x0 + 1, y0), c = clampedPixel(x0, y0 + 1), d = clampedPixel(x0 + 1, y0 + 1);
    precise vec3 v = vec3(0.0);
    for (int k = 0; k < channels; ++k) {
        float va = history[channels * a + k], vb = history[channels * b + k];
        float vc = history[channels * c + k], vd = history[channels * d + k];
        precise float top = va + tx * (vb - va), bottom = vc + tx * (vd - vc);
        v[k] = top + ty * (bottom - top);
    }
    return v;
}
)";

// stableSobelRow: the Sobel's own TAA, reprojected with the pixel's motion, clamped to the 3x3 box.
constexpr const char* kStableSobel = R"(
layout(std430, binding = 4) readonly buffer Motion { float motion[]; };
layout(std430, binding = 6) readonly buffer Sobel { float sobel[]; };
layout(std430, binding = 7) readonly buffer History { float history[]; };
layout(std430, binding = 0) writeonly buffer NextHistory { float nextHistory[]; };
uniform bool fresh;
)";
constexpr const char* kStableSobelMain = R"(
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int i = p.y * size.x + p.x;
    float current = sobel[i];
    if (fresh) {
        nextHistory[i] = current;
        return;
    }
    float lo = 1e30, hi = -1e30;
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            float v = sobel[clampedPixel(p.x + dx, p.y + dy)];
            lo = min(lo, v);
            hi = max(hi, v);
        }
    precise float px = float(p.x) + 0.5 - motion[2 * i], py = float(p.y) + 0.5 - motion[2 * i + 1];
    float previous = min(max(bilinear(1, px, py).x, lo), hi);
    float k = feedback(current, previous);
    precise float stable = current + (previous - current) * k;
    nextHistory[i] = stable;
}
)";

// blend: steps 1-5 of docs/taa.md.
constexpr const char* kBlend = R"(
layout(std430, binding = 1) readonly buffer Ids { float ids[]; };
layout(std430, binding = 2) readonly buffer PreviousDepth { float previousDepth[]; };
layout(std430, binding = 3) readonly buffer Depth { float depth[]; };
layout(std430, binding = 4) readonly buffer Motion { float motion[]; };
layout(std430, binding = 5) readonly buffer Current { float current[]; };
layout(std430, binding = 6) readonly buffer StableSobel { float stableSobel[]; };
layout(std430, binding = 7) readonly buffer History { float history[]; };
layout(std430, binding = 0) writeonly buffer NextHistory { float nextHistory[]; };
uniform bool fresh;
)";
constexpr const char* kBlendMain = R"(
vec3 colourAt(int x, int y) {
    int q = clampedPixel(x, y);
    return vec3(current[5 * q], current[5 * q + 1], current[5 * q + 2]);
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int x = p.x, y = p.y, i = y * size.x + x;
    // The colour box of the cross (centre and its 4 neighbours), then of all 9 taps.
    vec3 c = colourAt(x, y);
    vec3 minCross = c, maxCross = c;
    vec3 cross4[4] = vec3[](colourAt(x, y - 1), colourAt(x - 1, y), colourAt(x + 1, y), colourAt(x, y + 1));
    for (int n = 0; n < 4; ++n) {
        minCross = min(minCross, cross4[n]);
        maxCross = max(maxCross, cross4[n]);
    }
    vec3 min9 = minCross, max9 = maxCross;
    vec3 corners[4] = vec3[](colourAt(x - 1, y - 1), colourAt(x + 1, y - 1), colourAt(x - 1, y + 1), colourAt(x + 1, y + 1));
    for (int n = 0; n < 4; ++n) {
        min9 = min(min9, corners[n]);
        max9 = max(max9, corners[n]);
    }
    // 2. The velocity of the closest depth in the 3x3.
    float closest = 1e30, vx = motion[2 * i], vy = motion[2 * i + 1];
    for (int dy = -1; dy <= 1; ++dy)
        for (int dx = -1; dx <= 1; ++dx) {
            int q = clampedPixel(x + dx, y + dy);
            if (depth[q] < closest) {
                closest = depth[q];
                vx = motion[2 * q];
                vy = motion[2 * q + 1];
            }
        }
    precise float px = float(x) + 0.5 - vx, py = float(y) + 0.5 - vy;
    // 3. Reproject.
    vec3 previous = fresh ? c : bilinear(3, px, py);
    vec3 lo, hi;
    if (!IMPROVED) {
        precise vec3 l = (min9 + minCross) * 0.5, h = (max9 + maxCross) * 0.5;
        lo = l;
        hi = h;
    } else {
        // How aliased this pixel is: Sobel, model index, depth pseudo-variances.
        float sobelCentre = stableSobel[i], idCentre = ids[i];
        precise float sobel3x3 = 0.0, sobelCross = 0.0, different = 0.0, dsum = 0.0;
        float dmin = 1e30, dmax = -1e30;
        for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
                int q = clampedPixel(x + dx, y + dy);
                float s = stableSobel[q];
                sobel3x3 = sobel3x3 + s;
                if (dx == 0 || dy == 0) sobelCross = sobelCross + s;
                different = different + (ids[q] != idCentre ? 1.0 : 0.0);
                float d = depth[q];
                dmin = min(dmin, d);
                dmax = max(dmax, d);
                dsum = dsum + d;
            }
        sobel3x3 = sobel3x3 / 9.0;
        sobelCross = sobelCross / 5.0;
        precise float modelAverage = different / 9.0;
        precise float davg = dsum / 9.0;
        precise float maxDepthDistance = min(abs(dmin - davg), abs(dmax - davg));
        precise float depthPV = 0.0, depthTPV = 0.0;
        if (maxDepthDistance >= DEPTH_THRESHOLD) {
            precise float pv = abs(depth[i] - davg) / maxDepthDistance;
            float prior = previousDepth[clampedPixel(int(floor(px)), int(floor(py)))];
            precise float tpv = abs(prior - davg) / maxDepthDistance;
            depthPV = pv * pv;
            depthTPV = tpv * tpv * tpv * tpv;
        }
        float sobelAvgMixVal = clamp01(modelAverage + sobelCentre);
        float sobelAvg = mixf(sobelCross, sobel3x3, sobelAvgMixVal);
        precise float sum = sobelAvg + depthPV + depthTPV + modelAverage;
        float aliased = clamp01(sum);
        for (int k = 0; k < 3; ++k) {
            float colorMin = mixf(minCross[k], min9[k], aliased), colorMax = mixf(maxCross[k], max9[k], aliased);
            lo[k] = mixf(c[k], colorMin, aliased);
            hi[k] = mixf(c[k], colorMax, aliased);
        }
    }
    // 4. Clip towards the box centre (INSIDE's clip_aabb), 5. blend with the luminance feedback.
    precise vec3 centre = (lo + hi) * 0.5;
    precise vec3 inverseExtent = 1.0 / ((hi - lo) * 0.5 + 1e-6);
    precise vec3 offset = previous - centre;
    precise vec3 ratio = abs(offset * inverseExtent);
    float unit = max(max(max(0.0, ratio.x), ratio.y), ratio.z);
    vec3 clipped = previous;
    if (unit > 1.0) {
        precise float shrink = 1.0 / unit;
        precise vec3 q = centre + offset * shrink;
        clipped = q;
    }
    float k = 0.0;
    if (!fresh) {
        precise float lc = 0.25 * c.r + 0.5 * c.g + 0.25 * c.b, lh = 0.25 * clipped.r + 0.5 * clipped.g + 0.25 * clipped.b;
        k = feedback(lc, lh);
    }
    for (int n = 0; n < 3; ++n) nextHistory[3 * i + n] = mixf(c[n], clipped[n], k);
}
)";

// sharpenRow: 6. the blended frame sharpened (U-TAA 5 / -1, T-TAA 2 / -0.25), clamped to [0, 1].
constexpr const char* kSharpen = R"(
layout(std430, binding = 7) readonly buffer Blended { float blended[]; };
layout(std430, binding = 0) writeonly buffer Result { float result[]; };
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int i = p.y * size.x + p.x;
    int l = clampedPixel(p.x - 1, p.y), r = clampedPixel(p.x + 1, p.y), t = clampedPixel(p.x, p.y - 1),
        b = clampedPixel(p.x, p.y + 1);
    for (int k = 0; k < 3; ++k) {
        float c = blended[3 * i + k];
        precise float s = c;
        if (SHARPEN)
            s = c * CENTRE_WEIGHT + (blended[3 * l + k] + blended[3 * r + k] + blended[3 * t + k] + blended[3 * b + k]) * SIDE_WEIGHT;
        result[3 * i + k] = clamp01(s);
    }
}
)";

}  // namespace

std::vector<std::string> GlslTaa::sources(const TaaOptions& options) {
    Taa check(options);  // its range checks and their messages
    if (options.motionBlur) throw Error("TAA's motion blur has no GPU form (motion-blur=false)");
    const bool improved = options.improved;
    std::string constants = "#version 430\n// dejag: " + std::string(improved ? "T-TAA" : "U-TAA") +
                            " (infer/taa.h; docs/glsl.md)\n";
    constants += std::string("const bool IMPROVED = ") + (improved ? "true" : "false") +
                 ", SHARPEN = " + (options.sharpen ? "true" : "false") + ";\n";
    constants += "const float FEEDBACK_MIN = " + nn::glslFloat(options.feedbackMin) +
                 ", FEEDBACK_SPAN = " + nn::glslFloat(options.feedbackMax - options.feedbackMin) +
                 ", DEPTH_THRESHOLD = " + nn::glslFloat(options.depthThreshold) +
                 ", CENTRE_WEIGHT = " + nn::glslFloat(improved ? 2.0f : 5.0f) +
                 ", SIDE_WEIGHT = " + nn::glslFloat(improved ? -0.25f : -1.0f) + ";\n";
    const bool sobel = options.improved;
    return {constants + kCommon + kCurrent, sobel ? constants + kCommon + kSobel : "",
            sobel ? constants + kCommon + kStableSobel + kBilinear + kStableSobelMain : "",
            constants + kCommon + kBlend + kBilinear + kBlendMain, constants + kCommon + kSharpen};
}

GlslTaa::GlslTaa(render::GlContext& context, const TaaOptions& options)
    : context_(context), options_(options) {
    const bool improved = options.improved;
    const std::vector<std::string> sources = GlslTaa::sources(options);
    const render::GlFunctions& gl = context_.compute();
    const char* const names[5] = {"GLSL TAA: the current frame", "GLSL TAA: the Sobel",
                                  "GLSL TAA: the Sobel's TAA", "GLSL TAA: the blend",
                                  "GLSL TAA: the sharpen"};
    for (int k = 0; k < 5; ++k)
        if (improved || (k != 1 && k != 2))
            programs_[k] = render::compileComputeProgram(gl, sources[size_t(k)], names[k]);
    unsigned buffers[8];
    gl.GenBuffers(8, buffers);
    current_ = buffers[0], sobel_ = buffers[1], sobelHistory_[0] = buffers[2], sobelHistory_[1] = buffers[3];
    history_[0] = buffers[4], history_[1] = buffers[5], blended_ = buffers[6], empty_ = buffers[7];
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, empty_);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(sizeof(float)), nullptr, GL_STATIC_DRAW);
}

GlslTaa::~GlslTaa() {
    const render::GlFunctions& gl = context_.gl();
    const unsigned buffers[8] = {current_,    sobel_,      sobelHistory_[0], sobelHistory_[1],
                                 history_[0], history_[1], blended_,         empty_};
    gl.DeleteBuffers(8, buffers);
    for (unsigned program : programs_)
        if (program) gl.DeleteProgram(program);
}

void GlslTaa::dispatch(const TaaFrame& f, unsigned colour, unsigned albedo, unsigned depth, unsigned motion,
                       unsigned ids, unsigned previousDepth, unsigned out) {
    const int W = f.width, H = f.height;
    if (W < 1 || H < 1 || !colour || !depth || !motion)
        throw Error("TAA needs colour, depth and motion buffers");
    const bool improved = options_.improved;
    if (improved && (!albedo || !ids || !previousDepth))
        throw Error("the Sobel-improved TAA needs albedo, IDs and the previous depth too");
    const render::GlFunctions& gl = context_.compute();
    const size_t pixels = size_t(W) * size_t(H);
    if (pixels > pixels_) {
        const size_t sizes[6] = {5 * pixels, pixels, pixels, pixels, 3 * pixels, 3 * pixels};
        const unsigned buffers[6] = {current_,         sobel_,      sobelHistory_[0],
                                     sobelHistory_[1], history_[0], history_[1]};
        for (int k = 0; k < 6; ++k) {
            gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffers[k]);
            gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(sizes[k] * sizeof(float)), nullptr,
                          GL_DYNAMIC_COPY);
        }
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, blended_);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(3 * pixels * sizeof(float)), nullptr,
                      GL_DYNAMIC_COPY);
        pixels_ = pixels;
    }
    const bool fresh = W != width_ || H != height_;
    if (fresh) width_ = W, height_ = H;
    // As Taa::apply decides it: a jitter that is not a number, or none, is not un-jittered.
    const bool unjitter = options_.unjitter && f.hasJitter && std::isfinite(f.jitter[0]) &&
                          std::isfinite(f.jitter[1]) && (f.jitter[0] != 0 || f.jitter[1] != 0);
    const float jx = unjitter ? std::clamp(f.jitter[0], -float(W), float(W)) : 0.0f;
    const float jy = unjitter ? std::clamp(f.jitter[1], -float(H), float(H)) : 0.0f;
    const int ix = int(std::floor(jx)), iy = int(std::floor(jy));
    const float fx = jx - float(ix), fy = jy - float(iy);
    const float w00 = (1 - fx) * (1 - fy), w01 = fx * (1 - fy), w10 = (1 - fx) * fy, w11 = fx * fy;
    int pass = 0;
    const auto use = [&](int k) {
        pass = k;
        gl.UseProgram(programs_[k]);
        gl.Uniform2i(gl.GetUniformLocation(programs_[k], "size"), W, H);
    };
    const char* const passNames[5] = {"taa current", "taa sobel", "taa sobel history", "taa blend",
                                      "taa sharpen"};
    const auto grid = [&] { render::dispatchPass(context_, passNames[pass], W, H); };
    const auto bind = [&](unsigned binding, unsigned buffer) {
        gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, binding, buffer ? buffer : empty_);
    };
    use(0);
    gl.Uniform1i(gl.GetUniformLocation(programs_[0], "unjitter"), unjitter ? 1 : 0);
    gl.Uniform2i(gl.GetUniformLocation(programs_[0], "offset"), ix, iy);
    gl.Uniform4f(gl.GetUniformLocation(programs_[0], "weights"), w00, w01, w10, w11);
    bind(1, colour), bind(2, improved ? albedo : 0), bind(5, current_);
    grid();
    if (improved) {
        use(1);
        bind(3, depth), bind(5, current_), bind(6, sobel_);
        grid();
        use(2);
        gl.Uniform1i(gl.GetUniformLocation(programs_[2], "fresh"), fresh ? 1 : 0);
        bind(4, motion), bind(6, sobel_), bind(7, sobelHistory_[read_]), bind(0, sobelHistory_[1 - read_]);
        grid();
    }
    use(3);
    gl.Uniform1i(gl.GetUniformLocation(programs_[3], "fresh"), fresh ? 1 : 0);
    bind(1, improved ? ids : 0), bind(2, improved ? previousDepth : 0), bind(3, depth), bind(4, motion);
    bind(5, current_), bind(6, improved ? sobelHistory_[1 - read_] : 0), bind(7, history_[read_]);
    bind(0, history_[1 - read_]);
    grid();
    use(4);
    bind(7, history_[1 - read_]), bind(0, out);
    grid();
    read_ = 1 - read_;
}

}  // namespace dejag::infer

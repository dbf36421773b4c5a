// SMAA in GLSL: see infer/glsl_smaa.h. Each pass follows the CPU code it names (infer/smaa.cpp,
// infer/smaa_kernels.cpp): the edges of smaaEdgeRow, the weights of WeightSearch, the blending of
// smaaBlendRow.
#include "infer/glsl_smaa.h"

#include <algorithm>
#include <vector>

#include "base/error.h"
#include "infer/glsl_srgb.h"
#include "infer/smaa_area.h"
#include "nn/glsl.h"

namespace dejag::infer {
namespace {

constexpr const char* kHeader = R"(
layout(local_size_x = 8, local_size_y = 8) in;
layout(std430, binding = 1) readonly buffer Frame { float frame[]; };
layout(std430, binding = 2) buffer Edges { int edges[]; };
layout(std430, binding = 3) buffer Weights { float weights[]; };
layout(std430, binding = 4) writeonly buffer Result { float result[]; };
layout(std430, binding = 5) readonly buffer Orthogonal { float orthogonal[]; };
layout(std430, binding = 6) readonly buffer Diagonal { float diagonal[]; };
uniform ivec2 size;
// The edges of (x, y): bit 0 its left boundary, bit 1 its top; none outside the frame.
int at(int x, int y) {
    return (x < 0 || y < 0 || x >= size.x || y >= size.y) ? 0 : edges[y * size.x + x];
}
int leftEdge(int x, int y) { return at(x, y) & 1; }
int topEdge(int x, int y) { return at(x, y) >> 1; }
int frameAt(int x, int y) {
    return (clamp(y, 0, size.y - 1) * size.x + clamp(x, 0, size.x - 1)) * 3;
}
)";

// Pass 1: smaaEdgeRow (and smaaLumaRow's luma, clamped to the frame).
constexpr const char* kEdges = R"(
float lumaAt(int x, int y) {
    int i = frameAt(x, y);
    precise float l = LUMA_R * frame[i] + LUMA_G * frame[i + 1] + LUMA_B * frame[i + 2];
    return l;
}
float colourStep(int p, int q) {
    return max(max(abs(frame[p] - frame[q]), abs(frame[p + 1] - frame[q + 1])), abs(frame[p + 2] - frame[q + 2]));
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int x = p.x, y = p.y;
    precise float dl, dt, dr, db, dll, dtt;
    if (COLOUR_EDGES) {
        int c = frameAt(x, y), l = frameAt(x - 1, y), t = frameAt(x, y - 1);
        dl = colourStep(c, l);
        dt = colourStep(c, t);
        dr = colourStep(c, frameAt(x + 1, y));
        db = colourStep(c, frameAt(x, y + 1));
        dll = colourStep(l, frameAt(x - 2, y));
        dtt = colourStep(t, frameAt(x, y - 2));
    } else {
        float L = lumaAt(x, y), Ll = lumaAt(x - 1, y), Lt = lumaAt(x, y - 1);
        dl = abs(L - Ll);
        dt = abs(L - Lt);
        dr = abs(L - lumaAt(x + 1, y));
        db = abs(L - lumaAt(x, y + 1));
        dll = abs(Ll - lumaAt(x - 2, y));
        dtt = abs(Lt - lumaAt(x, y - 2));
    }
    bool el = dl >= THRESHOLD, et = dt >= THRESHOLD;
    int bits = 0;
    if (el || et) {
        float m = max(max(max(dl, dr), dll), max(max(dt, db), dtt));
        precise float twiceLeft = 2.0 * dl, twiceTop = 2.0 * dt;
        bits = int(el && twiceLeft >= m) | (int(et && twiceTop >= m) << 1);
    }
    edges[y * size.x + x] = bits;
}
)";

// Pass 2: WeightSearch::weights for each pixel with an edge.
constexpr const char* kWeights = R"(
void corners(int d1, int d2, int nearBeyond1, int nearBeyond2, int farBeyond1, int farBeyond2, inout vec2 w) {
    if (!CORNERS) return;
    float n1 = d1 <= d2 ? 1.0 : 0.0, n2 = d2 <= d1 ? 1.0 : 0.0;
    precise float k = ROUNDING_KEEP / (n1 + n2);
    precise float nearFactor = 1.0 - k * n1 * float(nearBeyond1) - k * n2 * float(nearBeyond2);
    precise float farFactor = 1.0 - k * n1 * float(farBeyond1) - k * n2 * float(farBeyond2);
    precise float a = w.x * clamp(nearFactor, 0.0, 1.0), b = w.y * clamp(farFactor, 0.0, 1.0);
    w = vec2(a, b);
}
vec2 orthogonalArea(int pattern, int d1, int d2) {
    int i = ((pattern * AREA_SIDE + d1) * AREA_SIDE + d2) * 2;
    return vec2(orthogonal[i], orthogonal[i + 1]);
}
vec2 horizontalWeights(int x, int y) {
    int l = x, r = x;
    while (x - l < REACH - 1 && (at(l - 1, y) & 2) != 0 && ((at(l, y) | at(l, y - 1)) & 1) == 0) --l;
    while (r - x < REACH && (at(r + 1, y) & 2) != 0 && ((at(r + 1, y) | at(r + 1, y - 1)) & 1) == 0) ++r;
    int pattern = leftEdge(l, y) | leftEdge(r + 1, y) << 1 | leftEdge(l, y - 1) << 2 | leftEdge(r + 1, y - 1) << 3;
    vec2 w = orthogonalArea(pattern, x - l, r - x);
    corners(x - l, r - x, leftEdge(l, y + 1), leftEdge(r + 1, y + 1), leftEdge(l, y - 2), leftEdge(r + 1, y - 2), w);
    return w;
}
vec2 verticalWeights(int x, int y) {
    int t = y, b = y;
    while (y - t < REACH - 1 && (at(x, t - 1) & 1) != 0 && (((at(x, t) | at(x - 1, t)) >> 1) & 1) == 0) --t;
    while (b - y < REACH && (at(x, b + 1) & 1) != 0 && (((at(x, b + 1) | at(x - 1, b + 1)) >> 1) & 1) == 0) ++b;
    int pattern = topEdge(x, t) | topEdge(x, b + 1) << 1 | topEdge(x - 1, t) << 2 | topEdge(x - 1, b + 1) << 3;
    vec2 w = orthogonalArea(pattern, y - t, b - y);
    corners(y - t, b - y, topEdge(x + 1, t), topEdge(x + 1, b + 1), topEdge(x - 2, t), topEdge(x - 2, b + 1), w);
    return w;
}
// (steps, ended): pixels of the diagonal found beyond the start, and whether its end was found.
ivec2 searchDiagonal(int x, int y, int dx, int dy, bool second, bool countTopEnd) {
    int steps = -1, both = 1, lastTop = 0;
    while (steps < DIAGONAL_STEPS - 1 && both != 0) {
        x += dx;
        y += dy;
        ++steps;
        int t = topEdge(x, y), l = second ? leftEdge(x + 1, y) : leftEdge(x, y);
        both = t & l;
        lastTop = t;
    }
    if (countTopEnd && lastTop != 0) ++steps;
    return ivec2(steps, both == 0 ? 1 : 0);
}
vec2 diagonalAreas(int c1, int c2, int d1, int d2) {
    int pattern = (c1 & 1) | (c2 & 2) | (c1 & 2) << 1 | (c2 & 1) << 3;
    int i = ((pattern * DIAGONAL_MAX + min(d1, DIAGONAL_MAX - 1)) * DIAGONAL_MAX + min(d2, DIAGONAL_MAX - 1)) * 2;
    return vec2(diagonal[i], diagonal[i + 1]);
}
vec2 diagonalWeights(int x, int y, int e) {
    precise vec2 w = vec2(0.0);
    ivec2 a = ivec2(0, 1);
    if ((e & 1) != 0) a = searchDiagonal(x, y, -1, 1, false, true);
    ivec2 b = searchDiagonal(x, y, 1, -1, false, false);
    if (a.x + b.x > 2) {
        int c1 = 2 * topEdge(x - a.x - 1, y + a.x) + leftEdge(x - a.x, y + a.x);
        int c2 = 2 * topEdge(x + b.x + 1, y - b.x) + leftEdge(x + b.x + 1, y - b.x - 1);
        if (a.y == 0) c1 = 0;
        if (b.y == 0) c2 = 0;
        vec2 area = diagonalAreas(c1, c2, a.x, b.x);
        w += area;
    }
    a = searchDiagonal(x, y, -1, -1, true, false);
    b = ivec2(0, 1);
    if (leftEdge(x + 1, y) != 0) b = searchDiagonal(x, y, 1, 1, true, true);
    if (a.x + b.x > 2) {
        int c1 = 2 * topEdge(x - a.x - 1, y - a.x) + leftEdge(x - a.x, y - a.x - 1);
        int c2 = 2 * topEdge(x + b.x + 1, y + b.x) + leftEdge(x + b.x + 1, y + b.x);
        if (a.y == 0) c1 = 0;
        if (b.y == 0) c2 = 0;
        vec2 area = diagonalAreas(c1, c2, a.x, b.x);
        w += area.yx;
    }
    return w;
}
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int x = p.x, y = p.y, e = at(x, y);
    if (e == 0) return;
    vec2 h = vec2(0.0), v = vec2(0.0);
    bool vertical = (e & 1) != 0;
    if ((e & 2) != 0) {
        if (DIAGONAL_STEPS > 0) h = diagonalWeights(x, y, e);
        precise float sum = h.x + h.y;
        if (sum == 0.0) {
            h = horizontalWeights(x, y);
        } else {
            vertical = false;  // a diagonal takes both edges of the pixel
        }
    }
    if (vertical) v = verticalWeights(x, y);
    int o = 4 * (y * size.x + x);
    weights[o] = h.x;
    weights[o + 1] = h.y;
    weights[o + 2] = v.x;
    weights[o + 3] = v.y;
}
)";

// Pass 3: smaaBlendRow.
constexpr const char* kBlend = R"(
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= size.x || p.y >= size.y) return;
    int x = p.x, y = p.y, self = (y * size.x + x) * 3;
    float toTop = 0.0, toLeft = 0.0, toRight = 0.0, toBottom = 0.0;
    if (at(x, y) != 0) {
        toTop = weights[4 * (y * size.x + x)];
        toLeft = weights[4 * (y * size.x + x) + 2];
    }
    if (at(x + 1, y) != 0) toRight = weights[4 * (y * size.x + x + 1) + 3];
    if (at(x, y + 1) != 0) toBottom = weights[4 * ((y + 1) * size.x + x) + 1];
    precise float total = toTop + toLeft + toRight + toBottom;
    if (total < 1e-5) {
        for (int k = 0; k < 3; ++k) result[self + k] = frame[self + k];
        return;
    }
    float a1, a2;
    int n1, n2;
    if (max(toRight, toLeft) > max(toBottom, toTop)) {
        a1 = toRight;
        a2 = toLeft;
        n1 = self + (x + 1 < size.x ? 3 : 0);
        n2 = self - (x > 0 ? 3 : 0);
    } else {
        a1 = toBottom;
        a2 = toTop;
        n1 = self + (y + 1 < size.y ? 3 * size.x : 0);
        n2 = self - (y > 0 ? 3 * size.x : 0);
    }
    precise float scale = 1.0 / (a1 + a2);
    for (int k = 0; k < 3; ++k) {
        float v0 = frame[self + k], v1 = frame[n1 + k], v2 = frame[n2 + k];
        if (LINEAR) {
            v0 = decodeSrgb(v0);
            v1 = decodeSrgb(v1);
            v2 = decodeSrgb(v2);
        }
        precise float v = (a1 * (v0 + (v1 - v0) * a1) + a2 * (v0 + (v2 - v0) * a2)) * scale;
        result[self + k] = LINEAR ? encodeSrgb(v) : v;
    }
}
)";

}  // namespace

std::vector<std::string> GlslSmaa::sources(const SmaaOptions& options) {
    Smaa check(options);  // its range checks and their messages
    if (options.predication)
        throw Error("SMAA with predication needs depth, which a GPU frame does not carry");
    const int reach = 2 * options.searchSteps, side = reach + 1;
    std::string constants = "#version 430\n// dejag: SMAA 1x (infer/smaa.h; docs/glsl.md)\n";
    constants += "const float THRESHOLD = " + nn::glslFloat(options.threshold) + ";\n";
    constants +=
        "const bool COLOUR_EDGES = " + std::string(options.edges == SmaaEdges::Colour ? "true" : "false") +
        ";\nconst float LUMA_R = " + nn::glslFloat(0.2126f) + ", LUMA_G = " + nn::glslFloat(0.7152f) +
        ", LUMA_B = " + nn::glslFloat(0.0722f) + ";\n";
    constants += "const int REACH = " + std::to_string(reach) + ", AREA_SIDE = " + std::to_string(side) +
                 ", DIAGONAL_STEPS = " + std::to_string(options.diagonalSteps) +
                 ", DIAGONAL_MAX = " + std::to_string(kSmaaDiagonalMax) + ";\n";
    constants +=
        "const bool CORNERS = " + std::string(options.cornerRounding < 100 ? "true" : "false") +
        ";\nconst float ROUNDING_KEEP = " + nn::glslFloat(1.0f - float(options.cornerRounding) / 100.0f) +
        ";\n";
    constants += "const bool LINEAR = " + std::string(options.linearBlending ? "true" : "false") + ";\n";
    constants += glslSrgbFunctions(7, 7);
    return {constants + kHeader + kEdges, constants + kHeader + kWeights, constants + kHeader + kBlend};
}

std::vector<float> GlslSmaa::orthogonalAreas(const SmaaOptions& options) {
    // For every distance a search can report, each way.
    const int side = 2 * options.searchSteps + 1;
    std::vector<float> orthogonal(size_t(16) * side * side * 2, 0.0f);
    for (int pattern = 0; pattern < 16; ++pattern)
        for (int l = 0; l < side; ++l)
            for (int r = 0; r < side; ++r) {
                const auto a = smaaOrthogonalArea(pattern, l, r);
                const size_t i = ((size_t(pattern) * side + size_t(l)) * side + size_t(r)) * 2;
                orthogonal[i] = a[0], orthogonal[i + 1] = a[1];
            }
    return orthogonal;
}

std::vector<float> GlslSmaa::diagonalAreas() {
    const float* table = smaaDiagonalAreaTable();
    return std::vector<float>(table, table + size_t(16) * kSmaaDiagonalMax * kSmaaDiagonalMax * 2);
}

GlslSmaa::GlslSmaa(render::GlContext& context, const SmaaOptions& options)
    : context_(context), options_(options) {
    const std::vector<std::string> passes = sources(options);
    const render::GlFunctions& gl = context_.compute();
    const char* const names[3] = {"GLSL SMAA: edges", "GLSL SMAA: weights", "GLSL SMAA: blending"};
    for (int i = 0; i < 3; ++i) programs_[i] = render::compileComputeProgram(gl, passes[size_t(i)], names[i]);
    const std::vector<float> orthogonal = orthogonalAreas(options), diagonal = diagonalAreas();
    unsigned buffers[4];
    gl.GenBuffers(4, buffers);
    edges_ = buffers[0], weights_ = buffers[1], orthogonal_ = buffers[2], diagonal_ = buffers[3];
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, orthogonal_);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(orthogonal.size() * sizeof(float)), orthogonal.data(),
                  GL_STATIC_DRAW);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, diagonal_);
    gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(diagonal.size() * sizeof(float)), diagonal.data(),
                  GL_STATIC_DRAW);
}

GlslSmaa::~GlslSmaa() {
    const render::GlFunctions& gl = context_.gl();
    const unsigned buffers[4] = {edges_, weights_, orthogonal_, diagonal_};
    gl.DeleteBuffers(4, buffers);
    for (unsigned program : programs_) gl.DeleteProgram(program);
}

void GlslSmaa::dispatch(unsigned in, unsigned out, int width, int height) {
    if (width < 1 || height < 1) throw Error("SMAA needs a non-empty image");
    const render::GlFunctions& gl = context_.compute();
    const size_t pixels = size_t(width) * size_t(height);
    if (pixels > pixels_) {
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, edges_);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(pixels * sizeof(int)), nullptr, GL_DYNAMIC_COPY);
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, weights_);
        gl.BufferData(GL_SHADER_STORAGE_BUFFER, GLsizeiptr(4 * pixels * sizeof(float)), nullptr,
                      GL_DYNAMIC_COPY);
        pixels_ = pixels;
    }
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 1, in);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 2, edges_);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 3, weights_);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 4, out);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 5, orthogonal_);
    gl.BindBufferBase(GL_SHADER_STORAGE_BUFFER, 6, diagonal_);
    const char* const names[3] = {"smaa edges", "smaa weights", "smaa blending"};
    for (int k = 0; k < 3; ++k) {
        gl.UseProgram(programs_[k]);
        gl.Uniform2i(gl.GetUniformLocation(programs_[k], "size"), width, height);
        render::dispatchPass(context_, names[k], width, height);
    }
}

}  // namespace dejag::infer

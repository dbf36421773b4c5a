#include "render/renderer.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <sstream>

#include "base/error.h"
#include "base/timer.h"
#include "render/fourier_texture.h"
#include "render/halton.h"

namespace dejag::render {

namespace {

constexpr const char* kSceneVertexShader = R"(#version 330 core
layout(location = 0) in vec3 inPosition;
layout(location = 1) in vec3 inNormal;
layout(location = 2) in vec2 inUv;
uniform mat4 uModel;
uniform mat4 uView;
uniform mat4 uJitteredProjection;
uniform mat4 uViewProjection;          // unjittered, this frame
uniform mat4 uPreviousModelViewProjection;  // unjittered, previous frame
out vec3 vWorldPosition;
out vec3 vNormal;
out vec2 vUv;
out vec4 vClip;
out vec4 vPreviousClip;
out float vViewDepth;
void main() {
    vec4 world = uModel * vec4(inPosition, 1.0);
    vWorldPosition = world.xyz;
    vNormal = mat3(uModel) * inNormal;
    vUv = inUv;
    vec4 view = uView * world;
    vViewDepth = -view.z;
    vClip = uViewProjection * world;
    vPreviousClip = uPreviousModelViewProjection * vec4(inPosition, 1.0);
    gl_Position = uJitteredProjection * view;
}
)";

constexpr const char* kSceneFragmentShader = R"(#version 330 core
in vec3 vWorldPosition;
in vec3 vNormal;
in vec2 vUv;
in vec4 vClip;
in vec4 vPreviousClip;
in float vViewDepth;
layout(location = 0) out vec4 outColour;
layout(location = 1) out vec4 outAlbedo;
layout(location = 2) out float outDepth;
layout(location = 3) out vec2 outMotion;
layout(location = 4) out float outId;
uniform vec3 uColour;
uniform int uPattern;  // 0 solid, 1 texture, 2 sweep, 3 zone plate, 4 bumps
uniform int uLit;
uniform int uAlphaCutout;
uniform float uSpecular;
uniform float uShininess;
uniform float uFrequency;
uniform sampler2D uTexture;
uniform vec3 uLightDirection;
uniform vec3 uLightColour;
uniform vec3 uAmbient;
uniform vec3 uEye;
uniform float uId;
uniform vec2 uViewport;
uniform int uFourier;                // the texture is read by the Fourier sampler
uniform sampler2D uOriginal;         // its box MIP chain, linear RGBA (decoded as FourierTexture does)
uniform sampler2D uBands;            // its band-limited MIP levels, linear RGBA
uniform sampler2D uDetail;           // its sets of removed sinusoids, a row each
uniform float uFourierSize;          // texels across level 0
uniform int uFourierLevels;
uniform int uFourierFrequencies;
uniform float uFourierSigma;
uniform float uFourierCutoff;
uniform float uFourierMinCaptured;
uniform int uFourierProbeLevels;  // log2 of the most probes
uniform int uBump;                   // Pattern::Bumps: 0 procedural, 1 standard normal map, 2 super bump map
uniform sampler2D uNormalMap;        // the standard chain: averaged normals (x, y, z), tangent space
uniform sampler2D uLobe0;            // the super chain, a texture a lobe: (x, y, weight, mean length)
uniform sampler2D uLobe1;
uniform sampler2D uLobe2;
uniform sampler2D uLobe3;
uniform int uBumpLobes;
uniform float uBumpSize;
uniform int uBumpLevels;
const float kTau = 6.28318530718;
const float kPi = 3.14159265359;
// The response of the mean of n probes spaced one unit apart (a Dirichlet kernel) at x cycles a unit;
// at whole cycles, its limit.
float probeResponse(float x, int n) {
    if (n == 1) return 1.0;
    float d = sin(kPi * x);
    return abs(d) < 1e-4 ? cos(float(n) * kPi * x) / cos(kPi * x) : sin(float(n) * kPi * x) / (float(n) * d);
}
// FourierTexture::sample (render/fourier_texture.cpp) in float; its comments say why.
vec4 fourierSample(vec2 uv) {
    vec2 dx = dFdx(uv), dy = dFdy(uv);
    vec2 a = dx * uFourierSize, b = dy * uFourierSize;
    float c00 = a.x * a.x + b.x * b.x, c01 = a.x * a.y + b.x * b.y, c11 = a.y * a.y + b.y * b.y;
    float middle = 0.5 * (c00 + c11), spread = sqrt(0.25 * (c00 - c11) * (c00 - c11) + c01 * c01);
    float majorLod = 0.5 * log2(max(middle + spread, 1e-30));
    float minorLod = 0.5 * log2(max(middle - spread, 1e-30));
    float angle = 0.5 * atan(2.0 * c01, c00 - c11);
    if (angle < 0.0) angle += kPi;
    float lod = clamp(majorLod, 0.0, float(uFourierLevels - 1));
    int level = min(int(floor(lod)), uFourierLevels - 2);
    float f = lod - float(level);
    int s = clamp(int(floor(minorLod)), 0, level);
    int orientation = int(floor(angle / (kPi / 4.0) + 0.5)) % 4;
    // The band level read: finer by p, with 2^p probes along the major axis (p = 0 with one probe).
    int m = level - min(level - s, uFourierProbeLevels);
    int probes = 1 << (level - m);
    vec2 probeStep = vec2(cos(angle), sin(angle)) * (exp2(lod) / uFourierSize / float(probes));
    int row = (level * (level + 1) / 2 + s) * 4 + orientation;
    if (m > 0 && texelFetch(uDetail, ivec2(2 * uFourierFrequencies, row), 0).x < uFourierMinCaptured) {
        // The sum would ring: the texture's box MIP chain instead, trilinear at each probe.
        vec4 mipmapped = vec4(0.0);
        for (int i = 0; i < probes; ++i) {
            vec2 p = uv + (float(i) + 0.5 - 0.5 * float(probes)) * probeStep;
            mipmapped += mix(textureLod(uOriginal, p, float(m)), textureLod(uOriginal, p, float(m + 1)), f);
        }
        return mipmapped / float(probes);
    }
    // Band m + 1 is OpenGL level m of uBands; band 0 is the texture itself.
    vec4 colour = vec4(0.0);
    for (int i = 0; i < probes; ++i) {
        vec2 p = uv + (float(i) + 0.5 - 0.5 * float(probes)) * probeStep;
        vec4 lower = m == 0 ? textureLod(uOriginal, p, 0.0) : textureLod(uBands, p, float(m - 1));
        colour += mix(lower, textureLod(uBands, p, float(m)), f);
    }
    colour /= float(probes);
    float cut = m == 0 ? 1e30 : uFourierCutoff * 0.5 * uFourierSize / exp2(float(m));
    float unit = kTau / uFourierSize, spread2 = 0.5 * uFourierSigma * uFourierSigma;
    vec2 at = fract(uv);
    vec3 detail = vec3(0.0);
    for (int j = 0; j < uFourierFrequencies; ++j) {
        vec4 e0 = texelFetch(uDetail, ivec2(2 * j, row), 0);
        vec4 e1 = texelFetch(uDetail, ivec2(2 * j + 1, row), 0);
        vec2 k = e0.xy;
        vec2 q = unit * vec2(dot(k, a), dot(k, b));
        float response = exp(-spread2 * dot(q, q));
        float attenuation = m == 0 ? response - (1.0 - f) * probeResponse(dot(k, probeStep), probes)
                            : max(abs(k.x), abs(k.y)) < cut ? f * response : response;
        float phase = kTau * fract(dot(k, at) - (k.x + k.y) * 0.5 / uFourierSize);
        detail += attenuation * (vec3(e0.z, e1.x, e1.z) * cos(phase) - vec3(e0.w, e1.y, e1.w) * sin(phase));
    }
    return vec4(clamp(colour.rgb + detail, 0.0, 1.0), colour.a);
}
// Blinn-Phong (docs/render.md): the ambient and diffuse part, and the specular factor for an exponent.
vec3 diffuseLighting(vec3 albedo, vec3 n) {
    return albedo * (uAmbient + uLightColour * max(dot(n, normalize(uLightDirection)), 0.0));
}
float specularFactor(vec3 n, float shininess) {
    vec3 l = normalize(uLightDirection);
    vec3 h = normalize(l + normalize(uEye - vWorldPosition));
    return dot(n, l) > 0.0 ? pow(max(dot(n, h), 0.0), shininess) : 0.0;
}
vec4 lobeTexel(int j, ivec2 p, int level) {
    if (j == 0) return texelFetch(uLobe0, p, level);
    if (j == 1) return texelFetch(uLobe1, p, level);
    if (j == 2) return texelFetch(uLobe2, p, level);
    return texelFetch(uLobe3, p, level);
}
// Super Bump Mapping (render/normal_map.h) at one place: each lobe of the 4 texels around uv at the two
// levels around `lod`, lit with the exponent its spread gives (Toksvig) and its peak lowered by
// (1 + s') / (1 + s) so that the widened lobe reflects what the spread normals do, weighted by its share,
// the texel's bilinear weight and the level's linear one. The lighting is filtered, not the normals.
// Level 0 is the surface itself: its bilinear normal, lit as standard normal mapping lights it.
vec3 superBumpProbe(vec2 uv, float lod, vec3 albedo, vec3 T, vec3 B, vec3 N) {
    int level0 = int(floor(lod));
    int level1 = min(level0 + 1, uBumpLevels - 1);
    float f = lod - float(level0);
    vec3 sum = vec3(0.0);
    for (int k = 0; k < 2; ++k) {
        int level = k == 0 ? level0 : level1;
        float levelWeight = k == 0 ? 1.0 - f : f;
        if (levelWeight == 0.0) continue;
        if (level == 0) {
            vec3 m = normalize(textureLod(uNormalMap, uv, 0.0).xyz);
            vec3 n = normalize(T * m.x + B * m.y + N * m.z);
            sum += levelWeight * (diffuseLighting(albedo, n) + uSpecular * uLightColour * specularFactor(n, uShininess));
            continue;
        }
        int texels = int(uBumpSize) >> level;
        vec2 t = uv * float(texels) - 0.5;
        vec2 base = floor(t), fraction = t - base;
        for (int corner = 0; corner < 4; ++corner) {
            ivec2 offset = ivec2(corner & 1, corner >> 1);
            float weight = levelWeight * (offset.x == 1 ? fraction.x : 1.0 - fraction.x) *
                           (offset.y == 1 ? fraction.y : 1.0 - fraction.y);
            ivec2 p = ivec2(mod(base + vec2(offset), float(texels)));
            for (int j = 0; j < uBumpLobes; ++j) {
                vec4 e = lobeTexel(j, p, level);
                if (e.z <= 0.0) continue;
                vec3 m = vec3(e.x, e.y, sqrt(max(1.0 - e.x * e.x - e.y * e.y, 0.0)));
                float r = clamp(e.w, 1e-6, 1.0);
                float s = uShininess * r / (r + uShininess * (1.0 - r));
                float peak = (1.0 + s) / (1.0 + uShininess);
                vec3 n = normalize(T * m.x + B * m.y + N * m.z);
                sum += weight * e.z * (diffuseLighting(albedo, n) + peak * uSpecular * uLightColour * specularFactor(n, s));
            }
        }
    }
    return sum;
}
// An anisotropic footprint is covered by up to 4 probes along its longer side, each at the level of
// detail of its share of that side (or of the shorter side, if longer), as anisotropic texture filtering
// does; a square footprint by one (docs/texture-aa.md).
vec3 superBumpLighting(vec3 albedo, vec3 T, vec3 B, vec3 N) {
    vec2 dx = dFdx(vUv) * uBumpSize, dy = dFdy(vUv) * uBumpSize;
    vec2 major = dot(dx, dx) >= dot(dy, dy) ? dx : dy;
    float majorLength = length(major), minorLength = min(length(dx), length(dy));
    int probes = int(clamp(ceil(majorLength / max(minorLength, 1e-6)), 1.0, 4.0));
    float lod = clamp(log2(max(max(majorLength / float(probes), minorLength), 1e-15)), 0.0, float(uBumpLevels - 1));
    vec3 sum = vec3(0.0);
    for (int i = 0; i < probes; ++i) {
        vec2 uv = vUv + ((float(i) + 0.5) / float(probes) - 0.5) * major / uBumpSize;
        sum += superBumpProbe(uv, lod, albedo, T, B, N);
    }
    return sum / float(probes);
}
void main() {
    vec3 albedo = uColour;
    vec3 superBump = vec3(0.0);
    vec3 n = normalize(vNormal);
    if (!gl_FrontFacing) n = -n;
    if (uPattern == 1) {
        vec4 t = uFourier == 1 ? fourierSample(vUv) : texture(uTexture, vUv);  // sRGB: filtered in linear
        if (uAlphaCutout == 1 && t.a < 0.5) discard;
        albedo *= t.rgb;
    } else if (uPattern == 2) {
        // Frequency rising linearly along u (0 .. uFrequency cycles per unit), 12 cycles along v.
        float phase = 0.5 * uFrequency * vUv.x * vUv.x;
        albedo *= 0.5 + 0.5 * cos(kTau * phase) * cos(kTau * 12.0 * vUv.y);
    } else if (uPattern == 3) {
        vec2 c = vUv - 0.5;
        albedo *= 0.5 + 0.5 * cos(uFrequency * dot(c, c));
    } else if (uPattern == 4) {
        // Procedural normal map in the cotangent frame of (position, uv).
        vec3 dp1 = dFdx(vWorldPosition), dp2 = dFdy(vWorldPosition);
        vec2 duv1 = dFdx(vUv), duv2 = dFdy(vUv);
        vec3 dp2perp = cross(dp2, n), dp1perp = cross(n, dp1);
        vec3 T = dp2perp * duv1.x + dp1perp * duv2.x;
        vec3 B = dp2perp * duv1.y + dp1perp * duv2.y;
        float scale = inversesqrt(max(max(dot(T, T), dot(B, B)), 1e-20));
        if (uBump == 0) {
            vec2 g = vec2(sin(kTau * uFrequency * vUv.x), sin(kTau * uFrequency * 1.37 * vUv.y)) * 0.35;
            n = normalize(n - g.x * T * scale - g.y * B * scale);
        } else {
            // The normal map's tangent frame: unit T and B (square texels), the surface normal.
            T = normalize(T * scale), B = normalize(B * scale);
            if (uBump == 2) {
                superBump = superBumpLighting(albedo, T, B, n);
            } else {
                vec3 m = normalize(texture(uNormalMap, vUv).xyz);
                n = normalize(T * m.x + B * m.y + n * m.z);
            }
        }
    }
    vec3 lit = albedo;
    if (uPattern == 4 && uBump == 2) {
        lit = superBump;
    } else if (uLit == 1) {
        lit = diffuseLighting(albedo, n) + uSpecular * uLightColour * specularFactor(n, uShininess);
    }
    outColour = vec4(lit, 1.0);
    outAlbedo = vec4(albedo, 1.0);
    outDepth = vViewDepth;
    // A point that was not in front of the previous camera (a dolly backing past it) was not seen: its
    // motion points off-screen, bounded (the previous place clamped to 3 half-viewports out), instead of
    // the blow-up of a division by w near 0.
    vec2 previous = vPreviousClip.w > 1e-4 ? clamp(vPreviousClip.xy / vPreviousClip.w, -3.0, 3.0) : vec2(3.0);
    vec2 d = (vClip.xy / vClip.w - previous) * 0.5 * uViewport;
    outMotion = vec2(d.x, -d.y);
    outId = uId;
}
)";

constexpr const char* kFullscreenVertexShader = R"(#version 330 core
void main() {
    vec2 p = vec2(float((gl_VertexID << 1) & 2), float(gl_VertexID & 2));
    gl_Position = vec4(p * 2.0 - 1.0, 0.0, 1.0);
}
)";

constexpr const char* kAccumulateFragmentShader = R"(#version 330 core
uniform sampler2D uSample;
uniform float uWeight;
layout(location = 0) out vec4 outSum;
layout(location = 1) out vec4 outSquares;
void main() {
    vec4 c = texelFetch(uSample, ivec2(gl_FragCoord.xy), 0);
    outSum = uWeight * c;
    outSquares = uWeight * c * c;
}
)";

constexpr GLenum kMaxAnisotropy = 0x84FE;  // GL_TEXTURE_MAX_ANISOTROPY (4.6 / EXT_texture_filter_anisotropic)

// Attachment slots of the G-buffer, matching the fragment shader's output locations.
enum Slot { kColourSlot, kAlbedoSlot, kDepthSlot, kMotionSlot, kIdSlot, kSlotCount };

}  // namespace

// ---- BufferSet -----------------------------------------------------------------------------------------

BufferSet BufferSet::all() {
    return {true, true, true, true, true, true};
}

BufferSet BufferSet::parse(const std::string& list) {
    BufferSet b;
    b.colour = false;
    std::stringstream stream(list);
    std::string item;
    bool any = false;
    while (std::getline(stream, item, ',')) {
        if (item == "color" || item == "colour")
            b.colour = true;
        else if (item == "albedo")
            b.albedo = true;
        else if (item == "depth")
            b.depth = true;
        else if (item == "motion")
            b.motion = true;
        else if (item == "id")
            b.id = true;
        else if (item == "prevdepth")
            b.previousDepth = true;
        else
            throw Error("unknown buffer '" + item + "' (color, albedo, depth, motion, id, prevdepth)");
        any = true;
    }
    if (!any) throw Error("no buffers named (color, albedo, depth, motion, id, prevdepth)");
    return b;
}

std::vector<std::string> BufferSet::channelNames() const {
    std::vector<std::string> names;
    if (colour) names.insert(names.end(), {"R", "G", "B"});
    if (albedo) names.insert(names.end(), {"albedo.R", "albedo.G", "albedo.B"});
    if (depth) names.push_back("depth.Z");
    if (motion) names.insert(names.end(), {"motion.X", "motion.Y"});
    if (id) names.push_back("id.ID");
    if (previousDepth) names.push_back("prevdepth.Z");
    return names;
}

std::string BufferSet::describe() const {
    std::string s;
    auto add = [&](bool on, const char* name) {
        if (on) s += (s.empty() ? "" : ",") + std::string(name);
    };
    add(colour, "color"), add(albedo, "albedo"), add(depth, "depth"), add(motion, "motion"), add(id, "id");
    add(previousDepth, "prevdepth");
    return s;
}

// ---- Renderer -------------------------------------------------------------------------------------------

struct Renderer::Impl {
    const GlFunctions& gl;
    const Scene& scene;
    int width, height;

    struct GpuMesh {
        GLuint vao = 0, vbo = 0, ebo = 0;
        GLsizei indexCount = 0;
    };
    std::vector<GpuMesh> meshes;
    std::vector<GLuint> textures;
    // Sampler::Fourier: per texture, its band-limited levels and its sets of sinusoids (units 1 and 2).
    struct FourierGpu {
        GLuint original = 0, bands = 0, detail = 0;
        int size = 0, levels = 0;
    };
    std::vector<FourierGpu> fourier;
    // Normal maps (Bump::Standard: the averaged chain on unit 4; Bump::Super: a texture a lobe, units 5-8).
    struct BumpGpu {
        GLuint standard = 0;
        std::array<GLuint, 4> lobes{};
        int size = 0, levels = 0, lobeCount = 0;
    };
    std::vector<BumpGpu> bumps;
    GLuint sceneProgram = 0, accumulateProgram = 0, emptyVao = 0;
    GLuint gbuffer = 0, accumulation = 0;
    std::array<GLuint, kSlotCount> targets{};
    GLuint previousDepthTarget = 0;  // the previous frame's depth of a frame left on the GPU
    GLuint accumulationTarget = 0, squaresTarget = 0, depthStencil = 0;
    // Multisampled colour and depth, created on first use.
    GLuint msaaFramebuffer = 0, msaaColour = 0, msaaDepth = 0;
    int msaaSamples = 0;

    void prepareMsaa(int samples) {
        if (samples == msaaSamples) return;
        if (msaaFramebuffer) {
            gl.DeleteFramebuffers(1, &msaaFramebuffer);
            gl.DeleteRenderbuffers(1, &msaaColour);
            gl.DeleteRenderbuffers(1, &msaaDepth);
        }
        GLint most = 0;
        gl.GetIntegerv(GL_MAX_SAMPLES, &most);
        if (samples > most)
            throw Error("MSAA " + std::to_string(samples) + "x: this OpenGL supports at most " +
                        std::to_string(most));
        gl.GenRenderbuffers(1, &msaaColour);
        gl.BindRenderbuffer(GL_RENDERBUFFER, msaaColour);
        gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_RGBA32F, width, height);
        gl.GenRenderbuffers(1, &msaaDepth);
        gl.BindRenderbuffer(GL_RENDERBUFFER, msaaDepth);
        gl.RenderbufferStorageMultisample(GL_RENDERBUFFER, samples, GL_DEPTH24_STENCIL8, width, height);
        gl.GenFramebuffers(1, &msaaFramebuffer);
        gl.BindFramebuffer(GL_FRAMEBUFFER, msaaFramebuffer);
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_RENDERBUFFER, msaaColour);
        gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, msaaDepth);
        checkFramebuffer("MSAA");
        msaaSamples = samples;
    }

    Impl(const GlFunctions& functions, const Scene& s, int w, int h)
        : gl(functions), scene(s), width(w), height(h) {}

    GLuint link(const char* vertex, const char* fragment) {
        return compileProgram(gl, {{GL_VERTEX_SHADER, vertex}, {GL_FRAGMENT_SHADER, fragment}},
                              "OpenGL: the renderer's program");
    }
    GLint uniform(GLuint program, const char* name) const { return gl.GetUniformLocation(program, name); }
    void setMatrix(GLuint program, const char* name, const Mat4& m) const {
        const auto f = m.toFloat();
        gl.UniformMatrix4fv(uniform(program, name), 1, GL_FALSE, f.data());
    }
    void setVec3(GLuint program, const char* name, const Vec3& v) const {
        gl.Uniform3f(uniform(program, name), float(v.x), float(v.y), float(v.z));
    }

    // A repeating RGBA32F texture of square levels (level j: sizes[j]^2 texels from data[j]) with the
    // given filters; the bound texture afterwards.
    GLuint makeFloatTexture(const std::vector<int>& sizes, const std::vector<const float*>& data,
                            GLenum magFilter, GLenum minFilter) {
        GLuint id = 0;
        gl.GenTextures(1, &id);
        gl.BindTexture(GL_TEXTURE_2D, id);
        for (size_t level = 0; level < sizes.size(); ++level)
            gl.TexImage2D(GL_TEXTURE_2D, GLint(level), GL_RGBA32F, sizes[level], sizes[level], 0, GL_RGBA,
                          GL_FLOAT, data[level]);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, GLint(sizes.size()) - 1);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GLint(magFilter));
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GLint(minFilter));
        return id;
    }

    GLuint makeTarget(GLenum internalFormat, GLenum format) {
        GLuint t = 0;
        gl.GenTextures(1, &t);
        gl.BindTexture(GL_TEXTURE_2D, t);
        gl.TexImage2D(GL_TEXTURE_2D, 0, GLint(internalFormat), width, height, 0, format, GL_FLOAT, nullptr);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
        return t;
    }

    void checkFramebuffer(const char* what) {
        const GLenum status = gl.CheckFramebufferStatus(GL_FRAMEBUFFER);
        if (status != GL_FRAMEBUFFER_COMPLETE)
            throw Error(std::string("OpenGL: the ") + what + " framebuffer is incomplete (status " +
                        std::to_string(status) + ")");
    }

    Mat4 projection(const CameraPose& pose, const Vec2& jitter) const {
        Mat4 p = Mat4::perspective(pose.fovY, double(width) / height, scene.near, scene.far);
        // docs/taa.md: the NDC offset goes into the third column (multiplying view z = -w), so after the
        // divide every vertex moves by exactly the jitter.
        p.at(0, 2) -= 2.0 * jitter.x / width;
        p.at(1, 2) -= 2.0 * jitter.y / height;
        return p;
    }
    static Mat4 view(const CameraPose& pose) { return Mat4::lookAt(pose.eye, pose.target, pose.up); }

    // Draws every object of the scene at `time` with the bound framebuffer and draw buffers.
    void drawScene(double time, double previousTime, const Vec2& jitter) {
        const CameraPose pose = scene.cameraAt(time), previousPose = scene.cameraAt(previousTime);
        const Mat4 v = view(pose), jittered = projection(pose, jitter);
        const Mat4 viewProjection = projection(pose, {}) * v;
        const Mat4 previousViewProjection = projection(previousPose, {}) * view(previousPose);
        const GLuint p = sceneProgram;
        gl.UseProgram(p);
        setMatrix(p, "uView", v);
        setMatrix(p, "uJitteredProjection", jittered);
        setMatrix(p, "uViewProjection", viewProjection);
        setVec3(p, "uLightDirection", scene.lightDirection);
        setVec3(p, "uLightColour", scene.lightColour);
        setVec3(p, "uAmbient", scene.ambient);
        setVec3(p, "uEye", pose.eye);
        gl.Uniform2f(uniform(p, "uViewport"), float(width), float(height));
        gl.Uniform1i(uniform(p, "uTexture"), 0);
        gl.Uniform1i(uniform(p, "uBands"), 1);
        gl.Uniform1i(uniform(p, "uDetail"), 2);
        gl.Uniform1i(uniform(p, "uOriginal"), 3);
        gl.Uniform1i(uniform(p, "uFourier"), fourier.empty() ? 0 : 1);
        gl.Uniform1i(uniform(p, "uBump"), int(scene.bump));
        gl.Uniform1i(uniform(p, "uNormalMap"), 4);
        for (int j = 0; j < 4; ++j) gl.Uniform1i(uniform(p, ("uLobe" + std::to_string(j)).c_str()), 5 + j);
        if (!fourier.empty()) {
            gl.Uniform1i(uniform(p, "uFourierFrequencies"), scene.fourier.frequencies);
            gl.Uniform1f(uniform(p, "uFourierSigma"), float(scene.fourier.sigma));
            gl.Uniform1f(uniform(p, "uFourierCutoff"), float(scene.fourier.cutoff));
            gl.Uniform1f(uniform(p, "uFourierMinCaptured"), float(scene.fourier.minCaptured));
            gl.Uniform1i(uniform(p, "uFourierProbeLevels"), std::countr_zero(unsigned(scene.fourier.probes)));
        }
        gl.ActiveTexture(GL_TEXTURE0);
        for (const SceneObject& object : scene.objects) {
            const Material& m = object.material;
            const Mat4 model = object.at(time);
            setMatrix(p, "uModel", model);
            setMatrix(p, "uPreviousModelViewProjection", previousViewProjection * object.at(previousTime));
            setVec3(p, "uColour", m.colour);
            gl.Uniform1i(uniform(p, "uPattern"), int(m.pattern));
            gl.Uniform1i(uniform(p, "uLit"), m.lit ? 1 : 0);
            gl.Uniform1i(uniform(p, "uAlphaCutout"), m.alphaCutout ? 1 : 0);
            gl.Uniform1f(uniform(p, "uSpecular"), float(m.specular));
            gl.Uniform1f(uniform(p, "uShininess"), float(m.shininess));
            gl.Uniform1f(uniform(p, "uFrequency"), float(m.frequency));
            gl.Uniform1f(uniform(p, "uId"), float(object.id));
            if (m.texture >= 0) gl.BindTexture(GL_TEXTURE_2D, textures.at(size_t(m.texture)));
            if (m.texture >= 0 && !fourier.empty()) {
                const FourierGpu& f = fourier.at(size_t(m.texture));
                gl.Uniform1f(uniform(p, "uFourierSize"), float(f.size));
                gl.Uniform1i(uniform(p, "uFourierLevels"), f.levels);
                gl.ActiveTexture(GL_TEXTURE1);
                gl.BindTexture(GL_TEXTURE_2D, f.bands);
                gl.ActiveTexture(GL_TEXTURE2);
                gl.BindTexture(GL_TEXTURE_2D, f.detail);
                gl.ActiveTexture(GL_TEXTURE3);
                gl.BindTexture(GL_TEXTURE_2D, f.original);
                gl.ActiveTexture(GL_TEXTURE0);
            }
            if (m.pattern == Pattern::Bumps && scene.bump != Bump::Procedural) {
                if (m.normalMap < 0) throw Error("material of '" + object.name + "' has no normal map");
                const BumpGpu& b = bumps.at(size_t(m.normalMap));
                gl.Uniform1f(uniform(p, "uBumpSize"), float(b.size));
                gl.Uniform1i(uniform(p, "uBumpLevels"), b.levels);
                gl.Uniform1i(uniform(p, "uBumpLobes"), b.lobeCount);
                gl.ActiveTexture(GL_TEXTURE4);
                gl.BindTexture(GL_TEXTURE_2D, b.standard);
                for (int j = 0; j < 4; ++j) {
                    gl.ActiveTexture(GLenum(GL_TEXTURE5 + j));
                    gl.BindTexture(GL_TEXTURE_2D, b.lobes[size_t(j)]);
                }
                gl.ActiveTexture(GL_TEXTURE0);
            }
            const GpuMesh& mesh = meshes[size_t(object.mesh)];
            gl.BindVertexArray(mesh.vao);
            gl.DrawElements(GL_TRIANGLES, mesh.indexCount, GL_UNSIGNED_INT, nullptr);
        }
        gl.BindVertexArray(0);
    }

    void selectDrawBuffers(const std::vector<int>& slots) {
        std::array<GLenum, kSlotCount> draw{};
        draw.fill(GL_NONE);
        // Output location k writes draw buffer k: only the requested slots get an attachment.
        for (int slot : slots) draw[size_t(slot)] = GL_COLOR_ATTACHMENT0 + GLenum(slot);
        gl.DrawBuffers(kSlotCount, draw.data());
    }

    // Reads `components` floats per pixel of an attachment into frame channels [offset, offset + components).
    void readInto(Frame& frame, GLenum attachment, GLenum format, int components, int offset) {
        std::vector<float> rows(size_t(width) * size_t(height) * size_t(components));
        gl.ReadBuffer(attachment);
        gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
        gl.ReadPixels(0, 0, width, height, format, GL_FLOAT, rows.data());
        const int channels = frame.channels();
        for (int y = 0; y < height; ++y) {
            const float* src = rows.data() + size_t(height - 1 - y) * size_t(width) * size_t(components);
            float* dst = frame.pixels.data() + size_t(y) * size_t(width) * size_t(channels) + size_t(offset);
            for (int x = 0; x < width; ++x)
                for (int c = 0; c < components; ++c) dst[size_t(x * channels + c)] = src[x * components + c];
        }
    }
};

Renderer::Renderer(const GlContext& context, const Scene& scene, int width, int height)
    : impl_(std::make_unique<Impl>(context.gl(), scene, width, height)) {
    Impl& m = *impl_;
    const GlFunctions& gl = m.gl;
    if (width < 1 || height < 1 || width > 16384 || height > 16384)
        throw Error("render size " + std::to_string(width) + "x" + std::to_string(height) +
                    " is outside 1..16384");
    m.sceneProgram = m.link(kSceneVertexShader, kSceneFragmentShader);
    m.accumulateProgram = m.link(kFullscreenVertexShader, kAccumulateFragmentShader);
    gl.GenVertexArrays(1, &m.emptyVao);
    for (const Mesh& mesh : scene.meshes) {
        Impl::GpuMesh g;
        gl.GenVertexArrays(1, &g.vao);
        gl.BindVertexArray(g.vao);
        gl.GenBuffers(1, &g.vbo);
        gl.BindBuffer(GL_ARRAY_BUFFER, g.vbo);
        gl.BufferData(GL_ARRAY_BUFFER, GLsizeiptr(mesh.vertices.size() * sizeof(Vertex)),
                      mesh.vertices.data(), GL_STATIC_DRAW);
        gl.GenBuffers(1, &g.ebo);
        gl.BindBuffer(GL_ELEMENT_ARRAY_BUFFER, g.ebo);
        gl.BufferData(GL_ELEMENT_ARRAY_BUFFER, GLsizeiptr(mesh.indices.size() * sizeof(uint32_t)),
                      mesh.indices.data(), GL_STATIC_DRAW);
        gl.VertexAttribPointer(0, 3, GL_FLOAT, GL_FALSE, sizeof(Vertex),
                               reinterpret_cast<void*>(offsetof(Vertex, position)));
        gl.VertexAttribPointer(1, 3, GL_FLOAT, GL_FALSE, sizeof(Vertex),
                               reinterpret_cast<void*>(offsetof(Vertex, normal)));
        gl.VertexAttribPointer(2, 2, GL_FLOAT, GL_FALSE, sizeof(Vertex),
                               reinterpret_cast<void*>(offsetof(Vertex, uv)));
        for (GLuint a = 0; a < 3; ++a) gl.EnableVertexAttribArray(a);
        g.indexCount = GLsizei(mesh.indices.size());
        m.meshes.push_back(g);
    }
    gl.BindVertexArray(0);
    while (gl.GetError() != GL_NO_ERROR) {
    }
    for (const TextureImage& t : scene.textures) {
        GLuint id = 0;
        gl.GenTextures(1, &id);
        gl.BindTexture(GL_TEXTURE_2D, id);
        gl.PixelStorei(GL_UNPACK_ALIGNMENT, 1);
        gl.TexImage2D(GL_TEXTURE_2D, 0, GL_SRGB8_ALPHA8, t.width, t.height, 0, GL_RGBA, GL_UNSIGNED_BYTE,
                      t.rgba.data());
        gl.GenerateMipmap(GL_TEXTURE_2D);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_S, GL_REPEAT);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_WRAP_T, GL_REPEAT);
        const Sampler s = scene.sampler;
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, s == Sampler::Point ? GL_NEAREST : GL_LINEAR);
        gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER,
                         s == Sampler::Point      ? GL_NEAREST
                         : s == Sampler::Bilinear ? GL_LINEAR
                                                  : GL_LINEAR_MIPMAP_LINEAR);
        if (s == Sampler::Anisotropic16) {
            gl.TexParameterf(GL_TEXTURE_2D, kMaxAnisotropy, 16.0f);
            anisotropy_ = gl.GetError() == GL_NO_ERROR;
        }
        m.textures.push_back(id);
        if (s == Sampler::Fourier) {
            const FourierTexture f(t, scene.fourier);
            Impl::FourierGpu g;
            g.size = f.size(), g.levels = f.levels();
            // The texture's box MIP chain (level 0 the texture itself, the fallback reads the others).
            std::vector<int> mipSizes;
            std::vector<const float*> mipmaps;
            for (int level = 0; level < f.levels(); ++level)
                mipSizes.push_back(f.size() >> level), mipmaps.push_back(f.mipmap(level).data());
            g.original = m.makeFloatTexture(mipSizes, mipmaps, GL_LINEAR, GL_LINEAR_MIPMAP_NEAREST);
            // OpenGL's level j holds band j + 1 (stored at twice its MIP size); band 0 is the texture.
            std::vector<int> sizes;
            std::vector<const float*> bands;
            for (int level = 1; level < f.levels(); ++level)
                sizes.push_back(f.levelSize(level)), bands.push_back(f.level(level).data());
            g.bands = m.makeFloatTexture(sizes, bands, GL_LINEAR, GL_LINEAR_MIPMAP_NEAREST);
            gl.GenTextures(1, &g.detail);
            gl.BindTexture(GL_TEXTURE_2D, g.detail);
            const std::vector<float> texels = f.detailTexels();
            gl.TexImage2D(GL_TEXTURE_2D, 0, GL_RGBA32F, 2 * f.frequencies() + 1, f.setCount(), 0, GL_RGBA,
                          GL_FLOAT, texels.data());
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAX_LEVEL, 0);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MAG_FILTER, GL_NEAREST);
            gl.TexParameteri(GL_TEXTURE_2D, GL_TEXTURE_MIN_FILTER, GL_NEAREST);
            m.fourier.push_back(g);
        }
    }

    if (scene.bump != Bump::Procedural)
        for (const NormalMapImage& map : scene.normalMaps) {
            const SuperBumpChain chain =
                buildSuperBumpChain(map, scene.bump == Bump::Super ? scene.bumpLobes : 0);
            Impl::BumpGpu b;
            b.size = chain.size, b.levels = chain.levels, b.lobeCount = chain.lobes;
            std::vector<int> sizes;
            for (int level = 0; level < chain.levels; ++level) sizes.push_back(chain.size >> level);
            const auto pointers = [](const std::vector<std::vector<float>>& levels) {
                std::vector<const float*> out;
                for (const std::vector<float>& level : levels) out.push_back(level.data());
                return out;
            };
            // The standard chain is read with the scene's sampler; the lobes by texel.
            const Sampler s = scene.sampler;
            b.standard = m.makeFloatTexture(sizes, pointers(chain.standard),
                                            s == Sampler::Point ? GL_NEAREST : GL_LINEAR,
                                            s == Sampler::Point      ? GL_NEAREST_MIPMAP_NEAREST
                                            : s == Sampler::Bilinear ? GL_LINEAR
                                                                     : GL_LINEAR_MIPMAP_LINEAR);
            if (s == Sampler::Anisotropic16) gl.TexParameterf(GL_TEXTURE_2D, kMaxAnisotropy, 16.0f);
            for (int j = 0; j < chain.lobes; ++j)
                b.lobes[size_t(j)] = m.makeFloatTexture(sizes, pointers(chain.lobe[size_t(j)]), GL_NEAREST,
                                                        GL_NEAREST_MIPMAP_NEAREST);
            m.bumps.push_back(b);
        }

    // The G-buffer: one float texture per buffer and a depth-stencil renderbuffer, which the
    // accumulation framebuffer shares (the adaptive truth marks unconverged tiles in its stencil).
    m.targets[kColourSlot] = m.makeTarget(GL_RGBA32F, GL_RGBA);
    m.targets[kAlbedoSlot] = m.makeTarget(GL_RGBA32F, GL_RGBA);
    m.targets[kDepthSlot] = m.makeTarget(GL_R32F, GL_RED);
    m.targets[kMotionSlot] = m.makeTarget(GL_RG32F, GL_RG);
    m.targets[kIdSlot] = m.makeTarget(GL_R32F, GL_RED);
    m.previousDepthTarget = m.makeTarget(GL_R32F, GL_RED);
    m.accumulationTarget = m.makeTarget(GL_RGBA32F, GL_RGBA);
    m.squaresTarget = m.makeTarget(GL_RGBA32F, GL_RGBA);
    gl.GenRenderbuffers(1, &m.depthStencil);
    gl.BindRenderbuffer(GL_RENDERBUFFER, m.depthStencil);
    gl.RenderbufferStorage(GL_RENDERBUFFER, GL_DEPTH24_STENCIL8, width, height);
    gl.GenFramebuffers(1, &m.gbuffer);
    gl.BindFramebuffer(GL_FRAMEBUFFER, m.gbuffer);
    for (int slot = 0; slot < kSlotCount; ++slot)
        gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + GLenum(slot), GL_TEXTURE_2D,
                                m.targets[size_t(slot)], 0);
    gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, m.depthStencil);
    m.checkFramebuffer("G-buffer");
    gl.GenFramebuffers(1, &m.accumulation);
    gl.BindFramebuffer(GL_FRAMEBUFFER, m.accumulation);
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0, GL_TEXTURE_2D, m.accumulationTarget, 0);
    gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT1, GL_TEXTURE_2D, m.squaresTarget, 0);
    gl.FramebufferRenderbuffer(GL_FRAMEBUFFER, GL_DEPTH_STENCIL_ATTACHMENT, GL_RENDERBUFFER, m.depthStencil);
    m.checkFramebuffer("accumulation");
    gl.Viewport(0, 0, width, height);
    gl.Enable(GL_DEPTH_TEST);
    gl.DepthFunc(GL_LESS);
    if (const GLenum error = gl.GetError(); error != GL_NO_ERROR)
        throw Error("OpenGL: error " + std::to_string(error) + " while setting up the renderer");
}

Renderer::~Renderer() {
    Impl& m = *impl_;
    const GlFunctions& gl = m.gl;
    for (const Impl::GpuMesh& g : m.meshes) {
        gl.DeleteVertexArrays(1, &g.vao);
        gl.DeleteBuffers(1, &g.vbo);
        gl.DeleteBuffers(1, &g.ebo);
    }
    gl.DeleteVertexArrays(1, &m.emptyVao);
    if (!m.textures.empty()) gl.DeleteTextures(GLsizei(m.textures.size()), m.textures.data());
    for (const Impl::BumpGpu& b : m.bumps) {
        gl.DeleteTextures(1, &b.standard);
        for (GLuint lobe : b.lobes)
            if (lobe) gl.DeleteTextures(1, &lobe);
    }
    for (const Impl::FourierGpu& f : m.fourier) {
        gl.DeleteTextures(1, &f.original);
        gl.DeleteTextures(1, &f.bands);
        gl.DeleteTextures(1, &f.detail);
    }
    gl.DeleteTextures(kSlotCount, m.targets.data());
    gl.DeleteTextures(1, &m.previousDepthTarget);
    gl.DeleteTextures(1, &m.accumulationTarget);
    gl.DeleteTextures(1, &m.squaresTarget);
    gl.DeleteRenderbuffers(1, &m.depthStencil);
    gl.DeleteFramebuffers(1, &m.gbuffer);
    gl.DeleteFramebuffers(1, &m.accumulation);
    if (m.msaaFramebuffer) {
        gl.DeleteFramebuffers(1, &m.msaaFramebuffer);
        gl.DeleteRenderbuffers(1, &m.msaaColour);
        gl.DeleteRenderbuffers(1, &m.msaaDepth);
    }
    gl.DeleteProgram(m.sceneProgram);
    gl.DeleteProgram(m.accumulateProgram);
}

Frame Renderer::render(const FrameRequest& request) {
    Impl& m = *impl_;
    const GlFunctions& gl = m.gl;
    const BufferSet& b = request.buffers;
    Frame frame;
    frame.width = m.width, frame.height = m.height;
    frame.channelNames = b.channelNames();
    if (request.readBack)
        frame.pixels.assign(size_t(m.width) * size_t(m.height) * frame.channelNames.size(), 0.0f);
    if (frame.channelNames.empty()) return frame;
    const double previousTime = request.previousTime < 0 ? request.time : request.previousTime;

    const bool msaa = b.colour && request.msaa > 1;
    if (request.msaa < 1 || request.msaa > 32 || (request.msaa & (request.msaa - 1)) != 0)
        throw Error("MSAA sample count " + std::to_string(request.msaa) + " is not 1, 2, 4, 8, 16 or 32");
    std::vector<int> slots;
    if (b.colour && !msaa) slots.push_back(kColourSlot);
    if (b.albedo) slots.push_back(kAlbedoSlot);
    if (b.depth) slots.push_back(kDepthSlot);
    if (b.motion) slots.push_back(kMotionSlot);
    if (b.id) slots.push_back(kIdSlot);
    gl.Disable(GL_STENCIL_TEST);
    gl.Disable(GL_BLEND);
    gl.Enable(GL_DEPTH_TEST);
    if (msaa) {
        // Colour into the multisampled buffer, resolved (averaged) into the G-buffer's colour texture.
        m.prepareMsaa(request.msaa);
        gl.BindFramebuffer(GL_FRAMEBUFFER, m.msaaFramebuffer);
        const GLenum attachment = GL_COLOR_ATTACHMENT0;
        gl.DrawBuffers(1, &attachment);
        const std::array<float, 4> bg{float(m.scene.background.x), float(m.scene.background.y),
                                      float(m.scene.background.z), 1};
        gl.ClearBufferfv(GL_COLOR, 0, bg.data());
        gl.ClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
        gl.Enable(GL_MULTISAMPLE);
        m.drawScene(request.time, previousTime, request.jitter);
        gl.BindFramebuffer(GL_READ_FRAMEBUFFER, m.msaaFramebuffer);
        gl.BindFramebuffer(GL_DRAW_FRAMEBUFFER, m.gbuffer);
        m.selectDrawBuffers({kColourSlot});
        gl.BlitFramebuffer(0, 0, m.width, m.height, 0, 0, m.width, m.height, GL_COLOR_BUFFER_BIT, GL_NEAREST);
    }
    gl.BindFramebuffer(GL_FRAMEBUFFER, m.gbuffer);
    int offset = 0;
    const bool read = request.readBack;
    if (msaa && read) m.readInto(frame, GL_COLOR_ATTACHMENT0 + kColourSlot, GL_RGB, 3, offset), offset += 3;
    if (!slots.empty()) {
        // ClearBuffer's index is the draw buffer index: clear each slot with only it selected.
        for (int slot : slots) {
            m.selectDrawBuffers({slot});
            std::array<float, 4> value{0, 0, 0, 0};
            if (slot == kColourSlot || slot == kAlbedoSlot)
                value = {float(m.scene.background.x), float(m.scene.background.y),
                         float(m.scene.background.z), 1};
            if (slot == kDepthSlot) value[0] = float(m.scene.far);
            gl.ClearBufferfv(GL_COLOR, slot, value.data());
        }
        gl.ClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
        m.selectDrawBuffers(slots);
        m.drawScene(request.time, previousTime, request.jitter);
        if (b.colour && !msaa && read)
            m.readInto(frame, GL_COLOR_ATTACHMENT0 + kColourSlot, GL_RGB, 3, offset), offset += 3;
        if (b.albedo && read)
            m.readInto(frame, GL_COLOR_ATTACHMENT0 + kAlbedoSlot, GL_RGB, 3, offset), offset += 3;
        if (b.depth && read)
            m.readInto(frame, GL_COLOR_ATTACHMENT0 + kDepthSlot, GL_RED, 1, offset), offset += 1;
        if (b.motion && read)
            m.readInto(frame, GL_COLOR_ATTACHMENT0 + kMotionSlot, GL_RG, 2, offset), offset += 2;
        if (b.id && read) m.readInto(frame, GL_COLOR_ATTACHMENT0 + kIdSlot, GL_RED, 1, offset), offset += 1;
    }
    if (b.previousDepth) {
        // The previous frame's depth: its pose and its jitter, into a texture of its own (attached in the
        // depth slot's place while it is drawn), so the depth stays for a pass on the GPU.
        gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + kDepthSlot, GL_TEXTURE_2D,
                                m.previousDepthTarget, 0);
        m.selectDrawBuffers({kDepthSlot});
        std::array<float, 4> far{float(m.scene.far), 0, 0, 0};
        gl.ClearBufferfv(GL_COLOR, kDepthSlot, far.data());
        gl.ClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
        m.drawScene(previousTime, previousTime, request.previousJitter);
        if (read) m.readInto(frame, GL_COLOR_ATTACHMENT0 + kDepthSlot, GL_RED, 1, offset);
        gl.FramebufferTexture2D(GL_FRAMEBUFFER, GL_COLOR_ATTACHMENT0 + kDepthSlot, GL_TEXTURE_2D,
                                m.targets[kDepthSlot], 0);
    }
    if (const GLenum error = gl.GetError(); error != GL_NO_ERROR)
        throw Error("OpenGL: error " + std::to_string(error) + " while rendering");
    return frame;
}

GLuint Renderer::colourTexture() const {
    return impl_->targets[kColourSlot];
}

GpuBuffers Renderer::textures() const {
    const Impl& m = *impl_;
    GpuBuffers t;
    t.colour = m.targets[kColourSlot], t.albedo = m.targets[kAlbedoSlot], t.depth = m.targets[kDepthSlot];
    t.motion = m.targets[kMotionSlot], t.id = m.targets[kIdSlot], t.previousDepth = m.previousDepthTarget;
    return t;
}

Frame Renderer::renderTruth(double time, const TruthOptions& options, TruthStats* stats) {
    Impl& m = *impl_;
    const GlFunctions& gl = m.gl;
    if (options.samples < 1) throw Error("the truth needs at least 1 sample");
    const Stopwatch clock;
    const int W = m.width, H = m.height, T = std::max(1, options.tileSize);
    const int tilesX = (W + T - 1) / T, tilesY = (H + T - 1) / T, tiles = tilesX * tilesY;

    // Sample i: Halton point i. Box: uniform over the pixel (weight 1). Gaussian: sigma 0.5 px over a
    // 3-pixel square, each sample weighted.
    auto jitterOf = [&](int i) {
        return options.filter == PixelFilter::Box ? jitterPixels(unsigned(i), 1.0)
                                                  : jitterPixels(unsigned(i), 3.0);
    };
    auto weightOf = [&](int i) {
        if (options.filter == PixelFilter::Box) return 1.0;
        const Vec2 j = jitterOf(i);
        return std::exp(-(j.x * j.x + j.y * j.y) / (2 * 0.25));
    };
    std::vector<double> weightPrefix(size_t(options.samples) + 1, 0.0);
    for (int i = 0; i < options.samples; ++i)
        weightPrefix[size_t(i) + 1] = weightPrefix[size_t(i)] + weightOf(i);

    // The accumulation buffer starts at zero.
    gl.BindFramebuffer(GL_FRAMEBUFFER, m.accumulation);
    gl.Disable(GL_STENCIL_TEST);
    const std::array<float, 4> zero{0, 0, 0, 0};
    const GLenum sumAndSquares[2] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1};
    gl.DrawBuffers(2, sumAndSquares);
    gl.ClearBufferfv(GL_COLOR, 0, zero.data());
    gl.ClearBufferfv(GL_COLOR, 1, zero.data());

    std::vector<int> tileSamples(size_t(tiles), 0);
    std::vector<char> active(size_t(tiles), 1);
    auto addSamples = [&](int first, int last, bool masked) {
        for (int i = first; i < last; ++i) {
            // Draw the sample into the G-buffer's colour (stencil-masked to the active tiles).
            gl.BindFramebuffer(GL_FRAMEBUFFER, m.gbuffer);
            m.selectDrawBuffers({kColourSlot});
            const std::array<float, 4> bg{float(m.scene.background.x), float(m.scene.background.y),
                                          float(m.scene.background.z), 1};
            gl.ClearBufferfv(GL_COLOR, kColourSlot, bg.data());
            gl.DepthMask(GL_TRUE);
            gl.Clear(GL_DEPTH_BUFFER_BIT);  // the stencil keeps the tile mask
            gl.Enable(GL_DEPTH_TEST);
            if (masked) {
                gl.Enable(GL_STENCIL_TEST);
                gl.StencilMask(0);
                gl.StencilFunc(GL_EQUAL, 1, 0xFF);
            } else {
                gl.Disable(GL_STENCIL_TEST);
            }
            m.drawScene(time, time, jitterOf(i));
            // Add it, weighted, into the accumulation buffer (same stencil).
            gl.BindFramebuffer(GL_FRAMEBUFFER, m.accumulation);
            gl.DrawBuffers(2, sumAndSquares);
            gl.Disable(GL_DEPTH_TEST);
            gl.Enable(GL_BLEND);
            gl.BlendFunc(GL_ONE, GL_ONE);
            gl.UseProgram(m.accumulateProgram);
            gl.ActiveTexture(GL_TEXTURE0);
            gl.BindTexture(GL_TEXTURE_2D, m.targets[kColourSlot]);
            gl.Uniform1i(m.uniform(m.accumulateProgram, "uSample"), 0);
            gl.Uniform1f(m.uniform(m.accumulateProgram, "uWeight"), float(weightOf(i)));
            gl.BindVertexArray(m.emptyVao);
            gl.DrawArrays(GL_TRIANGLES, 0, 3);
            gl.BindVertexArray(0);
            gl.Disable(GL_BLEND);
            gl.Enable(GL_DEPTH_TEST);
        }
        gl.Disable(GL_STENCIL_TEST);
        gl.StencilMask(0xFF);
    };
    auto readSums = [&](GLenum attachment = GL_COLOR_ATTACHMENT0) {
        std::vector<float> sums(size_t(W) * size_t(H) * 4);
        gl.BindFramebuffer(GL_FRAMEBUFFER, m.accumulation);
        gl.ReadBuffer(attachment);
        gl.PixelStorei(GL_PACK_ALIGNMENT, 1);
        gl.ReadPixels(0, 0, W, H, GL_RGBA, GL_FLOAT, sums.data());
        return sums;  // bottom row first
    };

    int rounds = 0;
    std::vector<float> sums;
    if (!options.adaptive || options.samples <= options.firstRound) {
        addSamples(0, options.samples, false);
        std::fill(tileSamples.begin(), tileSamples.end(), options.samples);
        sums = readSums();
        rounds = 1;
    } else {
        // Round 0: every tile gets firstRound samples, with a look at half of them for the first test.
        const int half = std::max(1, options.firstRound / 2);
        addSamples(0, half, false);
        std::vector<float> previous = readSums();
        int n = half;
        std::fill(tileSamples.begin(), tileSamples.end(), n);
        while (n < options.samples) {
            const int next = std::min(options.samples, 2 * n);
            const bool masked = n > half;  // the first doubling covers every tile
            if (masked) {
                // Mark the active tiles in the stencil: 1 inside, 0 elsewhere.
                gl.BindFramebuffer(GL_FRAMEBUFFER, m.gbuffer);
                gl.StencilMask(0xFF);
                gl.Disable(GL_SCISSOR_TEST);
                gl.ClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 0);
                gl.Enable(GL_SCISSOR_TEST);
                for (int t = 0; t < tiles; ++t) {
                    if (!active[size_t(t)]) continue;
                    const int tx = t % tilesX, ty = t / tilesX;
                    // GL rows count from the bottom.
                    const int y0 = std::max(0, H - (ty + 1) * T);
                    gl.Scissor(tx * T, y0, std::min(T, W - tx * T), H - ty * T - y0);
                    gl.ClearBufferfi(GL_DEPTH_STENCIL, 0, 1.0f, 1);
                }
                gl.Disable(GL_SCISSOR_TEST);
            }
            addSamples(n, next, masked);
            std::vector<float> current = readSums(), squares = readSums(GL_COLOR_ATTACHMENT1);
            ++rounds;
            // Converged: the standard error of every pixel's mean (from the spread of its samples) is
            // below pixelTolerance, and the tile's mean moved by less than `tolerance` (RMS) when its
            // samples doubled. An edge or a texture spreads a pixel's samples, so such tiles keep
            // sampling; a flat or smoothly shaded tile stops. (The doubling test alone is fooled by edges
            // aligned with the sample strata: 8 and 16 Halton points can give the same coverage.)
            int stillActive = 0;
            for (int t = 0; t < tiles; ++t) {
                if (!active[size_t(t)]) continue;
                tileSamples[size_t(t)] = next;
                const int tx = t % tilesX, ty = t / tilesX;
                const double wn = weightPrefix[size_t(n)], wnext = weightPrefix[size_t(next)];
                double squared = 0, largest = 0;
                int count = 0;
                for (int y = ty * T; y < std::min(H, (ty + 1) * T); ++y)
                    for (int x = tx * T; x < std::min(W, (tx + 1) * T); ++x) {
                        const size_t i = (size_t(H - 1 - y) * size_t(W) + size_t(x)) * 4;
                        for (int c = 0; c < 3; ++c) {
                            const double d = current[i + size_t(c)] / wnext - previous[i + size_t(c)] / wn;
                            squared += d * d;
                            const double mean = current[i + size_t(c)] / wnext;
                            const double variance =
                                std::max(0.0, squares[i + size_t(c)] / wnext - mean * mean);
                            largest = std::max(largest, std::sqrt(variance / next));
                        }
                        ++count;
                    }
                const bool converged = std::sqrt(squared / (3.0 * count)) < options.tolerance &&
                                       largest < options.pixelTolerance;
                if (converged || next >= options.samples) active[size_t(t)] = 0;
                stillActive += active[size_t(t)];
            }
            previous = std::move(current);
            n = next;
            if (stillActive == 0) break;
        }
        sums = std::move(previous);
    }

    Frame frame;
    frame.width = W, frame.height = H;
    frame.channelNames = {"R", "G", "B"};
    frame.pixels.resize(size_t(W) * size_t(H) * 3);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const int t = (y / T) * tilesX + x / T;
            const double weight = weightPrefix[size_t(tileSamples[size_t(t)])];
            const size_t src = (size_t(H - 1 - y) * size_t(W) + size_t(x)) * 4;
            for (int c = 0; c < 3; ++c)
                frame.pixels[(size_t(y) * size_t(W) + size_t(x)) * 3 + size_t(c)] =
                    float(sums[src + size_t(c)] / weight);
        }
    if (const GLenum error = gl.GetError(); error != GL_NO_ERROR)
        throw Error("OpenGL: error " + std::to_string(error) + " while accumulating the truth");
    if (stats) {
        stats->samples = *std::max_element(tileSamples.begin(), tileSamples.end());
        stats->tileSamples = 0;
        for (int s : tileSamples) stats->tileSamples += s;
        stats->fullTileSamples = int64_t(tiles) * options.samples;
        stats->tiles = tiles;
        stats->rounds = rounds;
        stats->milliseconds = clock.elapsedMs();
    }
    return frame;
}

}  // namespace dejag::render

// dejag/render: the procedural scenes of docs/scenes.md. A Scene is meshes + objects (each with an ID,
// a material and a transform over time) + textures + a camera path + one directional light.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "render/math.h"
#include "render/mesh.h"
#include "render/normal_map.h"

namespace dejag::render {

// How a material's colour varies over its surface.
enum class Pattern {
    Solid,      // material colour
    Texture,    // colour x texture (sampled with the scene's sampler)
    Sweep,      // product of cosines whose frequency rises along u (computed per fragment: no filtering)
    ZonePlate,  // cos(k r^2) around the uv centre
    Bumps,      // solid colour with a procedural normal map (shading aliasing on a shiny surface)
};

struct Material {
    Vec3 colour{0.8, 0.8, 0.8};
    bool lit = true;        // false: lit colour = albedo (the thesis' flat-coloured scenes)
    double specular = 0.0;  // Blinn-Phong
    double shininess = 32.0;
    Pattern pattern = Pattern::Solid;
    int texture = -1;          // index into Scene::textures (Pattern::Texture)
    bool alphaCutout = false;  // discard where the texture's alpha < 0.5 (foliage)
    double frequency = 1.0;    // Sweep / ZonePlate / Bumps scale
    int normalMap = -1;  // Bumps: index into Scene::normalMaps, read when the scene's bump is not procedural
};

// 8-bit RGBA texture made on the CPU; mipmapped by the renderer.
struct TextureImage {
    std::string name;
    int width = 0, height = 0;
    std::vector<uint8_t> rgba;
};

// Fourier: band-limited MIP levels plus the removed frequencies added back per pixel, each attenuated by
// the pixel's footprint (render/fourier_texture.h, docs/texture-aa.md).
enum class Sampler { Point, Bilinear, Trilinear, Anisotropic16, Fourier };
const char* samplerName(Sampler sampler);
Sampler parseSampler(const std::string& name);  // throws dejag::Error listing the choices

// How Pattern::Bumps shades (docs/texture-aa.md): the procedural perturbation evaluated per fragment
// (unfiltered), a normal map read through its standard MIP chain of averaged normals with the scene's
// sampler, or Super Bump Mapping (several lit normals per MIP texel).
enum class Bump { Procedural, Standard, Super };
const char* bumpName(Bump bump);
Bump parseBump(const std::string& name);  // throws dejag::Error listing the choices

// The Fourier sampler's parameters (docs/texture-aa.md).
struct FourierOptions {
    int frequencies = 64;  // sinusoids kept per set (a level, a sub-level and an orientation)
    double cutoff = 0.5;   // MIP level m keeps the frequencies below cutoff x its Nyquist limit (0, 1]
    double sigma = 0.35;   // the Gaussian pixel filter's standard deviation, in pixels
    // A set whose sinusoids hold less than this share of the energy it should add back (a broadband
    // texture, where a truncated sum rings) gives way to the trilinear sample.
    double minCaptured = 0.8;
    // The band levels read along the footprint's major axis: up to this many probes, each at the level
    // of the major axis over their count (1: one isotropic read at the major axis' level, as the thesis
    // does; docs/texture-aa.md, "Anisotropic band reads").
    int probes = 8;
};

struct SceneObject {
    std::string name;
    int mesh = 0;
    Material material;
    uint32_t id = 1;                        // object ID (0 = background)
    std::function<Mat4(double)> transform;  // frame time -> model matrix (null: identity)
    Mat4 at(double t) const { return transform ? transform(t) : Mat4(); }
};

struct CameraPose {
    Vec3 eye{0, 0, 5}, target{0, 0, 0}, up{0, 1, 0};
    double fovY = 45.0 * kPi / 180.0;
};

struct Scene {
    std::string name;
    std::vector<Mesh> meshes;
    std::vector<SceneObject> objects;
    std::vector<TextureImage> textures;
    Sampler sampler = Sampler::Trilinear;
    FourierOptions fourier = {};             // Sampler::Fourier
    std::vector<NormalMapImage> normalMaps;  // Bump::Standard and Bump::Super
    Bump bump = Bump::Procedural;
    int bumpLobes = 4;                         // Bump::Super: lobes a texel, 1 to 4
    std::function<CameraPose(double)> camera;  // frame time -> pose
    Vec3 lightDirection{-0.4, 0.8, 0.45};      // towards the light
    Vec3 lightColour{1.0, 0.97, 0.92};
    Vec3 ambient{0.22, 0.23, 0.26};
    Vec3 background{0.55, 0.62, 0.72};
    double near = 0.1, far = 200.0;

    int addMesh(Mesh mesh) {
        meshes.push_back(std::move(mesh));
        return int(meshes.size()) - 1;
    }
    // Adds an object with the next free ID.
    SceneObject& addObject(const std::string& name, int mesh, const Material& material,
                           std::function<Mat4(double)> transform = nullptr);
    CameraPose cameraAt(double t) const { return camera ? camera(t) : CameraPose(); }
    size_t triangleCount() const;
};

struct SceneOptions {
    uint64_t seed = 1;
    bool tiltedCamera = false;  // --camera tilted: rolled and turned so no edge is axis-aligned
    Sampler sampler = Sampler::Trilinear;
    FourierOptions fourier = {};
    Bump bump = Bump::Procedural;  // the normal-map scene
    int bumpLobes = 4;
    std::string texture = "checker";  // receding planes: checker, bricks, stripes, text, noise
};

struct SceneInfo {
    std::string name, description;
    std::string family;  // for dataset splits: scenes of one family share a look
};

// Every scene dejag can draw, in a stable order.
const std::vector<SceneInfo>& sceneCatalogue();
// Builds a scene by name (see sceneCatalogue()); throws dejag::Error for an unknown one.
Scene buildScene(const std::string& name, const SceneOptions& options = {});

// Procedural textures (exposed for tests).
TextureImage makeTexture(const std::string& kind, int size, uint64_t seed);

}  // namespace dejag::render

// dejag/render: normal maps and Super Bump Mapping (docs/texture-aa.md). A normal map holds unit
// tangent-space normals (z out of the surface). Its standard MIP chain averages the normals under each
// texel, and lighting the average is not averaging the lighting: a distant bumpy surface turns too
// glossy and its highlights alias. The super chain keeps, for each MIP texel, up to `lobes` clusters of
// the full-resolution normals it covers, each with its share of them and its spread, and the shader
// lights every cluster.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace dejag::render {

struct NormalMapImage {
    std::string name;
    int size = 0;                // square, a power of two
    std::vector<float> normals;  // size^2 x (x, y, z), unit, z > 0; row 0 first
};

// "dimples": a hammered surface of smooth bumps and dents at many sizes; "flat": every normal (0, 0, 1).
// Throws dejag::Error for another kind or a size that is not a power of two from 4 up.
NormalMapImage makeNormalMap(const std::string& kind, int size, uint64_t seed);

struct SuperBumpChain {
    int size = 0, levels = 0, lobes = 0;
    // Level l, (size >> l)^2 texels x 4: the average of the normals under the texel (x, y, z, not
    // renormalised) and its length.
    std::vector<std::vector<float>> standard;
    // lobe[j][l]: (size >> l)^2 texels x 4: the lobe's mean direction x and y (z = sqrt(1 - x^2 - y^2)),
    // its weight (its share of the normals under the texel; 0: no such lobe) and the length R of its
    // normals' mean (1: all alike; less: spread).
    std::vector<std::vector<std::vector<float>>> lobe;
};

// The standard chain (the texels' normals averaged) and the super chain with `lobes` clusters a texel
// (1 to 8; 0: the standard chain alone): spherical k-means from a farthest-first start, to a stable
// assignment (at most 16 rounds), on the surface the renderer draws at level 0 — the bilinearly interpolated
// normals, sampled twice a texel each way — under each texel of level 1 and up (level 0: the texel's own
// normal). Deterministic.
SuperBumpChain buildSuperBumpChain(const NormalMapImage& map, int lobes);

// The Blinn-Phong exponent that lights a lobe of mean length R as a spread of normals does (Toksvig):
// s R / (R + s (1 - R)).
double toksvigExponent(double shininess, double meanLength);

}  // namespace dejag::render

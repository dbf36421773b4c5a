// dejag/render: triangle meshes built procedurally (nothing is loaded from disk).
#pragma once

#include <cstdint>
#include <vector>

#include "render/math.h"

namespace dejag::render {

struct Vertex {
    float position[3];
    float normal[3];
    float uv[2];
};

struct Mesh {
    std::vector<Vertex> vertices;
    std::vector<uint32_t> indices;  // triangles

    // Appends `other` transformed by `transform` (normals by its rotation part; no shear expected).
    void append(const Mesh& other, const Mat4& transform = Mat4());
    size_t triangleCount() const { return indices.size() / 3; }
};

// A UV sphere of radius r centred at the origin.
Mesh makeSphere(double radius, int slices = 48, int stacks = 24);
// An axis-aligned box centred at the origin with the given full sizes.
Mesh makeBox(const Vec3& size);
// A rectangle in the XY plane facing +z, centred at the origin; uv spans [0, uRepeat] x [0, vRepeat].
Mesh makeQuad(double width, double height, double uRepeat = 1.0, double vRepeat = 1.0);
// A tube of radius r along a polyline (parallel-transported frame), open ends; uv: u along, v around.
Mesh makeTube(const std::vector<Vec3>& path, double radius, int sides = 12);

}  // namespace dejag::render

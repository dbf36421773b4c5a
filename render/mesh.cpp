#include "render/mesh.h"

#include <cmath>

namespace dejag::render {

namespace {
Vertex vertex(const Vec3& p, const Vec3& n, double u, double v) {
    return {{float(p.x), float(p.y), float(p.z)}, {float(n.x), float(n.y), float(n.z)}, {float(u), float(v)}};
}
}  // namespace

void Mesh::append(const Mesh& other, const Mat4& transform) {
    const uint32_t base = uint32_t(vertices.size());
    vertices.reserve(vertices.size() + other.vertices.size());
    for (const Vertex& v : other.vertices) {
        const Vec3 p = transform.transformPoint({v.position[0], v.position[1], v.position[2]});
        const Vec3 n = normalize(transform.transformDirection({v.normal[0], v.normal[1], v.normal[2]}));
        vertices.push_back(vertex(p, n, v.uv[0], v.uv[1]));
    }
    indices.reserve(indices.size() + other.indices.size());
    for (uint32_t i : other.indices) indices.push_back(base + i);
}

Mesh makeSphere(double radius, int slices, int stacks) {
    Mesh m;
    for (int i = 0; i <= stacks; ++i) {
        const double v = double(i) / stacks, theta = v * kPi;
        for (int j = 0; j <= slices; ++j) {
            const double u = double(j) / slices, phi = u * 2 * kPi;
            const Vec3 n{std::sin(theta) * std::cos(phi), std::cos(theta), std::sin(theta) * std::sin(phi)};
            m.vertices.push_back(vertex(n * radius, n, u, v));
        }
    }
    for (int i = 0; i < stacks; ++i)
        for (int j = 0; j < slices; ++j) {
            const uint32_t a = uint32_t(i * (slices + 1) + j), b = a + uint32_t(slices + 1);
            m.indices.insert(m.indices.end(), {a, a + 1, b, a + 1, b + 1, b});
        }
    return m;
}

Mesh makeQuad(double width, double height, double uRepeat, double vRepeat) {
    Mesh m;
    const double w = width / 2, h = height / 2;
    const Vec3 n{0, 0, 1};
    m.vertices = {vertex({-w, -h, 0}, n, 0, vRepeat), vertex({w, -h, 0}, n, uRepeat, vRepeat),
                  vertex({w, h, 0}, n, uRepeat, 0), vertex({-w, h, 0}, n, 0, 0)};
    m.indices = {0, 1, 2, 0, 2, 3};
    return m;
}

Mesh makeBox(const Vec3& size) {
    Mesh m;
    const Vec3 h = size * 0.5;
    // Six faces: a quad each, rotated into place.
    m.append(makeQuad(size.x, size.y), Mat4::translation({0, 0, h.z}));
    m.append(makeQuad(size.x, size.y), Mat4::translation({0, 0, -h.z}) * Mat4::rotation({0, 1, 0}, kPi));
    m.append(makeQuad(size.z, size.y), Mat4::translation({h.x, 0, 0}) * Mat4::rotation({0, 1, 0}, kPi / 2));
    m.append(makeQuad(size.z, size.y), Mat4::translation({-h.x, 0, 0}) * Mat4::rotation({0, 1, 0}, -kPi / 2));
    m.append(makeQuad(size.x, size.z), Mat4::translation({0, h.y, 0}) * Mat4::rotation({1, 0, 0}, -kPi / 2));
    m.append(makeQuad(size.x, size.z), Mat4::translation({0, -h.y, 0}) * Mat4::rotation({1, 0, 0}, kPi / 2));
    return m;
}

Mesh makeTube(const std::vector<Vec3>& path, double radius, int sides) {
    Mesh m;
    if (path.size() < 2) return m;
    // Parallel transport: carry a normal along the path, rotating it with each tangent change.
    Vec3 tangent = normalize(path[1] - path[0]);
    Vec3 normal = std::abs(tangent.y) < 0.9 ? normalize(cross(tangent, {0, 1, 0}))
                                            : normalize(cross(tangent, {1, 0, 0}));
    double along = 0;
    for (size_t i = 0; i < path.size(); ++i) {
        if (i > 0) along += length(path[i] - path[i - 1]);
        const Vec3 next = i + 1 < path.size() ? normalize(path[i + 1] - path[i]) : tangent;
        const Vec3 t = i == 0 ? next : normalize(tangent + next);
        normal = normalize(normal - t * dot(normal, t));
        const Vec3 binormal = cross(t, normal);
        for (int s = 0; s <= sides; ++s) {
            const double a = 2 * kPi * s / sides;
            const Vec3 n = normal * std::cos(a) + binormal * std::sin(a);
            m.vertices.push_back(vertex(path[i] + n * radius, n, along, double(s) / sides));
        }
        tangent = next;
    }
    const uint32_t ring = uint32_t(sides + 1);
    for (uint32_t i = 0; i + 1 < path.size(); ++i)
        for (uint32_t s = 0; s < uint32_t(sides); ++s) {
            const uint32_t a = i * ring + s, b = a + ring;
            m.indices.insert(m.indices.end(), {a, b, a + 1, a + 1, b, b + 1});
        }
    return m;
}

}  // namespace dejag::render

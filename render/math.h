// dejag/render: the little linear algebra a renderer needs. Column-major 4x4 matrices as OpenGL reads
// them (m[column * 4 + row]); right-handed view space looking down -z.
#pragma once

#include <array>
#include <cmath>

namespace dejag::render {

struct Vec2 {
    double x = 0, y = 0;
};

struct Vec3 {
    double x = 0, y = 0, z = 0;
    Vec3 operator+(const Vec3& o) const { return {x + o.x, y + o.y, z + o.z}; }
    Vec3 operator-(const Vec3& o) const { return {x - o.x, y - o.y, z - o.z}; }
    Vec3 operator*(double s) const { return {x * s, y * s, z * s}; }
    Vec3 operator-() const { return {-x, -y, -z}; }
};
inline double dot(const Vec3& a, const Vec3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}
inline Vec3 cross(const Vec3& a, const Vec3& b) {
    return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}
inline double length(const Vec3& v) {
    return std::sqrt(dot(v, v));
}
inline Vec3 normalize(const Vec3& v) {
    const double l = length(v);
    return l > 0 ? v * (1.0 / l) : Vec3{0, 0, 1};
}
inline Vec3 lerp(const Vec3& a, const Vec3& b, double t) {
    return a + (b - a) * t;
}

struct Mat4 {
    std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};  // identity
    double& at(int row, int column) { return m[size_t(column * 4 + row)]; }
    double at(int row, int column) const { return m[size_t(column * 4 + row)]; }

    Mat4 operator*(const Mat4& o) const {
        Mat4 r;
        for (int i = 0; i < 4; ++i)
            for (int j = 0; j < 4; ++j) {
                double s = 0;
                for (int k = 0; k < 4; ++k) s += at(i, k) * o.at(k, j);
                r.at(i, j) = s;
            }
        return r;
    }
    // Transforms a point (w = 1) and returns the homogeneous result's xyz and w.
    std::array<double, 4> apply(const Vec3& p, double w = 1.0) const {
        std::array<double, 4> r{};
        for (int i = 0; i < 4; ++i)
            r[size_t(i)] = at(i, 0) * p.x + at(i, 1) * p.y + at(i, 2) * p.z + at(i, 3) * w;
        return r;
    }
    Vec3 transformPoint(const Vec3& p) const {
        const auto r = apply(p);
        return {r[0] / r[3], r[1] / r[3], r[2] / r[3]};
    }
    Vec3 transformDirection(const Vec3& d) const {
        const auto r = apply(d, 0.0);
        return {r[0], r[1], r[2]};
    }
    std::array<float, 16> toFloat() const {
        std::array<float, 16> f{};
        for (size_t i = 0; i < 16; ++i) f[i] = float(m[i]);
        return f;
    }

    static Mat4 translation(const Vec3& t) {
        Mat4 r;
        r.at(0, 3) = t.x, r.at(1, 3) = t.y, r.at(2, 3) = t.z;
        return r;
    }
    static Mat4 scaling(const Vec3& s) {
        Mat4 r;
        r.at(0, 0) = s.x, r.at(1, 1) = s.y, r.at(2, 2) = s.z;
        return r;
    }
    // Rotation by `angle` radians about a unit axis (right-handed).
    static Mat4 rotation(const Vec3& axisIn, double angle) {
        const Vec3 a = normalize(axisIn);
        const double c = std::cos(angle), s = std::sin(angle), t = 1 - c;
        Mat4 r;
        r.at(0, 0) = t * a.x * a.x + c, r.at(0, 1) = t * a.x * a.y - s * a.z,
                r.at(0, 2) = t * a.x * a.z + s * a.y;
        r.at(1, 0) = t * a.x * a.y + s * a.z, r.at(1, 1) = t * a.y * a.y + c,
                r.at(1, 2) = t * a.y * a.z - s * a.x;
        r.at(2, 0) = t * a.x * a.z - s * a.y, r.at(2, 1) = t * a.y * a.z + s * a.x,
                r.at(2, 2) = t * a.z * a.z + c;
        return r;
    }
    static Mat4 lookAt(const Vec3& eye, const Vec3& target, const Vec3& up) {
        const Vec3 f = normalize(target - eye), s = normalize(cross(f, up)), u = cross(s, f);
        Mat4 r;
        r.at(0, 0) = s.x, r.at(0, 1) = s.y, r.at(0, 2) = s.z, r.at(0, 3) = -dot(s, eye);
        r.at(1, 0) = u.x, r.at(1, 1) = u.y, r.at(1, 2) = u.z, r.at(1, 3) = -dot(u, eye);
        r.at(2, 0) = -f.x, r.at(2, 1) = -f.y, r.at(2, 2) = -f.z, r.at(2, 3) = dot(f, eye);
        return r;
    }
    // OpenGL perspective projection; fovY in radians.
    static Mat4 perspective(double fovY, double aspect, double near, double far) {
        const double f = 1.0 / std::tan(fovY / 2);
        Mat4 r;
        r.m.fill(0);
        r.at(0, 0) = f / aspect, r.at(1, 1) = f;
        r.at(2, 2) = (far + near) / (near - far), r.at(2, 3) = 2 * far * near / (near - far);
        r.at(3, 2) = -1;
        return r;
    }
};

constexpr double kPi = 3.14159265358979323846;

}  // namespace dejag::render

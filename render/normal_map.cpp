#include "render/normal_map.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "base/error.h"
#include "base/random.h"
#include "base/thread_pool.h"

namespace dejag::render {
namespace {

struct V3 {
    double x = 0, y = 0, z = 0;
};
double dot(const V3& a, const V3& b) {
    return a.x * b.x + a.y * b.y + a.z * b.z;
}

constexpr int kDensity = 2;  // samples of the interpolated normals a texel, each way
// "dimples": how many, and their radii as fractions of the tile.
constexpr int kBumps = 600;
constexpr double kSmallest = 0.006, kLargest = 0.03;

}  // namespace

NormalMapImage makeNormalMap(const std::string& kind, int size, uint64_t seed) {
    if (size < 4 || (size & (size - 1)) != 0)
        throw Error("a normal map is square with a power-of-two size from 4 up, not " + std::to_string(size));
    NormalMapImage map;
    map.name = kind, map.size = size;
    map.normals.assign(size_t(size) * size_t(size) * 3, 0.0f);
    if (kind == "flat") {
        for (size_t i = 0; i < map.normals.size(); i += 3) map.normals[i + 2] = 1.0f;
        return map;
    }
    if (kind != "dimples") throw Error("unknown normal map '" + kind + "' (dimples, flat)");
    // A periodic height field: smooth bumps and dents (a (1 - r^2)^2 profile) of radius 3 % to 12 % of
    // the tile at random places, then the normal of height x slope scale by central differences.
    std::vector<double> height(size_t(size) * size_t(size), 0.0);
    uint64_t state = seed ^ 0xB0B5ull;
    const auto next = [&](double low, double high) { return unitInterval(splitMix64(state++), low, high); };
    for (int i = 0; i < kBumps; ++i) {
        const double cx = next(0, size), cy = next(0, size), radius = next(kSmallest, kLargest) * size;
        const double amplitude = next(-1, 1) * radius * 0.35;
        const int reach = int(std::ceil(radius));
        for (int dy = -reach; dy <= reach; ++dy)
            for (int dx = -reach; dx <= reach; ++dx) {
                const int x = int(std::floor(cx)) + dx, y = int(std::floor(cy)) + dy;
                const double rx = (x + 0.5 - cx) / radius, ry = (y + 0.5 - cy) / radius,
                             r2 = rx * rx + ry * ry;
                if (r2 >= 1) continue;
                height[size_t(((y % size) + size) % size) * size_t(size) +
                       size_t(((x % size) + size) % size)] += amplitude * (1 - r2) * (1 - r2);
            }
    }
    const auto h = [&](int x, int y) {
        return height[size_t(((y % size) + size) % size) * size_t(size) + size_t(((x % size) + size) % size)];
    };
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const double gx = 0.5 * (h(x + 1, y) - h(x - 1, y)), gy = 0.5 * (h(x, y + 1) - h(x, y - 1));
            const double length = std::sqrt(gx * gx + gy * gy + 1);
            float* n = &map.normals[(size_t(y) * size_t(size) + size_t(x)) * 3];
            n[0] = float(-gx / length), n[1] = float(-gy / length), n[2] = float(1 / length);
        }
    return map;
}

double toksvigExponent(double shininess, double meanLength) {
    const double r = std::clamp(meanLength, 1e-6, 1.0);
    return shininess * r / (r + shininess * (1 - r));
}

SuperBumpChain buildSuperBumpChain(const NormalMapImage& map, int lobes) {
    const int n = map.size;
    if (n < 4 || (n & (n - 1)) != 0 || map.normals.size() != size_t(n) * size_t(n) * 3)
        throw Error("normal map '" + map.name + "': not a square power-of-two map of normals");
    if (lobes < 0 || lobes > 8)
        throw Error("super bump mapping keeps 1 to 8 lobes a texel (0: the standard chain alone), not " +
                    std::to_string(lobes));
    SuperBumpChain chain;
    chain.size = n, chain.lobes = lobes;
    chain.levels = 1;
    while ((1 << (chain.levels - 1)) < n) ++chain.levels;
    chain.standard.resize(size_t(chain.levels));
    chain.lobe.assign(size_t(lobes), std::vector<std::vector<float>>(size_t(chain.levels)));
    const auto normalAt = [&](int x, int y) {
        // Renormalised in double: a float normal's own dot product is 1 only within 1e-7, more than
        // the cosine between close neighbours, which would steer the assignment.
        const float* p = &map.normals[(size_t(y) * size_t(n) + size_t(x)) * 3];
        const double length = std::sqrt(double(p[0]) * p[0] + double(p[1]) * p[1] + double(p[2]) * p[2]);
        return V3{p[0] / length, p[1] / length, p[2] / length};
    };
    // The normal at level-0 texel coordinates (x, y) (texel centres at whole numbers here), bilinear.
    const auto interpolated = [&](double x, double y) {
        const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
        const double fx = x - x0, fy = y - y0;
        V3 v;
        for (int j = 0; j < 2; ++j)
            for (int i = 0; i < 2; ++i) {
                const V3 c = normalAt(((x0 + i) % n + n) % n, ((y0 + j) % n + n) % n);
                const double w = (i ? fx : 1 - fx) * (j ? fy : 1 - fy);
                v.x += w * c.x, v.y += w * c.y, v.z += w * c.z;
            }
        const double length = std::sqrt(dot(v, v));
        return V3{v.x / length, v.y / length, v.z / length};
    };
    for (int level = 0; level < chain.levels; ++level) {
        const int texels = n >> level, block = 1 << level;
        chain.standard[size_t(level)].assign(size_t(texels) * size_t(texels) * 4, 0.0f);
        for (int j = 0; j < lobes; ++j)
            chain.lobe[size_t(j)][size_t(level)].assign(size_t(texels) * size_t(texels) * 4, 0.0f);
        const int side = level == 0 ? 1 : block * kDensity;
        parallelFor(0, int64_t(texels) * texels, 16, [&](int64_t first, int64_t last) {
            std::vector<V3> normals(size_t(side) * size_t(side));
            std::vector<int> owner(normals.size());
            std::vector<V3> centre(static_cast<size_t>(lobes)), sum(static_cast<size_t>(lobes));
            std::vector<int> count(static_cast<size_t>(lobes));
            for (int64_t t = first; t < last; ++t) {
                const int tx = int(t % texels), ty = int(t / texels);
                V3 mean;
                for (int y = 0; y < block; ++y)
                    for (int x = 0; x < block; ++x) {
                        const V3 v = normalAt(tx * block + x, ty * block + y);
                        mean.x += v.x, mean.y += v.y, mean.z += v.z;
                    }
                const double texelCount = double(block) * block;
                mean = {mean.x / texelCount, mean.y / texelCount, mean.z / texelCount};
                // The lobes cluster the surface the renderer draws at level 0 (bilinearly interpolated
                // normals, renormalised), sampled twice a texel each way: between texel centres a very
                // shiny surface lights normals that no texel holds.
                for (int y = 0; y < side; ++y)
                    for (int x = 0; x < side; ++x)
                        normals[size_t(y) * size_t(side) + size_t(x)] =
                            level == 0 ? normalAt(tx, ty)
                                       : interpolated(tx * block + (x + 0.5) / kDensity - 0.5,
                                                      ty * block + (y + 0.5) / kDensity - 0.5);
                const double total = double(normals.size());
                float* standard = &chain.standard[size_t(level)][size_t(t) * 4];
                standard[0] = float(mean.x), standard[1] = float(mean.y), standard[2] = float(mean.z);
                standard[3] = float(std::sqrt(dot(mean, mean)));
                if (lobes == 0) continue;
                // Farthest-first start: the normal nearest the mean, then each time the one farthest
                // from every centre so far (ties: the first).
                const int k = int(std::min<size_t>(size_t(lobes), normals.size()));
                size_t best = 0;
                for (size_t i = 1; i < normals.size(); ++i)
                    if (dot(normals[i], mean) > dot(normals[best], mean)) best = i;
                centre[0] = normals[best];
                int used = 1;
                for (; used < k; ++used) {
                    size_t farthest = 0;
                    double farthestDot = 2;
                    for (size_t i = 0; i < normals.size(); ++i) {
                        double nearest = -2;
                        for (int c = 0; c < used; ++c)
                            nearest = std::max(nearest, dot(normals[i], centre[size_t(c)]));
                        if (nearest < farthestDot) farthestDot = nearest, farthest = i;
                    }
                    if (farthestDot > 1 - 1e-9) break;  // every normal already sits on a centre
                    centre[size_t(used)] = normals[farthest];
                }
                std::fill(owner.begin(), owner.end(), -1);
                for (int round = 0; round < 16; ++round) {
                    bool changed = false;
                    for (size_t i = 0; i < normals.size(); ++i) {
                        int nearest = 0;
                        for (int c = 1; c < used; ++c)
                            if (dot(normals[i], centre[size_t(c)]) > dot(normals[i], centre[size_t(nearest)]))
                                nearest = c;
                        if (owner[i] != nearest) owner[i] = nearest, changed = true;
                    }
                    std::fill(sum.begin(), sum.end(), V3{});
                    std::fill(count.begin(), count.end(), 0);
                    for (size_t i = 0; i < normals.size(); ++i) {
                        V3& s = sum[size_t(owner[i])];
                        s.x += normals[i].x, s.y += normals[i].y, s.z += normals[i].z;
                        ++count[size_t(owner[i])];
                    }
                    for (int c = 0; c < used; ++c) {
                        const double length = std::sqrt(dot(sum[size_t(c)], sum[size_t(c)]));
                        if (count[size_t(c)] > 0 && length > 0)
                            centre[size_t(c)] = {sum[size_t(c)].x / length, sum[size_t(c)].y / length,
                                                 sum[size_t(c)].z / length};
                    }
                    if (!changed) break;
                }
                for (int c = 0; c < used; ++c) {
                    if (count[size_t(c)] == 0) continue;
                    float* lobe = &chain.lobe[size_t(c)][size_t(level)][size_t(t) * 4];
                    lobe[0] = float(centre[size_t(c)].x), lobe[1] = float(centre[size_t(c)].y);
                    lobe[2] = float(count[size_t(c)] / total);
                    lobe[3] = float(std::sqrt(dot(sum[size_t(c)], sum[size_t(c)])) / count[size_t(c)]);
                }
            }
        });
    }
    return chain;
}

}  // namespace dejag::render

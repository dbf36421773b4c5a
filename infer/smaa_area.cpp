// SMAA's pattern areas and its published textures (infer/smaa_area.h; the definitions in docs/smaa.md).
#include "infer/smaa_area.h"

#include <algorithm>
#include <cmath>

namespace dejag::infer {

namespace {

struct Point {
    double x, y;
};
Point operator+(Point a, Point b) {
    return {a.x + b.x, a.y + b.y};
}

using Areas = std::array<double, 2>;  // {near (y < 0), far (y > 0)}

Areas operator+(Areas a, Areas b) {
    return {a[0] + b[0], a[1] + b[1]};
}
Areas mean(Areas a, Areas b) {
    return {(a[0] + b[0]) / 2, (a[1] + b[1]) / 2};
}

// The areas between the line through a and b and the run (y = 0) over the pixel column [x, x + 1], where
// the column overlaps [a.x, b.x]: what lies below the run is the near share, above it the far share.
Areas columnArea(Point a, Point b, int column) {
    const double dx = b.x - a.x, dy = b.y - a.y;
    const double x1 = column, x2 = column + 1.0;
    const double y1 = a.y + dy * (x1 - a.x) / dx, y2 = a.y + dy * (x2 - a.x) / dx;
    const bool overlaps = (x1 >= a.x && x1 < b.x) || (x2 > a.x && x2 <= b.x);
    if (!overlaps) return {0, 0};
    if (std::signbit(y1) == std::signbit(y2) || std::abs(y1) < 1e-4 || std::abs(y2) < 1e-4) {
        const double m = (y1 + y2) / 2;  // a trapezoid on one side
        return m < 0 ? Areas{-m, 0} : Areas{0, m};
    }
    // The line crosses the run inside the column, at xc: a triangle on each side, each counted where
    // it lies within the segment.
    const double xc = a.x - a.y * dx / dy;
    const double f = xc - std::floor(xc);
    const double left = xc > a.x ? y1 * f / 2 : 0.0;
    const double right = xc < b.x ? y2 * (1 - f) / 2 : 0.0;
    const double larger = std::abs(left) > std::abs(right) ? left : -right;
    return larger < 0 ? Areas{std::abs(left), std::abs(right)} : Areas{std::abs(right), std::abs(left)};
}

// U shapes of few pixels are rounded: each area a becomes sqrt(2 a) / 2 at d = 0, blending back to a by
// d = 32.
Areas smoothU(double d, Areas a, Areas b) {
    const double p = std::clamp(d / 32.0, 0.0, 1.0);
    Areas sum{0, 0};
    for (const Areas& s : {a, b})
        for (int k = 0; k < 2; ++k) {
            const double rounded = std::sqrt(2 * s[size_t(k)]) / 2;
            sum[size_t(k)] += rounded + (s[size_t(k)] - rounded) * p;
        }
    return sum;
}

// The share of the unit pixel at `pixel` on the positive side of the line through p1 and p2, counted on
// a 30 x 30 grid of points spanning the pixel edge to edge (the published texture's count).
double sampledArea(Point p1, Point p2, Point pixel) {
    constexpr int kSamples = 30;
    if (p1.x == p2.x && p1.y == p2.y) return 1.0;
    const double mx = (p1.x + p2.x) / 2, my = (p1.y + p2.y) / 2;
    const double a = p2.y - p1.y, b = p1.x - p2.x;
    int inside = 0;
    for (int i = 0; i < kSamples; ++i)
        for (int j = 0; j < kSamples; ++j) {
            const double x = pixel.x + double(i) / (kSamples - 1), y = pixel.y + double(j) / (kSamples - 1);
            inside += a * (x - mx) + b * (y - my) > 0;
        }
    return double(inside) / (kSamples * kSamples);
}

// The crossing codes (c1, c2) of each diagonal pattern: the published texture's block of the pattern.
constexpr int kDiagonalCodes[16][2] = {{0, 0}, {1, 0}, {0, 2}, {1, 2}, {2, 0}, {3, 0}, {2, 2}, {3, 2},
                                       {0, 1}, {1, 1}, {0, 3}, {1, 3}, {2, 1}, {3, 1}, {2, 3}, {3, 3}};
// The crossing slots (round(4 e) of the bilinear fetch at a quarter pixel: 0, 1 far, 3 near, 4 both) of
// each orthogonal pattern at its two ends: the published texture's block of the pattern.
constexpr int kOrthogonalSlots[16][2] = {{0, 0}, {3, 0}, {0, 3}, {3, 3}, {1, 0}, {4, 0}, {1, 3}, {4, 3},
                                         {0, 1}, {3, 1}, {0, 4}, {3, 4}, {1, 1}, {4, 1}, {1, 4}, {4, 4}};

}  // namespace

std::array<float, 2> smaaOrthogonalArea(int pattern, int left, int right, float offset) {
    // The run spans [0, d] along x; the pixel is the column [left, left + 1]. A crossing edge on the near
    // side at an end puts the true line half a pixel below the run there (o2), on the far side half a
    // pixel above (o1); the line is revectorised from the ends to the run's middle, or end to end for a
    // Z shape.
    const double d = left + right + 1;
    const double o1 = 0.5 + offset, o2 = -0.5 + offset;
    auto area = [&](Point a, Point b) { return columnArea(a, b, left); };
    const Point mid{d / 2, 0};
    Areas a{0, 0};
    switch (pattern) {
        case 1:  // near crossing at the left end only: an L (the half nearer that end)
            if (left <= right) a = area({0, o2}, mid);
            break;
        case 2:
            if (left >= right) a = area(mid, {d, o2});
            break;
        case 3:  // a U on the near side
            a = smoothU(d, area({0, o2}, mid), area(mid, {d, o2}));
            break;
        case 4:
            if (left <= right) a = area({0, o1}, mid);
            break;
        case 6:  // a Z from far-left to near-right
            a = offset != 0 ? mean(area({0, o1}, {d, o2}), area({0, o1}, mid) + area(mid, {d, o2}))
                            : area({0, o1}, {d, o2});
            break;
        case 7:
            a = area({0, o1}, {d, o2});
            break;
        case 8:
            if (left >= right) a = area(mid, {d, o1});
            break;
        case 9:
            a = offset != 0 ? mean(area({0, o2}, {d, o1}), area({0, o2}, mid) + area(mid, {d, o1}))
                            : area({0, o2}, {d, o1});
            break;
        case 11:
        case 13:
            a = area({0, o2}, {d, o1});
            break;
        case 12:  // a U on the far side
            a = smoothU(d, area({0, o1}, mid), area(mid, {d, o1}));
            break;
        case 14:
            a = area({0, o1}, {d, o2});
            break;
        default:  // 0 (no crossing), 5, 10, 15 (crossings on both sides of an end): nothing to revectorise
            break;
    }
    return {float(a[0]), float(a[1])};
}

int smaaDiagonalPattern(int c1, int c2) {
    return (c1 & 1) | (c2 & 2) | (c1 & 2) << 1 | (c2 & 1) << 3;
}

std::array<float, 2> smaaDiagonalArea(int pattern, int left, int right, float offsetX, float offsetY) {
    // The diagonal runs from one end to the other across d pixels; its two flanking pixels at step
    // `left` are (1 + left, left) and (1 + left, 1 + left). Where an end's shape is not known (no
    // crossing, or an L whose far end could be either), the area is the mean of the candidate lines.
    const double d = left + right + 1;
    const Point zero{0, 0}, x{1, 0}, one{1, 1}, span{d, d};
    const Point shift{offsetX, offsetY};
    auto area = [&](Point p1, Point p2) -> Areas {
        if (kDiagonalCodes[pattern][0] > 0) p1 = p1 + shift;
        if (kDiagonalCodes[pattern][1] > 0) p2 = p2 + shift;
        const double a1 = sampledArea(p1, p2, {1.0 + left, double(left)});
        const double a2 = sampledArea(p1, p2, {1.0 + left, 1.0 + left});
        return {1 - a1, a2};
    };
    Areas a{0, 0};
    switch (pattern) {
        case 0:
            a = mean(area(one, one + span), area(x, x + span));
            break;
        case 1:
            a = mean(area(x, zero + span), area(x, x + span));
            break;
        case 2:
            a = mean(area(zero, x + span), area(x, x + span));
            break;
        case 3:
            a = area(x, x + span);
            break;
        case 4:
            a = mean(area(one, zero + span), area(one, x + span));
            break;
        case 5:
            a = mean(area(one, zero + span), area(x, x + span));
            break;
        case 6:
            a = area(one, x + span);
            break;
        case 7:
            a = mean(area(one, x + span), area(x, x + span));
            break;
        case 8:
            a = mean(area(zero, one + span), area(x, one + span));
            break;
        case 9:
            a = area(x, one + span);
            break;
        case 10:
            a = mean(area(zero, one + span), area(x, x + span));
            break;
        case 11:
            a = mean(area(x, one + span), area(x, x + span));
            break;
        case 12:
            a = area(one, one + span);
            break;
        case 13:
            a = mean(area(one, one + span), area(x, one + span));
            break;
        case 14:
            a = mean(area(one, one + span), area(one, x + span));
            break;
        default:
            a = mean(area(one, one + span), area(x, x + span));
            break;  // 15
    }
    return {float(a[0]), float(a[1])};
}

const float* smaaDiagonalAreaTable() {
    static const std::vector<float> table = [] {
        std::vector<float> t(size_t(16) * kSmaaDiagonalMax * kSmaaDiagonalMax * 2);
        for (int p = 0; p < 16; ++p)
            for (int l = 0; l < kSmaaDiagonalMax; ++l)
                for (int r = 0; r < kSmaaDiagonalMax; ++r) {
                    const auto a = smaaDiagonalArea(p, l, r);
                    float* dst =
                        t.data() +
                        ((size_t(p) * kSmaaDiagonalMax + size_t(l)) * kSmaaDiagonalMax + size_t(r)) * 2;
                    dst[0] = a[0], dst[1] = a[1];
                }
        return t;
    }();
    return table.data();
}

std::vector<uint8_t> smaaAreaTexture() {
    constexpr int kOrthogonalSize = 16, kDiagonalSize = 20;
    constexpr float kOrthogonalOffsets[7] = {0.0f, -0.25f, 0.25f, -0.125f, 0.125f, -0.375f, 0.375f};
    constexpr float kDiagonalOffsets[5][2] = {
        {0.0f, 0.0f}, {0.25f, -0.25f}, {-0.25f, 0.25f}, {0.125f, -0.125f}, {-0.125f, 0.125f}};
    std::vector<uint8_t> texture(size_t(kSmaaAreaTextureWidth) * kSmaaAreaTextureHeight * 2, 0);
    auto put = [&](int x, int y, std::array<float, 2> a) {
        uint8_t* texel = texture.data() + (size_t(y) * kSmaaAreaTextureWidth + size_t(x)) * 2;
        texel[0] = uint8_t(a[0] * 255.0f), texel[1] = uint8_t(a[1] * 255.0f);
    };
    for (int s = 0; s < 7; ++s)
        for (int p = 0; p < 16; ++p)
            for (int y = 0; y < kOrthogonalSize; ++y)
                for (int x = 0; x < kOrthogonalSize; ++x)  // indexed by the distances' square roots
                    put(kOrthogonalSize * kOrthogonalSlots[p][0] + x,
                        5 * kOrthogonalSize * s + kOrthogonalSize * kOrthogonalSlots[p][1] + y,
                        smaaOrthogonalArea(p, x * x, y * y, kOrthogonalOffsets[s]));
    for (int s = 0; s < 5; ++s)
        for (int p = 0; p < 16; ++p)
            for (int y = 0; y < kDiagonalSize; ++y)
                for (int x = 0; x < kDiagonalSize; ++x)
                    put(5 * kOrthogonalSize + kDiagonalSize * kDiagonalCodes[p][0] + x,
                        4 * kDiagonalSize * s + kDiagonalSize * kDiagonalCodes[p][1] + y,
                        smaaDiagonalArea(p, x, y, kDiagonalOffsets[s][0], kDiagonalOffsets[s][1]));
    return texture;
}

std::vector<uint8_t> smaaSearchTexture() {
    // A search fetches four edges at once, bilinearly at (-0.25, -0.125) from pixel 3:
    //   e0 e1      (the row above)
    //   e2 e3      (the run's row; e3 the pixel, e2 its neighbour in the search's direction)
    auto bilinear = [](const int e[4]) {
        const float up = float(e[0]) + (float(e[1]) - float(e[0])) * 0.75f;
        const float down = float(e[2]) + (float(e[3]) - float(e[2])) * 0.75f;
        return up + (down - up) * 0.875f;
    };
    struct Combination {
        float value;
        int e[4];
    };
    std::vector<Combination> combinations;
    for (int bits = 0; bits < 16; ++bits) {
        Combination c{};
        for (int k = 0; k < 4; ++k) c.e[k] = bits >> (3 - k) & 1;
        c.value = bilinear(c.e);
        combinations.push_back(c);
    }
    auto find = [&](float value) -> const int* {
        for (const Combination& c : combinations)
            if (c.value == value) return c.e;
        return nullptr;
    };
    // crossing: the crossing (left/top) edges of the four pixels; run: their run (top/left) edges.
    auto deltaLeft = [](const int* crossing, const int* run) {
        if (!run[3]) return 0;
        return run[2] && !crossing[1] && !crossing[3] ? 2 : 1;
    };
    auto deltaRight = [](const int* crossing, const int* run) {
        if (!(run[3] && !crossing[1] && !crossing[3])) return 0;
        return run[2] && !crossing[0] && !crossing[2] ? 2 : 1;
    };
    std::vector<uint8_t> texture(size_t(kSmaaSearchTextureWidth) * kSmaaSearchTextureHeight, 0);
    for (int x = 0; x <= 32; ++x)
        for (int y = 0; y < kSmaaSearchTextureHeight; ++y) {
            const int* crossing = find(0.03125f * float(x));
            const int* run = find(0.03125f * float(32 - y));
            if (!crossing || !run) continue;
            texture[size_t(y) * kSmaaSearchTextureWidth + size_t(x)] =
                uint8_t(127 * deltaLeft(crossing, run));
            if (x < 31)
                texture[size_t(y) * kSmaaSearchTextureWidth + size_t(x) + 33] =
                    uint8_t(127 * deltaRight(crossing, run));
        }
    return texture;
}

}  // namespace dejag::infer

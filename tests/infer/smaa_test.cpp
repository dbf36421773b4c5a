// SMAA 1x: constant images pass unchanged, aliased edges (synthetic and rendered) get closer to their
// truth, the result is independent of threads, in-place filtering and SIMD level, and the area and search
// textures keep their published invariants (the search ends dejag finds are the ones SMAA's bilinear search
// reads through the generated search texture).
#include "infer/smaa.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/random.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "data/frame_image.h"
#include "infer/smaa_area.h"
#include "render/renderer.h"

namespace dejag::infer {
namespace {

double mse(const std::vector<float>& a, const std::vector<float>& b, int channels = 3) {
    double squared = 0;
    size_t count = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        if (int(i % size_t(channels)) >= 3) continue;
        squared += double(a[i] - b[i]) * double(a[i] - b[i]);
        ++count;
    }
    return squared / double(count);
}

double decode(double v) {
    return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4);
}
double encode(double v) {
    return v <= 0.0031308 ? v * 12.92 : 1.055 * std::pow(v, 1 / 2.4) - 0.055;
}

// A half-plane below y = slope x + offset in one colour over another: point-sampled at pixel centres
// (aliased) and area-averaged in linear light over 32 x 32 sub-samples (truth), as dejag's truths are.
void straightEdge(int size, double slope, double offset, std::vector<float>& aliased,
                  std::vector<float>& truth) {
    aliased.assign(size_t(size * size * 3), 0.0f);
    truth.assign(size_t(size * size * 3), 0.0f);
    auto colour = [](bool below, int c) { return below ? (c == 0 ? 0.9 : c == 1 ? 0.8 : 0.3) : 0.1; };
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            const bool centre = (y + 0.5) > slope * (x + 0.5) + offset;
            double covered = 0;
            for (int sy = 0; sy < 32; ++sy)
                for (int sx = 0; sx < 32; ++sx)
                    covered += (y + (sy + 0.5) / 32) > slope * (x + (sx + 0.5) / 32) + offset;
            covered /= 1024;
            for (int c = 0; c < 3; ++c) {
                const size_t i = (size_t(y) * size_t(size) + size_t(x)) * 3 + size_t(c);
                aliased[i] = float(colour(centre, c));
                truth[i] = float(
                    encode(covered * decode(colour(true, c)) + (1 - covered) * decode(colour(false, c))));
            }
        }
}

TEST(Smaa, ConstantImagePassesUnchanged) {
    for (const char* preset : {"low", "medium", "high", "ultra"}) {
        Smaa smaa(smaaPreset(preset));
        std::vector<float> image(size_t(37 * 23 * 4), 0.42f), out(image.size());
        smaa.apply(image.data(), out.data(), 37, 23, 4);
        EXPECT_EQ(out, image) << preset;
        EXPECT_EQ(smaa.edgeFraction(), 0.0);
    }
}

TEST(Smaa, LowersTheErrorOfStraightEdgesAtEveryAngle) {
    for (const double slope : {0.05, 0.21, 0.37, 1.0, 2.6, 9.0, -0.2, -1.0}) {
        std::vector<float> aliased, truth, out(size_t(96 * 96 * 3));
        straightEdge(96, slope, slope < 0 ? 70.3 : (slope > 3 ? -300.3 : 20.3), aliased, truth);
        for (const char* preset : {"low", "medium", "high", "ultra"}) {
            Smaa smaa(smaaPreset(preset));
            smaa.apply(aliased.data(), out.data(), 96, 96, 3);
            const double ratio = mse(out, truth) / mse(aliased, truth);
            EXPECT_LT(ratio, 0.5) << "slope " << slope << " preset " << preset;
            EXPECT_GT(smaa.edgeFraction(), 0.0);
            printf("slope %5.2f %-6s error ratio %.3f\n", slope, preset, ratio);
        }
    }
}

TEST(Smaa, LowersTheErrorOfRenderedFrames) {
    const auto context = render::createOsMesaContext();
    for (const char* name : {"pipe", "hard-edges"}) {
        render::SceneOptions sceneOptions;
        sceneOptions.tiltedCamera = std::string(name) == "pipe";
        const render::Scene scene = render::buildScene(name, sceneOptions);
        render::Renderer renderer(*context, scene, 160, 120);
        const std::vector<float> aliased = frameChannels(renderer.render({}), 0, 3, true);
        const std::vector<float> truth =
            frameChannels(renderer.renderTruth(0, render::TruthOptions{}), 0, 3, true);
        std::vector<float> out(aliased.size());
        Smaa smaa;
        smaa.apply(aliased.data(), out.data(), 160, 120, 3);
        const double ratio = mse(out, truth) / mse(aliased, truth);
        printf("%s error ratio %.3f edges %.3f\n", name, ratio, smaa.edgeFraction());
        EXPECT_LT(ratio, 0.8) << name;
    }
}

TEST(Smaa, SameResultForEveryThreadCountSimdLevelInPlaceOrNotAndOtherChannelsKept) {
    std::vector<float> aliased, truth;
    straightEdge(83, 0.61, 7.7, aliased, truth);  // (83: a row tail on every SIMD level)
    std::vector<float> rgba(size_t(83 * 83 * 4));
    for (size_t p = 0; p < size_t(83 * 83); ++p) {
        for (int c = 0; c < 3; ++c) rgba[p * 4 + size_t(c)] = aliased[p * 3 + size_t(c)];
        rgba[p * 4 + 3] = float(p % 7) / 7.0f;
    }
    for (const bool colour : {false, true}) {
        SmaaOptions options;
        options.edges = colour ? SmaaEdges::Colour : SmaaEdges::Luma;
        Smaa smaa(options);
        std::vector<float> first;
        const SimdLevel original = activeSimdLevel();
        for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
            setSimdLevel(SimdLevel(level));
            for (const int threads : {1, 2, 3}) {
                setThreadCount(threads);
                std::vector<float> out(rgba.size());
                smaa.apply(rgba.data(), out.data(), 83, 83, 4);
                std::vector<float> inPlace = rgba;
                smaa.apply(inPlace.data(), inPlace.data(), 83, 83, 4);
                EXPECT_EQ(inPlace, out);
                if (first.empty()) first = out;
                EXPECT_EQ(out, first) << simdLevelName(SimdLevel(level)) << " threads " << threads;
            }
        }
        setSimdLevel(original);
        setThreadCount(0);
        for (size_t p = 0; p < size_t(83 * 83); ++p) ASSERT_EQ(first[p * 4 + 3], rgba[p * 4 + 3]);
        EXPECT_NE(first, rgba);
    }
}

// A 45-degree staircase: its pixels with a left and a top edge take the diagonal pattern's weights, and a
// pixel that found a diagonal has no orthogonal weights for its left edge; without diagonal steps the
// same pixels blend by the orthogonal patterns only.
TEST(Smaa, DiagonalPatternsTakePrecedence) {
    const int n = 24;
    std::vector<float> image(size_t(n * n * 3)), out(image.size());
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x)
            for (int c = 0; c < 3; ++c)
                image[size_t((y * n + x) * 3 + c)] = y > (n - 1 - x) + 3 ? 0.9f : 0.1f;
    // The mirror image ("\\" instead of "/", found by the other diagonal search): its pixels with a top and
    // a right edge take about the weights of their mirror pixels (the two searches read their patterns in
    // opposite directions, so the areas come swapped and are swapped back).
    {
        std::vector<float> mirrored(image.size());
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x)
                for (int c = 0; c < 3; ++c)
                    mirrored[size_t((y * n + x) * 3 + c)] = image[size_t((y * n + (n - 1 - x)) * 3 + c)];
        Smaa a(smaaPreset("ultra")), b(smaaPreset("ultra"));
        a.apply(image.data(), out.data(), n, n, 3);
        b.apply(mirrored.data(), out.data(), n, n, 3);
        for (int y = 8; y < 12; ++y) {
            const int x = n - 1 - (y - 4);
            ASSERT_EQ(b.edgeAt(n - 1 - x, y), 2);
            for (int k = 0; k < 2; ++k)
                EXPECT_NEAR(a.weightsAt(x, y)[k], b.weightsAt(n - 1 - x, y)[k], 0.03) << y << " " << k;
        }
    }
    for (const int diagonalSteps : {0, 16}) {
        SmaaOptions options = smaaPreset("ultra");
        options.diagonalSteps = diagonalSteps;
        Smaa smaa(options);
        smaa.apply(image.data(), out.data(), n, n, 3);
        for (int y = 8; y < 12; ++y) {
            const int x = n - 1 - (y - 4);  // the first bright pixel of the row
            ASSERT_EQ(smaa.edgeAt(x, y), 3) << x << "," << y;
            const float* w = smaa.weightsAt(x, y);
            if (diagonalSteps > 0) {
                EXPECT_GT(w[0], 0.2f);
                EXPECT_GT(w[1], 0.05f);
                EXPECT_EQ(w[2] + w[3], 0.0f);
            } else {
                EXPECT_GT(w[2] + w[3], 0.0f);
            }
        }
    }
}

TEST(Smaa, RefusesBadSettingsAndPredicationWithoutDepth) {
    EXPECT_THROW(smaaPreset("extreme"), Error);
    SmaaOptions o;
    o.searchSteps = 0;
    EXPECT_THROW(Smaa{o}, Error);
    o = {};
    o.threshold = 0;
    EXPECT_THROW(Smaa{o}, Error);
    o = {};
    o.predication = true;
    Smaa smaa(o);
    std::vector<float> image(size_t(8 * 8 * 3), 0.5f), out(image.size());
    EXPECT_THROW(smaa.apply(image.data(), out.data(), 8, 8, 3), Error);
    std::vector<float> depth(64, 0.5f);
    EXPECT_NO_THROW(smaa.apply(image.data(), out.data(), 8, 8, 3, depth.data()));
    EXPECT_EQ(out, image);
}

// The orthogonal areas: none where no line can be revectorised; never more than half a pixel; a pattern
// and its mirror image give the mirrored pixel the same areas.
TEST(SmaaArea, OrthogonalAreasAreBoundedAndMirrorSymmetric) {
    auto mirror = [](int p) {  // near-left <-> near-right, far-left <-> far-right
        return (p & 1) << 1 | (p & 2) >> 1 | (p & 4) << 1 | (p & 8) >> 1;
    };
    for (int p = 0; p < 16; ++p)
        for (int l = 0; l < 40; ++l)
            for (int r = 0; r < 40; ++r) {
                const auto a = smaaOrthogonalArea(p, l, r);
                ASSERT_GE(a[0], 0.0f);
                ASSERT_GE(a[1], 0.0f);
                ASSERT_LE(a[0], 0.5f);
                ASSERT_LE(a[1], 0.5f);
                if (p == 0 || p == 5 || p == 10 || p == 15) {
                    ASSERT_EQ(a[0] + a[1], 0.0f) << p;
                }
                const auto m = smaaOrthogonalArea(mirror(p), r, l);
                ASSERT_NEAR(a[0], m[0], 1e-6) << p << " " << l << " " << r;
                ASSERT_NEAR(a[1], m[1], 1e-6) << p << " " << l << " " << r;
            }
    // An L of a long run: the line climbs half a pixel over half the run; the pixel at the end takes
    // most of it (the triangle's first column), the middle nothing.
    const auto end = smaaOrthogonalArea(smaaOrthogonalPattern(true, false, false, false), 0, 9);
    EXPECT_NEAR(end[0], 0.5 * (0.5 + 0.4), 1e-6);  // the trapezoid from y = -0.5 to -0.4 over one column
    EXPECT_EQ(end[1], 0.0f);
    const auto middle = smaaOrthogonalArea(smaaOrthogonalPattern(true, false, false, false), 5, 4);
    EXPECT_EQ(middle[0] + middle[1], 0.0f);
    // A Z across 5 pixels, from half a pixel above to half below: it crosses the run in the middle
    // pixel, whose column holds a triangle of height 0.1 and width 0.5 on each side.
    const auto z = smaaOrthogonalArea(smaaOrthogonalPattern(false, true, true, false), 2, 2);
    EXPECT_NEAR(z[0], 0.025, 1e-6);
    EXPECT_NEAR(z[1], 0.025, 1e-6);
}

TEST(SmaaArea, PublishedTextureLayoutHoldsTheAreas) {
    const std::vector<uint8_t> area = smaaAreaTexture();
    ASSERT_EQ(area.size(), size_t(kSmaaAreaTextureWidth) * kSmaaAreaTextureHeight * 2);
    // Orthogonal block of pattern 1 (near-left: slot 3 at the left end, 0 at the right) at subtexture 0:
    // texel (x, y) holds the areas of distances x^2 and y^2.
    for (int y = 0; y < 16; ++y)
        for (int x = 0; x < 16; ++x) {
            const uint8_t* t = area.data() + (size_t(y) * kSmaaAreaTextureWidth + size_t(48 + x)) * 2;
            const auto a = smaaOrthogonalArea(1, x * x, y * y);
            ASSERT_EQ(t[0], uint8_t(a[0] * 255.0f));
            ASSERT_EQ(t[1], uint8_t(a[1] * 255.0f));
            ASSERT_LE(t[0], 127);
        }
    // The diagonal half, pattern 0 at (80, 0): 20 x 20 texels indexed by the distances themselves.
    const float* table = smaaDiagonalAreaTable();
    for (int y = 0; y < 20; ++y)
        for (int x = 0; x < 20; ++x) {
            const uint8_t* t = area.data() + (size_t(y) * kSmaaAreaTextureWidth + size_t(80 + x)) * 2;
            const float* a = smaaDiagonalAreas(table, 0, x, y);
            ASSERT_EQ(t[0], uint8_t(a[0] * 255.0f));
            ASSERT_EQ(t[1], uint8_t(a[1] * 255.0f));
        }
    // Below the 5 diagonal subtextures (400 rows) the right half is empty.
    for (int y = 400; y < kSmaaAreaTextureHeight; ++y)
        for (int x = 80; x < 160; ++x)
            ASSERT_EQ(area[(size_t(y) * kSmaaAreaTextureWidth + size_t(x)) * 2], 0);
}

// SMAA's GPU search: bilinear fetches of two pixels' edges a step, then the search texture's correction.
// Emulated here on an edge plane and compared with smaaHorizontalRun's direct walk, end for end.
TEST(SmaaArea, SearchTextureFindsTheRunEndsTheDirectWalkFinds) {
    const std::vector<uint8_t> search = smaaSearchTexture();
    ASSERT_EQ(search.size(), size_t(kSmaaSearchTextureWidth) * kSmaaSearchTextureHeight);
    const int width = 120, height = 12, pad = 80;
    const size_t stride = size_t(width + 2 * pad);
    uint64_t state = 11;
    for (const int steps : {2, 4, 8, 32}) {
        for (const double crossingRate : {0.05, 0.2}) {
            std::vector<uint8_t> edges(stride * size_t(height + 2 * pad), 0);
            auto at = [&](int x, int y) -> uint8_t& {
                return edges[size_t(y + pad) * stride + size_t(x + pad)];
            };
            for (int y = 0; y < height; ++y)
                for (int x = 0; x < width; ++x) {
                    const bool topEdge = unitInterval(state = splitMix64(state)) < 0.85;
                    const bool leftEdge = unitInterval(state = splitMix64(state)) < crossingRate;
                    at(x, y) = uint8_t(int(leftEdge) | int(topEdge) << 1);
                }
            // The plane transposed (a pixel's left and top edges swapped).
            const size_t tstride = size_t(height + 2 * pad);
            std::vector<uint8_t> transposed(tstride * size_t(width + 2 * pad), 0);
            for (int y = 0; y < height; ++y)
                for (int x = 0; x < width; ++x) {
                    const uint8_t e = at(x, y);
                    transposed[size_t(x + pad) * tstride + size_t(y + pad)] =
                        uint8_t((e & 1) << 1 | (e >> 1));
                }
            // The fetch at (-0.25, -0.125) from pixel (x, y) (right search: +0.25 from pixel x, so pixel
            // x + 1 takes the quarter weight): the r (left edges) and g (top edges) values.
            auto fetch = [&](int x, int y, int other, float& r, float& g) {
                auto bilinear = [](int e0, int e1, int e2, int e3) {
                    const float up = float(e0) + (float(e1) - float(e0)) * 0.75f;
                    const float down = float(e2) + (float(e3) - float(e2)) * 0.75f;
                    return up + (down - up) * 0.875f;
                };
                r = bilinear(at(other, y - 1) & 1, at(x, y - 1) & 1, at(other, y) & 1, at(x, y) & 1);
                g = bilinear(at(other, y - 1) >> 1, at(x, y - 1) >> 1, at(other, y) >> 1, at(x, y) >> 1);
            };
            auto texel = [&](float r, float g, int half) {
                const int col = int(std::lround(r * 32.0f)), row = 32 - int(std::lround(g * 32.0f));
                if (row >= kSmaaSearchTextureHeight || (half && col >= 31)) return 0;
                return search[size_t(row) * kSmaaSearchTextureWidth + size_t(col + 33 * half)] / 127;
            };
            int checked = 0;
            for (int y = 0; y < height; ++y)
                for (int x = 0; x < width; ++x) {
                    if (!(at(x, y) & 2)) continue;
                    float r = 0, g = 1;
                    int X = x, last = x;
                    for (int k = 0; k < steps && g > 0.8281f && r == 0.0f; ++k, X -= 2)
                        fetch(X, y, X - 1, r, g), last = X;
                    const int gpuFirst = last + 1 - texel(r, g, 0);
                    r = 0, g = 1, X = x + 1, last = x + 1;
                    for (int k = 0; k < steps && g > 0.8281f && r == 0.0f; ++k, X += 2)
                        fetch(X, y, X + 1, r, g), last = X;
                    const int gpuLast = last - 1 + texel(r, g, 1);
                    int first, lastPixel;
                    smaaHorizontalRun(edges.data(), stride, pad, x, y, steps, first, lastPixel);
                    int top, bottom;  // the vertical search on the transposed plane finds the same run
                    smaaVerticalRun(transposed.data(), tstride, pad, y, x, steps, top, bottom);
                    ASSERT_EQ(top, first);
                    ASSERT_EQ(bottom, lastPixel);
                    ASSERT_EQ(first, gpuFirst) << "pixel " << x << "," << y << " steps " << steps;
                    ASSERT_EQ(lastPixel, gpuLast) << "pixel " << x << "," << y << " steps " << steps;
                    ++checked;
                }
            EXPECT_GT(checked, 500);
        }
    }
}

}  // namespace
}  // namespace dejag::infer

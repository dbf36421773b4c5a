// render/normal_map.h: the standard chain averages the normals under each texel; the super chain's lobes
// split the interpolated surface under it (a flat map: one lobe of weight 1; level 0: the texel's normal),
// their weights sum to 1 and their weighted means give the surface's mean back; Toksvig's exponent.
#include "render/normal_map.h"

#include <gtest/gtest.h>

#include <cmath>

#include "base/error.h"

namespace dejag::render {
namespace {

TEST(SuperBump, AFlatMapHasOneLobeOfWeightOneAtEveryLevel) {
    const SuperBumpChain chain = buildSuperBumpChain(makeNormalMap("flat", 16, 1), 4);
    ASSERT_EQ(chain.levels, 5);
    for (int level = 0; level < chain.levels; ++level)
        for (size_t t = 0; t < chain.standard[size_t(level)].size() / 4; ++t) {
            const float* s = &chain.standard[size_t(level)][t * 4];
            EXPECT_FLOAT_EQ(s[2], 1.0f);
            EXPECT_FLOAT_EQ(s[3], 1.0f);
            const float* lobe = &chain.lobe[0][size_t(level)][t * 4];
            EXPECT_FLOAT_EQ(lobe[0], 0.0f);
            EXPECT_FLOAT_EQ(lobe[1], 0.0f);
            EXPECT_FLOAT_EQ(lobe[2], 1.0f);
            EXPECT_FLOAT_EQ(lobe[3], 1.0f);
            for (int j = 1; j < 4; ++j) EXPECT_EQ(chain.lobe[size_t(j)][size_t(level)][t * 4 + 2], 0.0f);
        }
}

TEST(SuperBump, LobesSplitTheSurfaceUnderATexel) {
    const int n = 64;
    const NormalMapImage map = makeNormalMap("dimples", n, 3);
    const SuperBumpChain chain = buildSuperBumpChain(map, 4);
    const auto normal = [&](int x, int y, int c) {
        return double(map.normals[(size_t((y + n) % n) * n + size_t((x + n) % n)) * 3 + size_t(c)]);
    };
    // Level 0: the texel's own normal, weight 1, no spread.
    for (int t = 0; t < n * n; ++t) {
        const float* lobe = &chain.lobe[0][0][size_t(t) * 4];
        ASSERT_NEAR(lobe[0], normal(t % n, t / n, 0), 1e-6);
        ASSERT_NEAR(lobe[1], normal(t % n, t / n, 1), 1e-6);
        ASSERT_EQ(lobe[2], 1.0f);
        ASSERT_NEAR(lobe[3], 1.0, 1e-6);
    }
    // Levels 1 and up: the lobes' weights sum to 1, each mean length is at most 1, and the lobes' weighted
    // means give back the mean of the surface under the texel: the bilinearly interpolated normals,
    // renormalised, twice a texel each way (computed here on its own).
    for (int level = 1; level < chain.levels; ++level) {
        const int texels = n >> level, block = 1 << level, side = 2 * block;
        for (int t = 0; t < texels * texels; t += 3) {
            double surface[3] = {0, 0, 0};
            for (int j = 0; j < side; ++j)
                for (int i = 0; i < side; ++i) {
                    const double x = (t % texels) * block + (i + 0.5) / 2 - 0.5;
                    const double y = (t / texels) * block + (j + 0.5) / 2 - 0.5;
                    const int x0 = int(std::floor(x)), y0 = int(std::floor(y));
                    const double fx = x - x0, fy = y - y0;
                    double v[3];
                    for (int c = 0; c < 3; ++c)
                        v[c] = (1 - fx) * (1 - fy) * normal(x0, y0, c) +
                               fx * (1 - fy) * normal(x0 + 1, y0, c) + (1 - fx) * fy * normal(x0, y0 + 1, c) +
                               fx * fy * normal(x0 + 1, y0 + 1, c);
                    const double length = std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
                    for (int c = 0; c < 3; ++c) surface[c] += v[c] / length / (side * side);
                }
            double weights = 0, mean[3] = {0, 0, 0};
            for (int j = 0; j < 4; ++j) {
                const float* lobe = &chain.lobe[size_t(j)][size_t(level)][size_t(t) * 4];
                if (lobe[2] == 0) continue;
                EXPECT_LE(lobe[3], 1.0 + 1e-6);
                const double z = std::sqrt(std::max(0.0, 1.0 - lobe[0] * lobe[0] - lobe[1] * lobe[1]));
                weights += lobe[2];
                const double d[3] = {lobe[0], lobe[1], z};
                for (int c = 0; c < 3; ++c) mean[c] += lobe[2] * lobe[3] * d[c];
            }
            EXPECT_NEAR(weights, 1.0, 1e-5);
            for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], surface[c], 1e-5) << level << " " << t;
        }
    }
    // The standard chain averages the texels.
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(chain.standard[1][size_t(c)],
                    (normal(0, 0, c) + normal(1, 0, c) + normal(0, 1, c) + normal(1, 1, c)) / 4, 1e-6);
}

TEST(SuperBump, ToksvigAndBadInput) {
    EXPECT_DOUBLE_EQ(toksvigExponent(200, 1.0), 200);
    EXPECT_NEAR(toksvigExponent(200, 0.99), 200 * 0.99 / (0.99 + 2), 1e-12);
    EXPECT_LT(toksvigExponent(200, 0.9), 10);
    EXPECT_THROW(makeNormalMap("dimples", 12, 1), Error);
    EXPECT_THROW(makeNormalMap("waves", 16, 1), Error);
    EXPECT_THROW(buildSuperBumpChain(makeNormalMap("flat", 16, 1), 9), Error);
    const SuperBumpChain standardOnly = buildSuperBumpChain(makeNormalMap("dimples", 16, 1), 0);
    EXPECT_EQ(standardOnly.lobes, 0);
    EXPECT_EQ(standardOnly.standard.size(), 5u);
}

}  // namespace
}  // namespace dejag::render

// FXAA 3.11 on the CPU: constant images pass unchanged, aliased edges (synthetic and rendered) get closer
// to their truth, and the result is independent of threads and of in-place filtering.
#include "infer/fxaa.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/random.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "render/renderer.h"
#include "tests/alloc_counter.h"
#include "tests/infer/fxaa_reference.h"

namespace dejag::infer {
namespace {

double mse(const std::vector<float>& a, const std::vector<float>& b, int channels = 3, int used = 3) {
    double squared = 0;
    size_t count = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        if (int(i % size_t(channels)) >= used) continue;
        squared += double(a[i] - b[i]) * double(a[i] - b[i]);
        ++count;
    }
    return squared / double(count);
}

// A dark/bright half-plane below the line y = slope * x + offset: point-sampled at pixel centres
// (aliased) and area-sampled with 32 x 32 sub-samples (truth).
void diagonalEdge(int size, double slope, double offset, std::vector<float>& aliased,
                  std::vector<float>& truth) {
    aliased.assign(size_t(size * size * 3), 0.0f);
    truth.assign(size_t(size * size * 3), 0.0f);
    auto colour = [](bool below, int c) { return below ? (c == 0 ? 0.9f : c == 1 ? 0.8f : 0.3f) : 0.1f; };
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
                aliased[i] = colour(centre, c);
                truth[i] = float(covered * colour(true, c) + (1 - covered) * colour(false, c));
            }
        }
}

TEST(Fxaa, ConstantImagePassesUnchanged) {
    for (const int preset : {12, 23, 39}) {
        FxaaOptions options;
        options.preset = preset;
        Fxaa fxaa(options);
        std::vector<float> image(size_t(37 * 23 * 4), 0.42f), out(image.size());
        fxaa.apply(image.data(), out.data(), 37, 23, 4);
        EXPECT_EQ(out, image);
        EXPECT_EQ(fxaa.processedFraction(), 0.0);
    }
}

TEST(Fxaa, LowersTheErrorOfADiagonalEdge) {
    for (const double slope : {0.37, 1.0, 2.6, -0.2}) {
        SCOPED_TRACE(slope);
        std::vector<float> aliased, truth, out(size_t(96 * 96 * 3));
        diagonalEdge(96, slope, slope < 0 ? 70.3 : 10.3, aliased, truth);
        for (const int preset : {12, 23, 39}) {
            FxaaOptions options;
            options.preset = preset;
            Fxaa fxaa(options);
            fxaa.apply(aliased.data(), out.data(), 96, 96, 3);
            EXPECT_LT(mse(out, truth), 0.6 * mse(aliased, truth)) << "preset " << preset;
            EXPECT_GT(fxaa.processedFraction(), 0.0);
        }
    }
}

TEST(Fxaa, LowersTheErrorOfARenderedEdge) {
    const auto context = render::createOsMesaContext();
    render::SceneOptions sceneOptions;
    sceneOptions.tiltedCamera = true;
    const render::Scene scene = render::buildScene("pipe", sceneOptions);
    render::Renderer renderer(*context, scene, 160, 120);
    const std::vector<float> aliased = frameChannels(renderer.render({}), 0, 3, true);
    const std::vector<float> truth =
        frameChannels(renderer.renderTruth(0, render::TruthOptions{}), 0, 3, true);
    std::vector<float> out(aliased.size());
    Fxaa fxaa;
    fxaa.apply(aliased.data(), out.data(), 160, 120, 3);
    EXPECT_LT(mse(out, truth), 0.8 * mse(aliased, truth));
}

TEST(Fxaa, SameResultForEveryThreadCountInPlaceOrNotAndOtherChannelsKept) {
    std::vector<float> aliased, truth;
    diagonalEdge(80, 0.61, 7.7, aliased, truth);
    // Add an alpha channel with its own values.
    std::vector<float> rgba(size_t(80 * 80 * 4));
    for (size_t p = 0; p < size_t(80 * 80); ++p) {
        for (int c = 0; c < 3; ++c) rgba[p * 4 + size_t(c)] = aliased[p * 3 + size_t(c)];
        rgba[p * 4 + 3] = float(p % 7) / 7.0f;
    }
    Fxaa fxaa;
    std::vector<std::vector<float>> results;
    for (const int threads : {1, 2, 3}) {
        setThreadCount(threads);
        std::vector<float> out(rgba.size());
        fxaa.apply(rgba.data(), out.data(), 80, 80, 4);
        results.push_back(out);
        std::vector<float> inPlace = rgba;
        fxaa.applyInPlace(inPlace.data(), 80, 80, 4);
        EXPECT_EQ(inPlace, out);
    }
    setThreadCount(0);
    EXPECT_EQ(results[0], results[1]);
    EXPECT_EQ(results[0], results[2]);
    for (size_t p = 0; p < size_t(80 * 80); ++p) ASSERT_EQ(results[0][p * 4 + 3], rgba[p * 4 + 3]);
    EXPECT_NE(results[0], rgba);
}

// The SIMD kernels against the scalar reference (the first implementation, kept in tests/) on a rendered
// frame, noisy blocks and diagonal edges, every preset, RGB and RGBA, luma computed or green, on every
// SIMD path: bit for bit (the kernels do the reference's arithmetic in its order, without contracted
// multiply-adds, so no threshold decision can flip).
TEST(Fxaa, EverySimdPathMatchesTheScalarReference) {
    struct Case {
        std::vector<float> image;
        int width, height, channels;
    };
    std::vector<Case> cases;
    {
        const auto context = render::createOsMesaContext();
        const render::Scene scene = render::buildScene("hard-edges");
        render::Renderer renderer(*context, scene, 203, 141);
        cases.push_back({frameChannels(renderer.render({}), 0, 3, true), 203, 141, 3});
    }
    {
        std::vector<float> aliased, truth;
        diagonalEdge(67, 0.37, 10.3, aliased, truth);
        cases.push_back({aliased, 67, 67, 3});
        uint64_t state = 7;
        std::vector<float> blocks(size_t(45 * 38 * 4));
        for (size_t i = 0; i < blocks.size(); ++i) {
            const size_t p = i / 4;
            const float block = float((p % 45) / 6 + (p / 45) / 4) * 0.13f;
            blocks[i] = std::fmod(block, 1.0f) * 0.8f + 0.2f * float(unitInterval(state = splitMix64(state)));
        }
        cases.push_back({blocks, 45, 38, 4});
    }
    const SimdLevel original = activeSimdLevel();
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        for (const Case& c : cases)
            for (const int preset : {12, 23, 39})
                for (const bool green : {false, true}) {
                    FxaaOptions options;
                    options.preset = preset, options.greenAsLuma = green;
                    Fxaa fxaa(options);
                    reference::ReferenceFxaa oracle(options);
                    std::vector<float> out(c.image.size()), expected(c.image.size());
                    fxaa.apply(c.image.data(), out.data(), c.width, c.height, c.channels);
                    oracle.apply(c.image.data(), expected.data(), c.width, c.height, c.channels);
                    SCOPED_TRACE(std::string(simdLevelName(SimdLevel(level))) + " preset " +
                                 std::to_string(preset) + (green ? " green" : "") + " " +
                                 std::to_string(c.width) + "x" + std::to_string(c.height));
                    EXPECT_GT(fxaa.processedFraction(), 0.01);
                    EXPECT_EQ(fxaa.processedFraction(), oracle.processedFraction());
                    EXPECT_EQ(out, expected);
                }
    }
    setSimdLevel(original);
}

TEST(Fxaa, NoAllocationPerFrameAfterWarmUp) {
    std::vector<float> aliased, truth;
    diagonalEdge(96, 0.37, 10.3, aliased, truth);
    Fxaa fxaa;
    std::vector<float> frame = aliased;
    fxaa.applyInPlace(frame.data(), 96, 96, 3);  // warm-up: scratch buffers grow once
    const int64_t before = testing::allocationCount();
    for (int i = 0; i < 3; ++i) {
        frame = aliased;  // same size: no allocation
        fxaa.applyInPlace(frame.data(), 96, 96, 3);
    }
    EXPECT_EQ(testing::allocationCount() - before, 0);
}

TEST(Fxaa, RefusesBadSettings) {
    FxaaOptions options;
    options.preset = 15;
    EXPECT_THROW(Fxaa{options}, Error);
    options.preset = 39, options.subpix = 1.5f;
    EXPECT_THROW(Fxaa{options}, Error);
    Fxaa fxaa;
    std::vector<float> grey(16), out(16);
    EXPECT_THROW(fxaa.apply(grey.data(), out.data(), 4, 4, 1), Error);
}

}  // namespace
}  // namespace dejag::infer

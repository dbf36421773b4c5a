// FXAA 3.11 as a GLSL compute shader (infer/glsl_fxaa.h) against the CPU filter (infer/fxaa.h), through
// OSMesa's llvmpipe: within 1/255 per channel on 8-bit values, on rendered frames, every preset.
#include "infer/glsl_fxaa.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "data/frame_image.h"
#include "render/renderer.h"

namespace dejag::infer {
namespace {

struct Difference {
    double largest = 0;
    int largest8bit = 0;
    size_t pixelsApart = 0;  // pixels whose colour differs by more than 1e-5
};

Difference compare(const std::vector<float>& a, const std::vector<float>& b, int channels) {
    Difference d;
    for (size_t p = 0; p < a.size() / size_t(channels); ++p) {
        bool apart = false;
        for (int c = 0; c < channels; ++c) {
            const size_t i = p * size_t(channels) + size_t(c);
            const double diff = std::abs(double(a[i]) - double(b[i]));
            d.largest = std::max(d.largest, diff);
            d.largest8bit = std::max(d.largest8bit,
                                     int(std::abs(std::lround(a[i] * 255.0f) - std::lround(b[i] * 255.0f))));
            apart |= diff > 1e-5;
        }
        d.pixelsApart += apart;
    }
    return d;
}

TEST(GlslFxaa, MatchesTheCpuFilterOnRenderedFramesForEveryPreset) {
    const auto context = render::createOsMesaContext();
    for (const char* sceneName : {"pipe", "text-wall", "blinds"}) {
        render::SceneOptions sceneOptions;
        sceneOptions.tiltedCamera = std::string(sceneName) == "pipe";
        const render::Scene scene = render::buildScene(sceneName, sceneOptions);
        render::Renderer renderer(*context, scene, 160, 120);
        const std::vector<float> frame = frameChannels(renderer.render({}), 0, 3, true);
        for (int preset : {12, 23, 39})
            for (bool green : {false, true}) {
                FxaaOptions options;
                options.preset = preset, options.greenAsLuma = green;
                std::vector<float> cpu(frame.size()), gl(frame.size());
                Fxaa(options).apply(frame.data(), cpu.data(), 160, 120, 3);
                GlslFxaa(*context, options, 3).apply(frame.data(), gl.data(), 160, 120);
                const Difference d = compare(cpu, gl, 3);
                std::printf("%s preset %d%s: largest |GLSL - CPU| %.3g, 8-bit %d, %zu pixels apart\n",
                            sceneName, preset, green ? " green" : "", d.largest, d.largest8bit,
                            d.pixelsApart);
                EXPECT_LE(d.largest8bit, 1) << sceneName << " preset " << preset;
                EXPECT_NE(cpu, frame);  // FXAA did change the frame, so the comparison means something
            }
    }
}

// Channels after R, G, B pass through; a bad preset is one error.
TEST(GlslFxaa, KeepsOtherChannelsAndRefusesBadPresets) {
    const auto context = render::createOsMesaContext();
    const int W = 40, H = 24;
    std::vector<float> rgba(size_t(W * H * 4));
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            float* p = &rgba[(size_t(y) * W + x) * 4];
            p[0] = p[1] = p[2] = x * 3 > y * 5 ? 0.9f : 0.1f;
            p[3] = float(x) / float(W);
        }
    std::vector<float> cpu(rgba.size()), gl(rgba.size());
    Fxaa().apply(rgba.data(), cpu.data(), W, H, 4);
    GlslFxaa(*context, FxaaOptions{}, 4).apply(rgba.data(), gl.data(), W, H);
    EXPECT_LE(compare(cpu, gl, 4).largest8bit, 1);
    for (size_t p = 0; p < size_t(W * H); ++p) EXPECT_EQ(gl[p * 4 + 3], rgba[p * 4 + 3]);
    FxaaOptions bad;
    bad.preset = 17;
    EXPECT_THROW(fxaaGlslSource(bad, 3), Error);
}

}  // namespace
}  // namespace dejag::infer

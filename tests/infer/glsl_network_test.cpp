// Networks as GLSL compute shaders (nn/glsl.h), exported to a folder, read back and run by OSMesa's
// llvmpipe (infer/glsl_network.h): the same output as the CPU's Model::forward within 1e-4, and within
// 1/255 per channel once both are 8-bit, on rendered frames and on a graph of every op.
#include "infer/glsl_network.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "base/error.h"
#include "base/random.h"
#include "data/frame_image.h"
#include "nn/init.h"
#include "render/renderer.h"
#include "tests/nn/exportable_ops.h"
#include "tests/test_util.h"

namespace dejag::infer {
namespace {

struct Difference {
    double largest = 0;   // |GLSL - CPU| over the output
    int largest8bit = 0;  // the same on 8-bit values of the outputs clamped to [0, 1]
};

Difference compare(nn::Model& model, const nn::Tensor& input, render::GlContext& context,
                   const std::string& folder) {
    nn::writeGlslNetwork(folder, nn::exportGlsl(model));
    GlslNetworkRunner runner(context, nn::readGlslNetwork(folder));
    const nn::Shape& s = input.shape();
    const std::vector<float> gl = runner.run(input.data(), int(s[3]), int(s[2]));
    const nn::Tensor& cpu = model.forward(input);
    EXPECT_EQ(int64_t(gl.size()), cpu.numel());
    Difference d;
    for (int64_t i = 0; i < std::min<int64_t>(cpu.numel(), int64_t(gl.size())); ++i) {
        const float a = gl[size_t(i)], b = cpu.data()[i];
        d.largest = std::max(d.largest, double(std::abs(a - b)));
        const long a8 = std::lround(std::clamp(a, 0.0f, 1.0f) * 255.0f),
                   b8 = std::lround(std::clamp(b, 0.0f, 1.0f) * 255.0f);
        d.largest8bit = std::max(d.largest8bit, int(std::abs(a8 - b8)));
    }
    std::printf("%s: largest |GLSL - CPU| %.3g, on 8-bit values %d\n", model.name().c_str(), d.largest,
                d.largest8bit);
    return d;
}

// A rendered frame as the network's planar input: sRGB R, G, B (then, for a 6-channel guided network, a
// second copy lightly blurred, standing in for the guide method's result).
nn::Tensor renderedInput(render::GlContext& context, int channels, int width, int height) {
    render::SceneOptions options;
    options.tiltedCamera = true;
    const render::Scene scene = render::buildScene("pipe", options);
    render::Renderer renderer(context, scene, width, height);
    const std::vector<float> rgb = frameChannels(renderer.render({}), 0, 3, true);
    nn::Tensor t({1, channels, height, width});
    for (int c = 0; c < channels; ++c)
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                const int k = c % 3, x1 = std::min(x + 1, width - 1);
                const float v = rgb[(size_t(y) * width + x) * 3 + k];
                t.data()[(size_t(c) * height + y) * width + x] =
                    c < 3 ? v : 0.5f * (v + rgb[(size_t(y) * width + x1) * 3 + k]);
            }
    return t;
}

TEST(Glsl, EveryOpMatchesTheCpu) {
    testing::TempDir dir;
    const auto context = render::createOsMesaContext();
    nn::Model model = nn::Model::fromArchitecture(nn::everyExportableOp());
    model.initialize(7);
    nn::Rng rng(3);
    for (const nn::ParameterInfo& p : model.parameters())
        if (p.isBias)
            for (int64_t i = 0; i < p.shape[0]; ++i)
                model.parameterData()[p.offset + i] = rng.uniform(-0.3f, 0.3f);
    nn::Tensor input({1, 4, 24, 40});
    for (int64_t i = 0; i < input.numel(); ++i) input.data()[i] = rng.uniform(0.0f, 1.0f);
    const Difference d = compare(model, input, *context, dir.file("every"));
    EXPECT_LE(d.largest, 1e-4);
}

TEST(Glsl, ShippedNetworksMatchTheCpuOnARenderedFrame) {
    testing::TempDir dir;
    const auto context = render::createOsMesaContext();
    for (const char* name : {"dejag-fast", "dejag-guided", "seed2020-gray"}) {
        nn::Model model = nn::loadModel(testing::sourcePath(std::string("models/") + name + ".safetensors"));
        nn::Tensor input =
            renderedInput(*context, model.inputChannels() == 1 ? 3 : model.inputChannels(), 96, 64);
        if (model.inputChannels() == 1) {  // the grey network: the luma of docs/seed-cnn.md
            nn::Tensor grey({1, 1, 64, 96});
            for (int64_t p = 0; p < 64 * 96; ++p)
                grey.data()[p] = 0.21f * input.data()[p] + 0.72f * input.data()[64 * 96 + p] +
                                 0.07f * input.data()[2 * 64 * 96 + p];
            input = std::move(grey);
        }
        const Difference d = compare(model, input, *context, dir.file(name));
        EXPECT_LE(d.largest, 1e-4) << name;
        EXPECT_LE(d.largest8bit, 1) << name;
    }
}

// Wide layers, where llvmpipe once computed a pixel's large array of sums wrongly (the shaders sum 16
// output channels at a time): convolutions of up to 256 x 200 channels and a transposed one.
TEST(Glsl, WideLayersMatchTheCpu) {
    testing::TempDir dir;
    const auto context = render::createOsMesaContext();
    for (auto [cin, cout] : std::vector<std::pair<int, int>>{{64, 128}, {40, 200}, {128, 57}, {256, 29}}) {
        for (const char* op : {"conv2d", "conv_transpose2d"}) {
            nlohmann::json node = {
                {"name", "wide"}, {"op", op}, {"inputs", {"input"}}, {"out_channels", cout}, {"kernel", 3}};
            if (std::string(op) == "conv2d")
                node["padding"] = "same";
            else
                node["stride"] = 2, node["padding"] = 1, node["output_padding"] = 1;
            nn::Model model = nn::Model::fromArchitecture(
                {{"name", std::string(op) + "_" + std::to_string(cin) + "x" + std::to_string(cout)},
                 {"input_channels", cin},
                 {"nodes", {node}}});
            model.initialize(1);
            nn::Tensor input({1, cin, 4, 6});
            nn::Rng rng(2);
            for (int64_t i = 0; i < input.numel(); ++i) input.data()[i] = rng.uniform(0.0f, 1.0f);
            EXPECT_LE(compare(model, input, *context, dir.file(model.name())).largest, 1e-4) << model.name();
        }
    }
}

// The recurrent network's frame (its warps, Catmull-Rom and bilinear, and its accumulate) against
// Model::forward on an input laid out as the filter assembles it: a rendered frame, a history of kept
// colours and confidences, motion of a few pixels (some whole, some not), the jitter, depths.
TEST(Glsl, TheTemporalNetworksFrameMatchesTheCpu) {
    testing::TempDir dir;
    const auto context = render::createOsMesaContext();
    nn::Model temporal = nn::loadModel(testing::sourcePath("models/dejag-temporal.safetensors"));
    ASSERT_EQ(temporal.inputChannels(), 16);
    constexpr int w = 96, h = 64;
    nn::Tensor input = renderedInput(*context, 16, w, h);
    nn::Rng rng(11);
    float* in = input.data();
    const size_t plane = size_t(w) * h;
    for (size_t p = 0; p < plane; ++p) {
        for (int c = 3; c < 9; ++c)
            in[c * plane + p] = std::clamp(in[(c % 3) * plane + p] + rng.uniform(-0.1f, 0.1f), 0.0f, 1.0f);
        in[9 * plane + p] = rng.uniform(0.0f, 0.97f);                       // confidence
        in[10 * plane + p] = p % 7 == 0 ? 2.0f : rng.uniform(-3.0f, 3.0f);  // motion x
        in[11 * plane + p] = rng.uniform(-1.5f, 1.5f);                      // motion y
        in[12 * plane + p] = 0.25f, in[13 * plane + p] = -0.375f;           // jitter
        in[14 * plane + p] = rng.uniform(0.1f, 0.2f), in[15 * plane + p] = rng.uniform(0.1f, 0.2f);
    }
    const Difference d = compare(temporal, input, *context, dir.file("temporal"));
    EXPECT_LE(d.largest, 1e-4);
    EXPECT_LE(d.largest8bit, 1);
}

TEST(Glsl, BadSizesAndFoldersAreRefused) {
    testing::TempDir dir;
    nn::Model fast = nn::loadModel(testing::sourcePath("models/dejag-fast.safetensors"));
    const nn::GlslNetwork network = nn::exportGlsl(fast);
    EXPECT_EQ(network.sizeDivisor, 8);
    const auto context = render::createOsMesaContext();
    GlslNetworkRunner runner(*context, network);
    std::vector<float> input(3 * 20 * 30, 0.5f);
    EXPECT_THROW(runner.run(input.data(), 30, 20), Error);
    EXPECT_THROW(nn::readGlslNetwork(dir.file("missing")), Error);
}

}  // namespace
}  // namespace dejag::infer

// How a model meets a frame (nn/frame_network.h): the row packers on every SIMD level, the receptive
// field of the shipped architectures, the whole-frame run against the model's reference forward on the
// replicated frame, and the models it refuses.
#include "nn/frame_network.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>
#include <string>

#include "base/error.h"
#include "nn/frame_network_kernels.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

// The frame rows into planes and back on every SIMD level: RGB frames by vectors (and a tail), RGBA
// pixel by pixel; out-of-range values clamped, NaN kept, the other channels untouched.
class FrameRows : public testing::SimdLevelTest {};

TEST_P(FrameRows, SplitAndJoinMatchThePixelLoops) {
    for (int channels : {3, 4})
        for (int64_t count : {0, 1, 15, 16, 17, 40, 77}) {
            std::vector<float> frame(size_t(count * channels));
            for (size_t i = 0; i < frame.size(); ++i) frame[i] = float(i % 29) / 13.0f - 0.5f;
            if (count > 5) frame[size_t(5 * channels + 1)] = NAN;
            std::vector<float> r(size_t(count) + 1, -7.0f), g = r, b = r;
            DEJAG_SIMD_CALL(splitRgbRow, frame.data(), channels, count, r.data(), g.data(), b.data());
            for (int64_t x = 0; x < count; ++x) {
                const float* p = &frame[size_t(x * channels)];
                ASSERT_EQ(std::bit_cast<uint32_t>(r[size_t(x)]), std::bit_cast<uint32_t>(p[0])) << x;
                ASSERT_EQ(std::bit_cast<uint32_t>(g[size_t(x)]), std::bit_cast<uint32_t>(p[1])) << x;
                ASSERT_EQ(std::bit_cast<uint32_t>(b[size_t(x)]), std::bit_cast<uint32_t>(p[2])) << x;
            }
            EXPECT_EQ(r[size_t(count)], -7.0f) << "written past the row";
            std::vector<float> joined(frame.size() + size_t(channels), 9.0f);
            DEJAG_SIMD_CALL(joinRgbRowClamped, r.data(), g.data(), b.data(), count, channels, joined.data());
            for (int64_t x = 0; x < count; ++x)
                for (int c = 0; c < channels; ++c) {
                    const float v = frame[size_t(x * channels + c)], got = joined[size_t(x * channels + c)];
                    if (c >= 3)
                        EXPECT_EQ(got, 9.0f) << "channel " << c << " of pixel " << x << " written";
                    else if (std::isnan(v))
                        EXPECT_TRUE(std::isnan(got)) << x;
                    else
                        EXPECT_EQ(got, std::clamp(v, 0.0f, 1.0f)) << "channel " << c << " of pixel " << x;
                }
            EXPECT_EQ(joined[frame.size()], 9.0f) << "written past the row";
            // A passed row clamped straight from the frame: what the join of its split gives.
            std::vector<float> clamped(frame.size() + size_t(channels), 9.0f);
            DEJAG_SIMD_CALL(clampRgbRow, frame.data(), channels, count, clamped.data());
            for (size_t i = 0; i < frame.size(); ++i) {
                if (std::isnan(joined[i]))
                    EXPECT_TRUE(std::isnan(clamped[i])) << "element " << i;
                else
                    EXPECT_EQ(clamped[i], joined[i]) << "element " << i;
            }
            EXPECT_EQ(clamped[frame.size()], 9.0f) << "written past the row";
        }
}

INSTANTIATE_TEST_SUITE_P(SimdLevels, FrameRows, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);

TEST(FrameNetwork, ReceptiveFieldOfTheShippedArchitectures) {
    const ReceptiveField seed = receptiveField(Model::builtin("seed2020"));
    EXPECT_EQ(seed.stride, 4);
    EXPECT_GE(seed.radius, 2 + 1 + 1 + 2 + 4 + 4);  // 5x5, 3x3, pools, 3x3 at 1/4, transposed convs
    const ReceptiveField fast = receptiveField(Model::builtin("fast"));
    EXPECT_EQ(fast.stride, 8);
    EXPECT_GE(fast.radius, 2 + 4 + 4 + 8 + 8);  // the encoder alone
    const ReceptiveField kpn = receptiveField(Model::builtin("kpn"));
    EXPECT_EQ(kpn.stride, 8);
    EXPECT_GE(kpn.radius, fast.radius - 2 + 1);  // a 1x1 head instead of a 3x3, then the 3x3 kernel filter
}

// The frame padded by repeating its last row and column up to a multiple of the stride, the network's
// reference forward (nn::Model::forward) run on it, the result cropped and clamped to [0, 1] (a grey
// model's luma change added to R, G and B); alpha copied through. A guided model's guide (the frame's
// layout) is channels 3..5 of its input, replicated alike.
class FrameNetworkOn : public ::testing::TestWithParam<const char*> {};

// A built-in architecture by name; "kpn+guide": kpn reading a guide beside the frame.
Model builtinForFrames(const std::string& name) {
    if (name != "kpn+guide") return Model::builtin(name);
    ModelOptions options;
    options.width = 8, options.guide = true;
    nlohmann::json architecture = Model::builtinArchitecture("kpn", options);
    architecture["guide_method"] = "smaa";
    return Model::fromArchitecture(architecture);
}

TEST_P(FrameNetworkOn, AWholeFrameIsTheModelOnTheReplicatedFrame) {
    const int W = 75, H = 53, C = 4;  // not a multiple of any stride
    std::vector<float> frame(size_t(W) * H * C), guide(frame.size());
    std::mt19937 rng(11);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (size_t i = 0; i < frame.size(); ++i) frame[i] = i % C == 3 ? 0.5f : u(rng);
    for (size_t i = 0; i < frame.size(); ++i) guide[i] = i % C == 3 ? -9.0f : u(rng);
    Model model = builtinForFrames(GetParam());
    model.initialize(5);
    FrameNetwork network = FrameNetwork::borrowing(model);
    const bool guided = model.inputChannels() == 6;
    EXPECT_EQ(network.guideMethod(), guided ? "smaa" : "");
    if (guided) {
        std::vector<float> out(frame.size());
        EXPECT_THROW(network.run(frame.data(), out.data(), W, H, C), Error) << "a guided run without a guide";
    }
    std::vector<float> got(frame.size(), -1.0f);
    network.run(frame.data(), got.data(), W, H, C, guide.data());
    const int a = network.alignment(), PW = (W + a - 1) / a * a, PH = (H + a - 1) / a * a;
    const bool grey = model.inputChannels() == 1;
    auto luma = [](const float* p) { return 0.21f * p[0] + 0.72f * p[1] + 0.07f * p[2]; };
    Tensor input({1, model.inputChannels(), PH, PW});
    for (int y = 0; y < PH; ++y)
        for (int x = 0; x < PW; ++x) {
            const size_t at = (size_t(std::min(y, H - 1)) * W + size_t(std::min(x, W - 1))) * C;
            const float* p = &frame[at];
            for (int c = 0; c < std::min(3, model.inputChannels()); ++c)
                input.at(0, c, y, x) = grey ? luma(p) : p[c];
            for (int c = 3; c < model.inputChannels(); ++c) input.at(0, c, y, x) = guide[at + size_t(c - 3)];
        }
    const Tensor& result = model.forward(input);
    float worst = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const float* p = &frame[(size_t(y) * W + size_t(x)) * C];
            for (int c = 0; c < 3; ++c) {
                const float want = std::clamp(
                    grey ? p[c] + result.at(0, 0, y, x) - luma(p) : result.at(0, c, y, x), 0.0f, 1.0f);
                worst = std::max(worst, std::abs(got[(size_t(y) * W + size_t(x)) * C + size_t(c)] - want));
            }
            ASSERT_EQ(got[(size_t(y) * W + size_t(x)) * C + 3], 0.5f) << "alpha passes through";
        }
    EXPECT_LE(worst, 1e-5f);
}

INSTANTIATE_TEST_SUITE_P(Architectures, FrameNetworkOn,
                         ::testing::Values("seed2020", "fast", "kpn", "kpn+guide"), [](const auto& test) {
                             std::string name = test.param;
                             std::replace(name.begin(), name.end(), '+', '_');
                             return name;
                         });

// A guided kpn blends the frame's 3x3 neighbourhood with the guide's pixel: with the guide's logit far
// above the kernel's, it returns the guide; far below, a filter of the frame alone.
TEST(FrameNetwork, AGuidedKpnBlendsTheFrameWithTheGuide) {
    Model model = builtinForFrames("kpn+guide");
    model.initialize(3);
    const int W = 40, H = 24, C = 3;
    std::vector<float> frame(size_t(W) * H * C), guide(frame.size());
    for (size_t i = 0; i < frame.size(); ++i) frame[i] = 0.25f, guide[i] = float(i % 7) / 8.0f;
    // The head: the last convolution before the pixel shuffle, its bias per logit (tap j of the 10 at
    // shuffle phase p is channel j * 4 + p).
    const auto& nodes = model.architecture()["nodes"];
    std::string head;
    for (const auto& n : nodes)
        if (n["op"] == "pixel_shuffle") head = n["inputs"][0];
    ASSERT_FALSE(head.empty());
    for (const float guideLogit : {60.0f, -60.0f}) {
        // Zero weights: the logits are the biases alone.
        Model copy = Model::fromArchitecture(model.architecture());
        copy.initialize(3);
        for (int64_t i = 0; i < copy.parameterCount(); ++i) copy.parameterData()[i] = 0.0f;
        float* bias = copy.parameterData() + copy.parameter(head + ".bias").offset;
        for (int p = 0; p < 4; ++p) bias[9 * 4 + p] = guideLogit;
        FrameNetwork network = FrameNetwork::borrowing(copy);
        std::vector<float> out(frame.size());
        network.run(frame.data(), out.data(), W, H, C, guide.data());
        for (size_t i = 0; i < out.size(); ++i)
            ASSERT_NEAR(out[i], guideLogit > 0 ? guide[i] : 0.25f, 1e-5f) << i;
    }
}

TEST(FrameNetwork, RefusesWhatIsNoFilterOfFrames) {
    EXPECT_THROW(FrameNetwork(Model::fromArchitecture(Model::builtinArchitecture("fast", {8, 3, 4}))), Error);
    Model huge = Model::builtin("fast");
    huge.initialize(1);
    for (int64_t i = 0; i < huge.parameterCount(); ++i) huge.parameterData()[i] = 1e30f;
    FrameNetwork accepted = FrameNetwork::borrowing(huge);  // training scores a diverged model as the worst
    EXPECT_THROW(checkWeightsForFrames(huge), Error);
}

}  // namespace
}  // namespace dejag::nn

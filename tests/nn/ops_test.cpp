// The op harness, after ggml's test-backend-ops: one case per op and parameters, each a small graph whose
// last node is the op under test, and every case through the same checks, its parameters printed when
// one fails:
//   - the registry: the output shape it declares is what the forward writes, in float and in double;
//   - backward against central differences in double (the op alone, on random inputs and weights);
//   - the fast paths against the reference forward: training's blocked convolutions and the inference
//     plan (nn/inference.h), and bf16 activations against float where the CPU has AVX-512 BF16;
//   - the receptive field (nn/frame_network.h): a pixel changed in the input changes no output pixel
//     beyond the radius the registry gives.
// and, a level down, every function of nn/layers.h with its descriptor (tests/nn/layer_cases.h): in float
// against its PyTorch golden (tests/golden/make_nn_golden.py; forward within 1e-5 and backward within
// 1e-4 of torch's float64, relative to the tensor's largest value), and in double against central
// differences on the seeded random shapes. The losses' and optimizers' goldens are in golden_test.cpp.
#include "nn/ops.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include "base/error.h"
#include "base/simd.h"
#include "nn/frame_network.h"
#include "nn/gradient_check.h"
#include "nn/inference.h"
#include "nn/layers.h"
#include "nn/safetensors.h"
#include "tests/nn/layer_cases.h"
#include "tests/nn/relative_error.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

using nlohmann::json;
using Vec = std::vector<double>;

struct OpCase {
    std::string label;
    int inputChannels = 3;
    json nodes;  // the graph; its last node is the op under test
    int height = 12, width = 16;
    bool piecewise = false;  // max or ReLU kinks: one-sided differences may disagree
};

json node(const std::string& name, const std::string& op, std::vector<std::string> inputs, json fields = {}) {
    json n = {{"name", name}, {"op", op}, {"inputs", inputs}};
    for (auto& [k, v] : fields.items()) n[k] = v;
    return n;
}

std::vector<OpCase> cases() {
    std::vector<OpCase> c;
    auto single = [&](std::string label, json n, bool piecewise = false, int cin = 3) {
        c.push_back({std::move(label), cin, json::array({std::move(n)}), 12, 16, piecewise});
    };
    single("conv2d 3x3 same",
           node("op", "conv2d", {"input"}, {{"out_channels", 5}, {"kernel", 3}, {"padding", "same"}}));
    single(
        "conv2d 3x3 stride 2 relu",
        node(
            "op", "conv2d", {"input"},
            {{"out_channels", 4}, {"kernel", 3}, {"stride", 2}, {"padding", "same"}, {"activation", "relu"}}),
        true);
    single("conv2d 5x5 dilation 2 sigmoid", node("op", "conv2d", {"input"},
                                                 {{"out_channels", 3},
                                                  {"kernel", 5},
                                                  {"dilation", 2},
                                                  {"padding", "same"},
                                                  {"activation", "sigmoid"}}));
    single("conv2d 1x1 no bias",
           node("op", "conv2d", {"input"}, {{"out_channels", 7}, {"kernel", 1}, {"bias", false}}));
    single("conv2d 3x3 padding 1 leaky",
           node("op", "conv2d", {"input"},
                {{"out_channels", 6},
                 {"kernel", 3},
                 {"padding", 1},
                 {"activation", "leaky_relu"},
                 {"slope", 0.1}}),
           true);
    single("conv2d 16 in",
           node("op", "conv2d", {"input"}, {{"out_channels", 8}, {"kernel", 3}, {"padding", "same"}}), false,
           16);
    single("conv_transpose2d 3x3 s2 p1 op1",
           node("op", "conv_transpose2d", {"input"},
                {{"out_channels", 4}, {"kernel", 3}, {"stride", 2}, {"padding", 1}, {"output_padding", 1}}));
    single("conv_transpose2d 2x2 s2 relu",
           node("op", "conv_transpose2d", {"input"},
                {{"out_channels", 3}, {"kernel", 2}, {"activation", "relu"}}),
           true);
    single("maxpool2d 2", node("op", "maxpool2d", {"input"}, {{"kernel", 2}}), true);
    single("maxpool2d 3 stride 2", node("op", "maxpool2d", {"input"}, {{"kernel", 3}, {"stride", 2}}), true);
    for (const char* a : {"relu", "leaky_relu", "sigmoid", "clamp"})
        single(std::string("activation ") + a, node("op", "activation", {"input"}, {{"activation", a}}),
               std::string(a) != "sigmoid");
    single("upsample nearest 2", node("op", "upsample", {"input"}, {{"mode", "nearest"}}));
    single("upsample bilinear 2", node("op", "upsample", {"input"}, {{"mode", "bilinear"}}));
    single("upsample bilinear 3", node("op", "upsample", {"input"}, {{"mode", "bilinear"}, {"factor", 3}}));
    single("pixel_shuffle 2", node("op", "pixel_shuffle", {"input"}, {{"factor", 2}}), false, 8);
    single("pixel_shuffle 3", node("op", "pixel_shuffle", {"input"}, {{"factor", 3}}), false, 9);
    const json conv =
        node("branch", "conv2d", {"input"}, {{"out_channels", 3}, {"kernel", 3}, {"padding", "same"}});
    c.push_back({"add input + conv", 3, json::array({conv, node("op", "add", {"input", "branch"})})});
    c.push_back(
        {"concat 3 inputs", 3, json::array({conv, node("op", "concat", {"input", "branch", "input"})})});
    for (int k : {3, 5}) {
        const json logits = node("logits", "conv2d", {"input"},
                                 {{"out_channels", k * k}, {"kernel", 3}, {"padding", "same"}});
        c.push_back({"kernel_filter " + std::to_string(k) + (k == 5 ? " centre_bias 1" : ""), 3,
                     json::array({logits, node("op", "kernel_filter", {"input", "logits"},
                                               {{"kernel", k}, {"centre_bias", k == 5 ? 1.0 : 0.0}})})});
    }
    {
        // The temporal network's blend: the frame's 3x3 neighbourhood and a history's pixel.
        const json image = node("image", "slice", {"input"}, {{"from", 0}, {"to", 3}});
        const json history = node("history", "slice", {"input"}, {{"from", 3}, {"to", 6}});
        const json logits =
            node("logits", "conv2d", {"input"}, {{"out_channels", 10}, {"kernel", 3}, {"padding", "same"}});
        c.push_back(
            {"kernel_filter 3 with a history", 6,
             json::array({image, history, logits,
                          node("op", "kernel_filter", {"image", "logits", "history"}, {{"kernel", 3}})})});
    }
    for (double maxCount : {1000.0, 3.0, 999.0}) {  // 999: with the clip
        // The accumulate family's blend: a history of colour and a confidence in (0, 1) (a sigmoid).
        const json image = node("image", "slice", {"input"}, {{"from", 0}, {"to", 3}});
        const json colour = node("colour", "slice", {"input"}, {{"from", 3}, {"to", 6}});
        const json raw = node("raw", "slice", {"input"}, {{"from", 6}, {"to", 7}});
        const json confidence = node("confidence", "activation", {"raw"}, {{"activation", "sigmoid"}});
        const json history = node("history", "concat", {"colour", "confidence"});
        const json logits =
            node("logits", "conv2d", {"input"}, {{"out_channels", 10}, {"kernel", 3}, {"padding", "same"}});
        const bool clip = maxCount == 999.0;
        c.push_back({"accumulate max_count " + std::to_string(int(maxCount)) + (clip ? " clip" : ""), 7,
                     json::array({image, colour, raw, confidence, history, logits,
                                  node("op", "accumulate", {"image", "logits", "history"},
                                       {{"kernel", 3}, {"max_count", maxCount}, {"clip", clip}})}),
                     12, 16, maxCount < 100 || clip});
    }
    single("slice 2..5 of 6", node("op", "slice", {"input"}, {{"from", 2}, {"to", 5}}), false, 6);
    single("slice all", node("op", "slice", {"input"}));
    // A recurrent network's input: an image (3 channels) and its motion (2), split and warped.
    for (const char* filter : {"bilinear", "catmull-rom", "bicubic"}) {
        const json image = node("image", "slice", {"input"}, {{"from", 0}, {"to", 3}});
        const json motion = node("motion", "slice", {"input"}, {{"from", 3}, {"to", 5}});
        c.push_back(
            {std::string("warp ") + filter, 5,
             json::array({image, motion, node("op", "warp", {"image", "motion"}, {{"filter", filter}})}), 12,
             16, std::string(filter) == "bilinear"});
    }
    return c;
}

Model buildModel(const OpCase& c) {
    Model model = Model::fromArchitecture(
        {{"name", "case"}, {"input_channels", c.inputChannels}, {"nodes", c.nodes}, {"output", "op"}});
    model.initialize(7);
    // Biases away from zero, so that their gradients and the fused activations' kinks are exercised.
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> u(-0.3f, 0.3f);
    for (const ParameterInfo& p : model.parameters())
        if (p.isBias)
            for (int64_t i = 0; i < shapeNumel(p.shape); ++i) model.parameterData()[p.offset + i] = u(rng);
    return model;
}

Tensor randomInput(const Shape& shape, uint64_t seed) {
    Tensor t(shape);
    std::mt19937 rng{static_cast<uint32_t>(seed)};
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int64_t i = 0; i < t.numel(); ++i) t.data()[i] = u(rng);
    return t;
}

void PrintTo(const OpCase& c, std::ostream* os) {
    *os << c.label;
}

class Ops : public ::testing::TestWithParam<OpCase> {};

std::string describe(const OpCase& c) {
    return c.label + ": input (1, " + std::to_string(c.inputChannels) + ", " + std::to_string(c.height) +
           ", " + std::to_string(c.width) + "), nodes " + c.nodes.dump();
}

// The registry's shape and the forward agree, in float (Model) and in double (forwardInDouble).
TEST_P(Ops, TheDeclaredShapeIsWhatTheForwardWritesInFloatAndDouble) {
    const OpCase& c = GetParam();
    SCOPED_TRACE(describe(c));
    Model model = buildModel(c);
    model.setFastKernels(false);
    const Shape inShape{1, c.inputChannels, c.height, c.width};
    const Tensor x = randomInput(inShape, 1);
    const Tensor& y = model.forward(x);
    EXPECT_EQ(y.shape(), model.outputShape(inShape));
    const Vec xd(x.data(), x.data() + x.numel());
    const Vec yd = forwardInDouble(model, xd, inShape);
    ASSERT_EQ(int64_t(yd.size()), y.numel());
    double worst = 0;
    for (int64_t i = 0; i < y.numel(); ++i) worst = std::max(worst, std::abs(yd[size_t(i)] - y.data()[i]));
    EXPECT_LE(worst, 1e-5);
}

// The op alone in double: L = sum(r * y) for a random r, its backward with dL/dy = r against central
// differences of L, for every input and the weights.
TEST_P(Ops, BackwardMatchesCentralDifferencesInDouble) {
    const OpCase& c = GetParam();
    SCOPED_TRACE(describe(c));
    const Model model = buildModel(c);
    const std::vector<GraphNode> graph = model.graph();
    const GraphNode& n = graph.back();
    const OpDef& def = opDef(n.op);
    const Shape inShape{1, c.inputChannels, c.height, c.width};
    const std::vector<Shape> shapes = model.nodeShapes(inShape);
    std::vector<Shape> ins;
    for (int i : n.inputs) ins.push_back(i < 0 ? inShape : shapes[size_t(i)]);
    const Shape out = shapes.back();
    std::mt19937 rng(11);
    std::vector<Vec> x;
    for (const Shape& s : ins) x.push_back(randomValues(size_t(shapeNumel(s)), rng, -1.0, 1.0));
    Vec w(model.parameterData(), model.parameterData() + model.parameterCount());
    const Vec r = randomValues(size_t(shapeNumel(out)), rng);
    Vec y(r.size()), pre(r.size());
    std::vector<int32_t> indices;
    const bool fused = def.fusesActivation && n.activation.kind != Activation::None;
    auto run = [&] {
        OpForward<double> call{n, ins, out};
        for (const Vec& v : x) call.inputs.push_back(v.data());
        call.weight = n.weightOffset >= 0 ? w.data() + n.weightOffset : nullptr;
        call.bias = n.biasOffset >= 0 ? w.data() + n.biasOffset : nullptr;
        call.output = fused ? pre.data() : y.data(), call.indices = &indices;
        def.forwardDouble(call);
        if (fused) activationForward(y.data(), pre.data(), int64_t(y.size()), n.activation);
        return dot(y, r);
    };
    run();
    Vec g = r;
    if (fused) {
        g.assign(r.size(), 0.0);
        activationBackward(g.data(), r.data(), pre.data(), y.data(), int64_t(r.size()), n.activation);
    }
    std::vector<Vec> dx;
    for (const Vec& v : x) dx.emplace_back(v.size(), 0.0);
    Vec dw(w.size(), 0.0);
    OpBackward<double> call{n, ins, out};
    for (size_t k = 0; k < x.size(); ++k)
        call.inputs.push_back(x[k].data()), call.dInputs.push_back(dx[k].data());
    call.weight = n.weightOffset >= 0 ? w.data() + n.weightOffset : nullptr;
    call.output = y.data(), call.dOutput = g.data(), call.indices = &indices;
    call.dWeight = n.weightOffset >= 0 ? dw.data() + n.weightOffset : nullptr;
    call.dBias = n.biasOffset >= 0 ? dw.data() + n.biasOffset : nullptr;
    def.backwardDouble(call);
    GradientCheckOptions options;
    options.samples = 40, options.step = 1e-5, options.floorOfLargest = 1e-3, options.piecewise = c.piecewise;
    std::mt19937_64 coordinates(5);
    for (size_t k = 0; k < x.size(); ++k)
        EXPECT_LE(checkGradient(x[k], dx[k], run, coordinates, options).worst, 1e-6) << "input " << k;
    if (n.weightOffset >= 0) {
        // Only this node's parameters: the others are not the op's.
        const int64_t first = n.weightOffset,
                      last = n.biasOffset >= 0 ? n.biasOffset + n.outChannels
                                               : n.weightOffset + int64_t(n.inChannels) * n.outChannels *
                                                                      n.kernel * n.kernel;
        Vec own(w.begin() + first, w.begin() + last), ownGradient(dw.begin() + first, dw.begin() + last);
        auto runOwn = [&] {
            std::copy(own.begin(), own.end(), w.begin() + first);
            return run();
        };
        EXPECT_LE(checkGradient(own, ownGradient, runOwn, coordinates, options).worst, 1e-6) << "weights";
    }
}

// Training's fast kernels and the inference plan against the reference forward; bf16 against float.
TEST_P(Ops, TheFastPathsMatchTheReference) {
    const OpCase& c = GetParam();
    SCOPED_TRACE(describe(c));
    Model model = buildModel(c);
    const Shape inShape{1, c.inputChannels, c.height, c.width};
    const Tensor x = randomInput(inShape, 2);
    model.setFastKernels(false);
    const Tensor reference = model.forward(x).clone();
    model.setFastKernels(true);
    const Tensor fast = model.forward(x).clone();
    InferencePlan plan(model, inShape);
    const Tensor planned = plan.run(x).clone();
    float worstFast = 0, worstPlan = 0, scale = 1;
    for (int64_t i = 0; i < reference.numel(); ++i) {
        worstFast = std::max(worstFast, std::abs(fast.data()[i] - reference.data()[i]));
        worstPlan = std::max(worstPlan, std::abs(planned.data()[i] - reference.data()[i]));
        scale = std::max(scale, std::abs(reference.data()[i]));
    }
    EXPECT_LE(worstFast, 1e-5f * scale) << "training's fast kernels";
    EXPECT_LE(worstPlan, 1e-5f * scale) << "the inference plan";
    if (bf16Available()) {
        InferencePlan half(model, inShape, InferencePrecision::BFloat16);
        const Tensor& y = half.run(x);
        float worst = 0;
        for (int64_t i = 0; i < reference.numel(); ++i)
            worst = std::max(worst, std::abs(y.data()[i] - reference.data()[i]));
        EXPECT_LE(worst, 3e-2f * scale) << "bf16 activations (" << half.bf16Activations() << ")";
    }
}

INSTANTIATE_TEST_SUITE_P(Registry, Ops, ::testing::ValuesIn(cases()), [](const auto& p) {
    std::string name = p.param.label;
    for (char& ch : name)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
    return name;
});

// ---- The layers of nn/layers.h ---------------------------------------------------------------------

using harness::LayerCase;

std::string testName(const std::string& label) {
    std::string name = label.substr(0, label.find(':'));
    for (char& ch : name)
        if (!std::isalnum(static_cast<unsigned char>(ch))) ch = '_';
    return name;
}

class LayerGoldens : public ::testing::TestWithParam<LayerCase> {};
class LayerGradients : public ::testing::TestWithParam<LayerCase> {};

// The float forward and backward on the fixture's values against PyTorch's (float64) results.
TEST_P(LayerGoldens, MatchPyTorch) {
    const LayerCase& c = GetParam();
    SCOPED_TRACE(c.label);
    const SafetensorsFile file =
        readSafetensors(::dejag::testing::sourcePath("tests/golden/nn/" + c.golden + ".safetensors"));
    std::vector<std::vector<float>> args;
    harness::LayerCall<float> call;
    for (size_t k = 0; k < c.names.size(); ++k) {
        args.push_back(file.at(c.names[k]).asFloat());
        ASSERT_EQ(args.back().size(), c.sizes[k]) << c.names[k];
    }
    for (const auto& a : args) call.in.push_back(a.data());
    std::vector<float> out(c.outputSize);
    call.out = out.data();
    c.forwardFloat(call);
    const double forward = relativeError(out, file.at("output").asDouble());
    const std::vector<float> dout = file.at("dout").asFloat();
    ASSERT_EQ(dout.size(), c.outputSize);
    harness::LayerGradient<float> gradient;
    gradient.in = call.in, gradient.out = out.data(), gradient.dOut = dout.data();
    std::vector<std::vector<float>> d;
    for (size_t k = 0; k < c.names.size(); ++k) d.emplace_back(c.sizes[k], 0.0f);
    for (auto& v : d) gradient.dIn.push_back(v.data());
    c.backwardFloat(gradient);
    double backward = 0;
    for (size_t k = 0; k < c.names.size(); ++k)
        backward = std::max(backward, relativeError(d[k], file.at("d" + c.names[k]).asDouble()));
    std::printf("[golden] %-32s forward %.2e  backward %.2e\n", c.golden.c_str(), forward, backward);
    EXPECT_LE(forward, 1e-5) << "forward";
    EXPECT_LE(backward, 1e-4) << "backward";
}

// In double: L = sum(r * y) for a random r; the backward with dL/dy = r against central differences of L
// for every argument (inputs, weights, bias).
void checkLayerGradients(const LayerCase& c) {
    std::mt19937 rng(std::hash<std::string>{}(c.label) & 0xffffffffu);
    std::vector<Vec> args;
    for (size_t k = 0; k < c.sizes.size(); ++k) {
        const bool input = c.names[k] == "input" || c.names[k] == "logits";
        args.push_back(randomValues(c.sizes[k], rng, input ? c.inputLow : -1.0, input ? c.inputHigh : 1.0));
    }
    const Vec r = randomValues(c.outputSize, rng);
    Vec y(c.outputSize);
    auto loss = [&] {
        harness::LayerCall<double> call;
        for (const Vec& a : args) call.in.push_back(a.data());
        call.out = y.data();
        c.forwardDouble(call);
        return dot(y, r);
    };
    loss();
    harness::LayerGradient<double> gradient;
    for (const Vec& a : args) gradient.in.push_back(a.data());
    gradient.out = y.data(), gradient.dOut = r.data();
    std::vector<Vec> d;
    for (const Vec& a : args) d.emplace_back(a.size(), 0.0);
    for (Vec& v : d) gradient.dIn.push_back(v.data());
    c.backwardDouble(gradient);
    GradientCheckOptions options;
    options.samples = 100, options.step = 1e-5, options.floorOfLargest = 1e-3,
    options.piecewise = c.piecewise;
    std::mt19937_64 coordinates(rng());
    for (size_t k = 0; k < args.size(); ++k)
        EXPECT_LE(checkGradient(args[k], d[k], loss, coordinates, options).worst, 1e-6) << c.names[k];
}

TEST_P(LayerGoldens, BackwardMatchesCentralDifferencesInDouble) {
    SCOPED_TRACE(GetParam().label);
    checkLayerGradients(GetParam());
}
TEST_P(LayerGradients, BackwardMatchesCentralDifferencesInDouble) {
    SCOPED_TRACE(GetParam().label);
    checkLayerGradients(GetParam());
}

INSTANTIATE_TEST_SUITE_P(Fixtures, LayerGoldens, ::testing::ValuesIn(harness::goldenLayerCases()),
                         [](const auto& p) { return p.param.golden; });
INSTANTIATE_TEST_SUITE_P(RandomShapes, LayerGradients, ::testing::ValuesIn(harness::randomLayerCases()),
                         [](const auto& p) {
                             return testName(p.param.label) + "_" + std::to_string(p.index);
                         });

// The fixtures of every layer are cases here (those of the losses, the optimizers and a training run are
// other tests').
TEST(LayerHarness, EveryLayerFixtureIsACase) {
    int layers = 0;
    for (const auto& entry :
         std::filesystem::directory_iterator(::dejag::testing::sourcePath("tests/golden/nn"))) {
        const auto layer = json::parse(readSafetensors(entry.path().string()).metadata.at("config"))["layer"]
                               .get<std::string>();
        for (const char* name : {"conv2d", "conv_transpose2d", "maxpool2d", "activation", "nearest",
                                 "bilinear", "pixel_shuffle", "kernel_filter", "warp", "accumulate"})
            layers += layer == name;
    }
    EXPECT_EQ(int(harness::goldenLayerCases().size()), layers);
    EXPECT_GE(layers, 30);
}

// The accumulate blend's invariants: on a still view with full trust the kept colour is the mean of every
// sample so far in linear light (up to the cap, then a running mean with weight 1 / (N + 1)), the confidence
// counts them, and no trust drops the history.
TEST(Accumulate, AStillViewWithFullTrustKeepsTheMeanOfItsSamples) {
    AccumulateDesc d;
    d.batch = 1, d.channels = 2, d.height = 3, d.width = 4, d.kernel = 3, d.maxCount = 8;
    const int64_t plane = 12;
    std::mt19937 rng(5);
    std::uniform_real_distribution<double> u(0, 1);
    for (double trust : {20.0, -40.0}) {
        std::vector<double> history(size_t(3 * plane), 0.0), out(size_t(5 * plane)),
            logits(size_t(10 * plane));
        for (size_t i = 0; i < logits.size(); ++i) logits[i] = i >= size_t(9 * plane) ? trust : u(rng);
        std::vector<double> sum(size_t(2 * plane), 0.0), image(size_t(2 * plane));
        for (int t = 1; t <= 12; ++t) {
            for (double& v : image) v = u(rng);
            accumulateForward(out.data(), image.data(), logits.data(), history.data(), d);
            for (int64_t i = 0; i < 2 * plane; ++i) {
                const double kept = out[size_t(2 * plane + i)];
                if (trust < 0) {
                    EXPECT_NEAR(kept, srgbDecode(image[size_t(i)]),
                                1e-12);  // nothing kept but the new sample
                    continue;
                }
                // Up to 8 samples the plain mean; after, each new one weighs 1 / 9 of what was kept.
                const double linear = srgbDecode(image[size_t(i)]);
                sum[size_t(i)] =
                    t <= 8 ? sum[size_t(i)] + linear : sum[size_t(i)] * 8.0 / 9.0 + linear * 8.0 / 9.0;
                EXPECT_NEAR(kept, sum[size_t(i)] / std::min(t, 8), 1e-12) << "frame " << t;
            }
            const double count = trust < 0 ? 1.0 : std::min(t, 8);
            for (int64_t i = 0; i < plane; ++i)
                EXPECT_NEAR(out[size_t(4 * plane + i)], count / (count + 1), 1e-12);
            for (int64_t c = 0; c < 2; ++c)
                std::copy_n(out.data() + (2 + c) * plane, plane, history.data() + c * plane);
            std::copy_n(out.data() + 4 * plane, plane, history.data() + 2 * plane);
        }
    }
}

// A pixel changed at the centre of the input changes no output pixel further than the receptive field's
// radius from it (every case whose graph keeps the input's size).
TEST(OpTable, NothingBeyondTheReceptiveFieldChanges) {
    int checked = 0;
    for (const OpCase& c : cases()) {
        SCOPED_TRACE(describe(c));
        Model model = buildModel(c);
        model.setFastKernels(false);
        const int H = 24, W = 28;
        const Shape inShape{1, c.inputChannels, H, W};
        const Shape out = model.outputShape(inShape);
        if (out[2] != H || out[3] != W) continue;  // the op changes the size
        ++checked;
        const ReceptiveField field = receptiveField(model);
        // A warp reads wherever the motion points: unbounded, and only a warp is.
        EXPECT_EQ(field.bounded, c.label.rfind("warp", 0) != 0);
        if (!field.bounded) continue;
        Tensor x = randomInput(inShape, 3);
        const Tensor before = model.forward(x).clone();
        const int cy = H / 2, cx = W / 2;
        for (int ch = 0; ch < c.inputChannels; ++ch) x.at(0, ch, cy, cx) += 0.5f;
        const Tensor& after = model.forward(x);
        int changedFar = 0, changedNear = 0;
        for (int64_t ch = 0; ch < out[1]; ++ch)
            for (int y = 0; y < H; ++y)
                for (int xx = 0; xx < W; ++xx) {
                    const bool changed = after.at(0, ch, y, xx) != before.at(0, ch, y, xx);
                    const bool far = std::abs(y - cy) > field.radius || std::abs(xx - cx) > field.radius;
                    changedFar += changed && far, changedNear += changed && !far;
                }
        EXPECT_EQ(changedFar, 0) << "radius " << field.radius;
        EXPECT_GT(changedNear, 0) << "the change reached no output at all";
    }
    EXPECT_GE(checked, 12);
}

// The warp's invariants, every filter: a whole-pixel motion copies the image shifted (the cubics read the
// texel exactly) and a constant image stays constant; and bilinear and Catmull-Rom read a linear ramp
// exactly where the taps lie inside the image (of the cubic convolution kernels only a = -0.5 reproduces
// linear functions: with bicubic's a = -0.75 a ramp comes back bent).
TEST(Warp, WholePixelsCopyConstantsStayAndRampsAreExact) {
    const int H = 9, W = 11;
    WarpDesc d;
    d.height = H, d.width = W;
    std::vector<double> image(size_t(H * W)), ramp(image.size()), constant(image.size(), 0.37),
        motion(size_t(2 * H * W)), out(image.size());
    std::mt19937 rng(4);
    std::uniform_real_distribution<double> u(-1.5, 1.5);
    for (int i = 0; i < H * W; ++i)
        image[size_t(i)] = u(rng), ramp[size_t(i)] = 0.25 * (i % W) - 0.5 * (i / W);
    for (WarpFilter filter : {WarpFilter::Bilinear, WarpFilter::CatmullRom, WarpFilter::Bicubic}) {
        SCOPED_TRACE(warpFilterName(filter));
        d.filter = filter;
        for (int i = 0; i < H * W; ++i) motion[size_t(i)] = 2, motion[size_t(H * W + i)] = -1;
        warpForward(out.data(), image.data(), motion.data(), d);
        for (int y = 0; y < H - 1; ++y)
            for (int x = 2; x < W; ++x) EXPECT_EQ(out[size_t(y * W + x)], image[size_t((y + 1) * W + x - 2)]);
        for (double& m : motion) m = u(rng);
        warpForward(out.data(), constant.data(), motion.data(), d);
        for (double v : out) EXPECT_NEAR(v, 0.37, 1e-12);
        if (filter == WarpFilter::Bicubic) continue;
        warpForward(out.data(), ramp.data(), motion.data(), d);
        const int reach = d.taps() / 2 + 2;
        for (int y = reach; y < H - reach; ++y)
            for (int x = reach; x < W - reach; ++x) {
                const double sx = x - motion[size_t(y * W + x)], sy = y - motion[size_t(H * W + y * W + x)];
                EXPECT_NEAR(out[size_t(y * W + x)], 0.25 * sx - 0.5 * sy, 1e-12);
            }
    }
    EXPECT_THROW(parseWarpFilter("lanczos"), Error);
}

// The inference warp (4 floats a pixel in, planes out) is the layer's forward on the same image at every
// SIMD level: every filter, pixels whose taps lie inside and pixels whose taps cross the borders, a NaN
// and a huge motion among the motion; 1 to 4 channels, and one channel stored as a plane.
class WarpLevels : public testing::SimdLevelTest {};
INSTANTIATE_TEST_SUITE_P(SimdLevels, WarpLevels, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);
TEST_P(WarpLevels, TheInterleavedWarpIsTheLayersForward) {
    // Large motion (most taps cross a border somewhere in each run of pixels), then small motion (whole runs
    // of 16 pixels with every tap inside).
    for (const float reach : {6.0f, 1.5f}) {
        SCOPED_TRACE("motion up to " + std::to_string(reach));
        const int H = 19, W = 37;
        std::mt19937 rng(8);
        std::uniform_real_distribution<float> u(-1, 1), m(-reach, reach);
        std::vector<float> interleaved(size_t(H * W * 4)), motionPairs(size_t(H * W * 2));
        for (float& v : interleaved) v = u(rng);
        for (float& v : motionPairs) v = m(rng);
        if (reach > 2) motionPairs[10] = std::nanf(""), motionPairs[23] = 1e9f;
        std::vector<float> motionPlanes(motionPairs.size());
        for (int p = 0; p < H * W; ++p)
            motionPlanes[size_t(p)] = motionPairs[size_t(2 * p)],
            motionPlanes[size_t(H * W + p)] = motionPairs[size_t(2 * p + 1)];
        for (WarpFilter filter : {WarpFilter::Bilinear, WarpFilter::CatmullRom, WarpFilter::Bicubic})
            for (int channels = 1; channels <= 4; ++channels) {
                SCOPED_TRACE(std::string(warpFilterName(filter)) + " " + std::to_string(channels));
                std::vector<float> planes(size_t(channels * H * W)), expected(planes.size()),
                    out(planes.size());
                for (int c = 0; c < channels; ++c)
                    for (int p = 0; p < H * W; ++p)
                        planes[size_t(c * H * W + p)] = interleaved[size_t(4 * p + c)];
                WarpDesc d;
                d.channels = channels, d.height = H, d.width = W, d.filter = filter;
                warpForward(expected.data(), planes.data(), motionPlanes.data(), d);
                float* rows[4];
                for (int c = 0; c < channels; ++c) rows[c] = out.data() + c * H * W;
                warpInterleaved(rows, interleaved.data(), motionPairs.data(), W, H, channels, filter);
                for (size_t i = 0; i < out.size(); ++i) ASSERT_NEAR(out[i], expected[i], 1e-6f) << i;
                if (channels == 1) {  // one channel as a plane
                    std::vector<float> plane(size_t(H * W));
                    warpPlane(plane.data(), planes.data(), motionPairs.data(), W, H, filter);
                    for (size_t i = 0; i < plane.size(); ++i) ASSERT_NEAR(plane[i], expected[i], 1e-6f) << i;
                }
            }
    }
    const int H = 19, W = 37;
    std::vector<float> interleaved(size_t(H * W * 4)), motionPairs(size_t(H * W * 2));
    float* none[1] = {nullptr};
    EXPECT_THROW(warpInterleaved(none, interleaved.data(), motionPairs.data(), W, H, 5, WarpFilter::Bilinear),
                 Error);
}

TEST(OpTable, EveryOpHasItsEntryAndItsName) {
    for (int i = 0; i < int(GraphOp::Count); ++i) {
        const OpDef& d = opDef(GraphOp(i));
        EXPECT_EQ(d.op, GraphOp(i));
        EXPECT_EQ(opNamed(d.name), GraphOp(i)) << d.name;
        EXPECT_STREQ(graphOpName(GraphOp(i)), d.name);
    }
    EXPECT_EQ(opNamed("conv3d"), GraphOp::Count);
    EXPECT_THROW(Model::fromArchitecture(
                     {{"input_channels", 3}, {"nodes", json::array({node("x", "conv3d", {"input"})})}}),
                 Error);
}

}  // namespace
}  // namespace dejag::nn

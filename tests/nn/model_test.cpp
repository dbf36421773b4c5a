// The model graph: architectures, the seed2020 replica against PyTorch over 5 Adam steps, model files,
// bad input, determinism and learning.
#include "nn/model.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/init.h"
#include "nn/losses.h"
#include "nn/optim.h"
#include "nn/safetensors.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

Tensor randomTensor(const Shape& shape, uint64_t seed, float low = 0.0f, float high = 1.0f) {
    Tensor t(shape);
    Rng rng(seed);
    for (int64_t i = 0; i < t.numel(); ++i) t.data()[i] = rng.uniform(low, high);
    return t;
}

TEST(Model, Seed2020HasThePublishedParameterCounts) {
    const Model model = Model::builtin("seed2020");
    std::map<std::string, int64_t> perLayer;
    for (const ParameterInfo& p : model.parameters())
        perLayer[p.name.substr(0, p.name.find('.'))] += shapeNumel(p.shape);
    EXPECT_EQ(perLayer["conv1"], 832);
    EXPECT_EQ(perLayer["conv2"], 9248);
    EXPECT_EQ(perLayer["conv3"], 2112);
    EXPECT_EQ(perLayer["conv4"], 73856);
    EXPECT_EQ(perLayer["up1"], 73792);  // not published; 3x3 assumed (docs/seed-cnn.md)
    EXPECT_EQ(perLayer["up2"], 577);
    EXPECT_EQ(model.parameterCount(), 832 + 9248 + 2112 + 73856 + 73792 + 577);
    EXPECT_EQ(model.outputShape({1, 1, 800, 800}), (Shape{1, 1, 800, 800}));
}

TEST(Model, FastFamilyIsResidualAndCheap) {
    ModelOptions options;
    options.width = 16, options.depth = 3;
    Model model = Model::builtin("fast", options);
    EXPECT_EQ(model.outputShape({2, 3, 64, 48}), (Shape{2, 3, 64, 48}));
    // Multiply-adds per full-resolution pixel: nothing runs at full resolution, the U-Net's levels are
    // 1/2, 1/4 and 1/8 (docs/train.md: 3,996).
    const double macsPerPixel = double(model.macs({1, 3, 256, 256})) / (256.0 * 256.0);
    EXPECT_LT(macsPerPixel, 4000.0);
    // With the last conv at zero, the output is the input exactly.
    model.initialize(1);
    const ParameterInfo& last = model.parameter("to_subpixels.weight");
    std::fill(model.parameterData() + last.offset,
              model.parameterData() + last.offset + shapeNumel(last.shape), 0.0f);
    const Tensor input = randomTensor({1, 3, 24, 16}, 2);
    const Tensor& output = model.forward(input);
    for (int64_t i = 0; i < input.numel(); ++i) ASSERT_EQ(output.data()[i], input.data()[i]);
}

TEST(Model, KpnFamilyOnlyMixesTheNeighbourhood) {
    Model model = Model::builtin("kpn");
    EXPECT_EQ(model.outputShape({2, 3, 64, 48}), (Shape{2, 3, 64, 48}));
    // The trunk of fast with a 1x1 head of 36 logits at 1/2 instead of a 3x3 head of 12, plus the
    // filter's 27 multiply-adds per pixel.
    const double macsPerPixel = double(model.macs({1, 3, 256, 256})) / (256.0 * 256.0);
    EXPECT_NEAR(macsPerPixel, 3996.0 - 432.0 + 144.0 + 27.0, 0.5);
    model.initialize(3);
    const ParameterInfo& head = model.parameter("to_kernels.weight");  // far from the identity start
    for (int64_t i = 0; i < shapeNumel(head.shape); ++i) model.parameterData()[head.offset + i] *= 30.0f;
    const Tensor input = randomTensor({1, 3, 24, 16}, 4);
    const Tensor& output = model.forward(input);
    // Every output is a convex combination of its 3x3 neighbourhood (edges repeated): inside its range.
    auto at = [&](int64_t c, int64_t y, int64_t x) {
        return input.data()[(c * 24 + std::clamp<int64_t>(y, 0, 23)) * 16 + std::clamp<int64_t>(x, 0, 15)];
    };
    for (int64_t c = 0; c < 3; ++c)
        for (int64_t y = 0; y < 24; ++y)
            for (int64_t x = 0; x < 16; ++x) {
                float low = INFINITY, high = -INFINITY;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx)
                        low = std::min(low, at(c, y + dy, x + dx)),
                        high = std::max(high, at(c, y + dy, x + dx));
                const float v = output.data()[(c * 24 + y) * 16 + x];
                ASSERT_GE(v, low - 1e-6f) << c << " " << y << " " << x;
                ASSERT_LE(v, high + 1e-6f) << c << " " << y << " " << x;
            }
    // A flat image stays flat, whatever the weights.
    Tensor flat({1, 3, 24, 16});
    flat.fill(0.3f);
    const Tensor& same = model.forward(flat);
    for (int64_t i = 0; i < flat.numel(); ++i) ASSERT_NEAR(same.data()[i], 0.3f, 1e-6f);
}

// The architecture file docs/train.md measures ("Seven times the multiply-adds"): it loads, keeps the
// frame's size, and has the parameter and multiply-add counts the document quotes.
TEST(Model, DocumentedKpnFullArchitectureHasTheQuotedCounts) {
    std::ifstream file(testing::sourcePath("docs/arch/kpn-full.json"));
    ASSERT_TRUE(file.good());
    const Model model = Model::fromArchitecture(nlohmann::json::parse(file));
    EXPECT_EQ(model.parameterCount(), 93105);
    EXPECT_EQ(model.outputShape({1, 3, 64, 48}), (Shape{1, 3, 64, 48}));
    EXPECT_EQ(std::lround(double(model.macs({1, 3, 256, 256})) / (256.0 * 256.0)), 6891);
}

// 5 Adam steps of seed2020 on one batch against PyTorch (tests/golden/make_nn_golden.py), with the
// reference kernels and with the fast ones.
class Seed2020Golden : public ::testing::TestWithParam<bool> {};

TEST_P(Seed2020Golden, AdamStepsMatchPyTorch) {
    const SafetensorsFile golden =
        readSafetensors(testing::sourcePath("tests/golden/nn/seed2020_adam5.safetensors"));
    Model model = Model::builtin("seed2020");
    model.setFastKernels(GetParam());
    std::printf("[golden] seed2020 with the %s kernels\n", GetParam() ? "fast" : "reference");
    for (const ParameterInfo& p : model.parameters()) {
        const std::vector<float> values = golden.at("initial." + p.name).asFloat();
        ASSERT_EQ(int64_t(values.size()), shapeNumel(p.shape)) << p.name;
        std::copy(values.begin(), values.end(), model.parameterData() + p.offset);
    }
    const StoredTensor& inputRecord = golden.at("input");
    Tensor input(inputRecord.shape), target(inputRecord.shape);
    std::copy(inputRecord.f32.begin(), inputRecord.f32.end(), input.data());
    const std::vector<float> targetValues = golden.at("target").asFloat();
    std::copy(targetValues.begin(), targetValues.end(), target.data());
    const std::vector<double> losses = golden.at("losses").asDouble();

    OptimizerConfig config;  // Adam, PyTorch defaults
    Optimizer optimizer(config, model.parameterCount());
    const SsimLossDesc shape{input.dim(0), input.dim(1), input.dim(2), input.dim(3), 1.0};
    double worstLoss = 0.0, worstGradient = 0.0;
    for (size_t step = 0; step < losses.size(); ++step) {
        const Tensor& output = model.forward(input);
        Tensor doutput(output.shape());
        const double loss = ssimLoss(output.data(), target.data(), shape);
        ssimLossBackward(doutput.data(), output.data(), target.data(), shape, 1.0);
        model.backward(doutput);
        if (step == 0) {
            // The graph's backward against PyTorch's, per parameter tensor (relative to its largest value).
            for (const ParameterInfo& p : model.parameters()) {
                const std::vector<double> want = golden.at("grad0." + p.name).asDouble();
                double worst = 0.0, scale = 0.0;
                for (size_t i = 0; i < want.size(); ++i) {
                    worst = std::max(worst,
                                     std::abs(double(model.gradientData()[p.offset + int64_t(i)]) - want[i]));
                    scale = std::max(scale, std::abs(want[i]));
                }
                worstGradient = std::max(worstGradient, worst / scale);
                EXPECT_LE(worst / scale, 1e-4) << p.name;
            }
        }
        optimizer.step(model.parameterData(), model.gradientData(), 1e-3);
        worstLoss = std::max(worstLoss, std::abs(loss - losses[step]) / std::abs(losses[step]));
    }
    // Final weights: max |dejag - torch| over max |torch|, and the same for the updates (final - initial),
    // norm-wise: Adam divides by sqrt(v), so a parameter whose gradient is near zero (e.g. 1e-9, where
    // float32 summation differs from float64 in the last digits) can take a visibly different step.
    double worstWeight = 0.0, scale = 0.0, updateError = 0.0, updateNorm = 0.0;
    std::string worstName;
    for (const ParameterInfo& p : model.parameters()) {
        const std::vector<double> want = golden.at("final." + p.name).asDouble();
        const std::vector<float> initial = golden.at("initial." + p.name).asFloat();
        for (size_t i = 0; i < want.size(); ++i) {
            const double got = model.parameterData()[p.offset + int64_t(i)];
            if (std::abs(got - want[i]) > worstWeight) worstName = p.name + "[" + std::to_string(i) + "]";
            worstWeight = std::max(worstWeight, std::abs(got - want[i]));
            scale = std::max(scale, std::abs(want[i]));
            updateError += (got - want[i]) * (got - want[i]);
            updateNorm += (want[i] - initial[i]) * (want[i] - initial[i]);
        }
    }
    const double updateRelative = std::sqrt(updateError / updateNorm);
    std::printf("[golden] seed2020 backward (step 1): gradient rel. error %.2e\n", worstGradient);
    std::printf(
        "[golden] seed2020 5 Adam steps: loss rel. error %.2e; final weights max rel. error %.2e (at %s), "
        "update rel. error (L2) %.2e\n",
        worstLoss, worstWeight / scale, worstName.c_str(), updateRelative);
    EXPECT_LE(worstLoss, 1e-5);
    EXPECT_LE(worstWeight / scale, 1e-3);
    EXPECT_LE(updateRelative, 1e-3);
}

// The fast kernels against the reference kernels inside the whole graph: outputs and every gradient.
void expectFastMatchesReference(Model& model, const Shape& shape) {
    model.initialize(21);
    const Tensor input = randomTensor(shape, 22);
    model.setFastKernels(false);
    const Tensor wantOut = model.forward(input).clone();
    const Tensor dout = randomTensor(wantOut.shape(), 23, -1.0f, 1.0f);
    model.backward(dout);
    const std::vector<float> wantGrad(model.gradientData(), model.gradientData() + model.parameterCount());
    model.setFastKernels(true);
    const Tensor& out = model.forward(input);
    double worst = 0.0, scale = 1e-9;
    for (int64_t i = 0; i < out.numel(); ++i) {
        worst = std::max(worst, double(std::abs(out.data()[i] - wantOut.data()[i])));
        scale = std::max(scale, double(std::abs(wantOut.data()[i])));
    }
    EXPECT_LE(worst / scale, 1e-5) << model.name() << " forward";
    model.backward(dout);
    for (const ParameterInfo& p : model.parameters()) {
        double w = 0.0, sc = 1e-9;
        for (int64_t i = p.offset; i < p.offset + shapeNumel(p.shape); ++i) {
            w = std::max(w, double(std::abs(model.gradientData()[i] - wantGrad[size_t(i)])));
            sc = std::max(sc, double(std::abs(wantGrad[size_t(i)])));
        }
        EXPECT_LE(w / sc, 1e-4) << model.name() << " gradient of " << p.name;
    }
}

INSTANTIATE_TEST_SUITE_P(Kernels, Seed2020Golden, ::testing::Values(false, true),
                         [](const ::testing::TestParamInfo<bool>& test) {
                             return std::string(test.param ? "fast" : "reference");
                         });

// The double-precision forward (the yardstick of the accumulation figure in `dejag bench stability`)
// agrees with the float32 forward to float rounding, for both built-in families.
TEST(Model, ForwardInDoubleAgreesWithTheFloatForward) {
    for (const std::string name : {"seed2020", "fast", "kpn"}) {
        Model model = Model::builtin(name);
        model.initialize(5);
        const Shape shape = {2, model.inputChannels(), 40, 48};
        Tensor x(shape);
        Rng rng(9);
        for (int64_t i = 0; i < x.numel(); ++i) x.data()[i] = rng.uniform();
        const Tensor& y = model.forward(x);
        const std::vector<double> reference =
            forwardInDouble(model, std::vector<double>(x.data(), x.data() + x.numel()), shape);
        ASSERT_EQ(int64_t(reference.size()), y.numel()) << name;
        double difference = 0, norm = 0;
        for (size_t i = 0; i < reference.size(); ++i) {
            difference += (y.data()[i] - reference[i]) * (y.data()[i] - reference[i]);
            norm += reference[i] * reference[i];
        }
        EXPECT_LE(std::sqrt(difference / norm), 1e-6) << name;
        EXPECT_GT(norm, 0.0) << name;
    }
}

// A recurrent network's step: its input holds the frame (3), its previous output (3) and the motion (2);
// the history is warped and concatenated with the frame. The gradient w.r.t. that input (what
// backpropagation through time passes to the previous step) against central differences of the
// double-precision forward, on the fast and the reference kernels.
TEST(Model, TheInputGradientMatchesCentralDifferences) {
    using nlohmann::json;
    auto node = [](const std::string& name, const std::string& op, std::vector<std::string> inputs,
                   json fields = json::object()) {
        json n = {{"name", name}, {"op", op}, {"inputs", inputs}};
        for (auto& [k, v] : fields.items()) n[k] = v;
        return n;
    };
    const json nodes = json::array(
        {node("frame", "slice", {"input"}, {{"from", 0}, {"to", 3}}),
         node("history", "slice", {"input"}, {{"from", 3}, {"to", 6}}),
         node("motion", "slice", {"input"}, {{"from", 6}, {"to", 8}}),
         node("warped", "warp", {"history", "motion"}, {{"filter", "catmull-rom"}}),
         node("both", "concat", {"frame", "warped"}),
         node("c1", "conv2d", {"both"},
              {{"out_channels", 8}, {"kernel", 3}, {"padding", "same"}, {"activation", "sigmoid"}}),
         node("c2", "conv2d", {"c1"}, {{"out_channels", 3}, {"kernel", 3}, {"padding", "same"}}),
         node("out", "add", {"c2", "warped"})});
    for (bool fast : {true, false}) {
        SCOPED_TRACE(fast ? "fast kernels" : "reference kernels");
        Model model = Model::fromArchitecture(
            {{"name", "step"}, {"input_channels", 8}, {"nodes", nodes}, {"output", "out"}});
        model.initialize(3);
        model.setFastKernels(fast);
        model.setInputGradient(true);
        const Shape shape{1, 8, 10, 12};
        Tensor x(shape), r(Shape{1, 3, 10, 12});
        Rng rng(21);
        for (int64_t i = 0; i < x.numel(); ++i) {
            const int64_t channel = (i / (10 * 12)) % 8;
            x.data()[i] = channel >= 6 ? float(rng.uniform() * 3 - 1.5) : float(rng.uniform());
        }
        for (int64_t i = 0; i < r.numel(); ++i) r.data()[i] = float(rng.uniform() * 2 - 1);
        model.forward(x);
        model.backward(r);
        const Tensor& g = model.inputGradient();
        ASSERT_EQ(g.shape(), shape);
        std::vector<double> xd(x.data(), x.data() + x.numel());
        auto loss = [&] {
            const std::vector<double> y = forwardInDouble(model, xd, shape);
            double sum = 0;
            for (size_t i = 0; i < y.size(); ++i) sum += y[i] * r.data()[i];
            return sum;
        };
        double worst = 0, largest = 0;
        for (int64_t i = 0; i < x.numel(); i += 7) {
            const double keep = xd[size_t(i)], h = 1e-5;
            xd[size_t(i)] = keep + h;
            const double up = loss();
            xd[size_t(i)] = keep - h;
            const double down = loss();
            xd[size_t(i)] = keep;
            const double numeric = (up - down) / (2 * h);
            worst = std::max(worst, std::abs(numeric - g.data()[i]));
            largest = std::max(largest, std::abs(numeric));
        }
        EXPECT_GT(largest, 0.1);
        EXPECT_LE(worst, 1e-4 * std::max(1.0, largest));
    }
    Model plain = Model::builtin("fast");
    EXPECT_THROW((void)plain.inputGradient(), Error);
}

TEST(Model, FastKernelsMatchTheReferenceKernelsInTheGraph) {
    Model seed = Model::builtin("seed2020");
    expectFastMatchesReference(seed, {2, 1, 24, 20});
    Model fast = Model::builtin("fast");
    expectFastMatchesReference(fast, {2, 3, 24, 40});
    Model kpn = Model::builtin("kpn");
    expectFastMatchesReference(kpn, {2, 3, 24, 40});
}

TEST(Model, SameSeedSameWeightsAndThreadCountDoesNotChangeOutputs) {
    Model a = Model::builtin("seed2020"), b = Model::builtin("seed2020");
    a.initialize(42);
    b.initialize(42);
    ASSERT_TRUE(std::equal(a.parameterData(), a.parameterData() + a.parameterCount(), b.parameterData()));
    b.initialize(43);
    EXPECT_FALSE(std::equal(a.parameterData(), a.parameterData() + a.parameterCount(), b.parameterData()));

    const Tensor input = randomTensor({2, 1, 24, 20}, 5);
    setThreadCount(1);
    const Tensor one = a.forward(input).clone();
    Tensor dout = randomTensor(one.shape(), 6, -1.0f, 1.0f);
    a.backward(dout);
    const std::vector<float> gradsOne(a.gradientData(), a.gradientData() + a.parameterCount());
    setThreadCount(2);
    const Tensor& two = a.forward(input);
    a.backward(dout);
    setThreadCount(0);
    for (int64_t i = 0; i < one.numel(); ++i) ASSERT_EQ(one.data()[i], two.data()[i]);
    for (int64_t i = 0; i < a.parameterCount(); ++i) ASSERT_EQ(gradsOne[size_t(i)], a.gradientData()[i]);
}

TEST(Model, SaveLoadGivesIdenticalOutputs) {
    testing::TempDir dir;
    Model model = Model::builtin("fast");
    model.initialize(7);
    saveModel(dir.file("m.safetensors"), model, {{"dejag.provenance", "unit test"}});
    std::map<std::string, std::string> metadata;
    Model loaded = loadModel(dir.file("m.safetensors"), &metadata);
    EXPECT_EQ(metadata["dejag.provenance"], "unit test");
    EXPECT_EQ(metadata["dejag.input_colour"], "sRGB-encoded RGB");
    EXPECT_EQ(metadata["dejag.normalisation"], "[0, 1]");
    EXPECT_EQ(metadata["dejag.format"], "dejag-model-1");
    EXPECT_EQ(loaded.name(), "fast");
    const Tensor input = randomTensor({1, 3, 16, 16}, 8);
    const Tensor expected = model.forward(input).clone();
    const Tensor& got = loaded.forward(input);
    for (int64_t i = 0; i < expected.numel(); ++i) ASSERT_EQ(expected.data()[i], got.data()[i]);
}

std::string expectLoadError(const std::string& path) {
    try {
        loadModel(path);
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
        return e.what();
    }
    ADD_FAILURE() << "loading " << path << " did not fail";
    return "";
}

TEST(Model, BadModelFilesAreRefusedClearly) {
    testing::TempDir dir;
    Model model = Model::builtin("seed2020");
    model.initialize(1);
    saveModel(dir.file("good.safetensors"), model);
    const auto size = std::filesystem::file_size(dir.file("good.safetensors"));

    std::filesystem::copy_file(dir.file("good.safetensors"), dir.file("truncated.safetensors"));
    std::filesystem::resize_file(dir.file("truncated.safetensors"), size - 100);
    EXPECT_NE(expectLoadError(dir.file("truncated.safetensors")).find("run past"), std::string::npos);

    std::filesystem::copy_file(dir.file("good.safetensors"), dir.file("header.safetensors"));
    std::filesystem::resize_file(dir.file("header.safetensors"), 20);
    expectLoadError(dir.file("header.safetensors"));

    std::ofstream(dir.file("junk.safetensors")) << "not a model at all, just text";
    expectLoadError(dir.file("junk.safetensors"));

    // Right file format, wrong architecture: a fast model's weights under seed2020's architecture.
    Model fast = Model::builtin("fast");
    std::vector<TensorToWrite> tensors;
    for (const ParameterInfo& p : fast.parameters())
        tensors.push_back({p.name, p.shape, fast.parameterData() + p.offset});
    writeSafetensors(dir.file("mismatch.safetensors"), tensors,
                     {{"dejag.architecture", model.architecture().dump()}});
    EXPECT_NE(expectLoadError(dir.file("mismatch.safetensors")).find("missing"), std::string::npos);

    // Wrong shape for one parameter.
    std::vector<float> big(64 * 64 * 9);
    std::vector<TensorToWrite> wrong;
    for (const ParameterInfo& p : model.parameters())
        wrong.push_back({p.name, p.name == "conv1.weight" ? Shape{32, 2, 5, 5} : p.shape,
                         p.name == "conv1.weight" ? big.data() : model.parameterData() + p.offset});
    writeSafetensors(dir.file("shape.safetensors"), wrong,
                     {{"dejag.architecture", model.architecture().dump()}});
    EXPECT_NE(expectLoadError(dir.file("shape.safetensors")).find("conv1.weight"), std::string::npos);

    // A NaN weight.
    Model poisoned = Model::builtin("seed2020");
    poisoned.parameterData()[5] = std::nanf("");
    saveModel(dir.file("nan.safetensors"), poisoned);
    EXPECT_NE(expectLoadError(dir.file("nan.safetensors")).find("non-finite"), std::string::npos);

    // No architecture.
    writeSafetensors(dir.file("plain.safetensors"), tensors, {});
    EXPECT_NE(expectLoadError(dir.file("plain.safetensors")).find("architecture"), std::string::npos);
}

TEST(Model, BadArchitecturesAndInputsAreClearErrors) {
    using nlohmann::json;
    auto arch = [](json nodes) { return json{{"input_channels", 1}, {"nodes", nodes}}; };
    EXPECT_THROW(
        Model::fromArchitecture(arch(json::array({{{"name", "a"}, {"op", "warp"}, {"inputs", {"input"}}}}))),
        Error);
    EXPECT_THROW(Model::fromArchitecture(
                     arch(json::array({{{"name", "a"}, {"op", "activation"}, {"inputs", {"nope"}}}}))),
                 Error);
    EXPECT_THROW(Model::fromArchitecture(
                     arch(json::array({{{"name", "a"}, {"op", "conv2d"}, {"inputs", {"input"}}}}))),
                 Error);  // no out_channels
    EXPECT_THROW(Model::fromArchitecture(json{{"nodes", json::array()}}), Error);
    // A kernel filter whose logits are not kernel^2 channels, or whose kernel is even.
    auto filter = [&](int logits, int kernel) {
        return arch(json::array(
            {{{"name", "l"},
              {"op", "conv2d"},
              {"inputs", {"input"}},
              {"out_channels", logits},
              {"kernel", 1}},
             {{"name", "f"}, {"op", "kernel_filter"}, {"inputs", {"input", "l"}}, {"kernel", kernel}}}));
    };
    EXPECT_NO_THROW(Model::fromArchitecture(filter(9, 3)));
    try {
        Model::fromArchitecture(filter(8, 3));
        FAIL() << "8 logits for a 3x3 kernel accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("kernel^2"), std::string::npos) << e.what();
    }
    EXPECT_THROW(Model::fromArchitecture(filter(4, 2)), Error);
    EXPECT_THROW(Model::builtin("resnet50"), Error);

    Model model = Model::builtin("seed2020");
    model.initialize(1);
    EXPECT_THROW(model.forward(Tensor({1, 3, 16, 16})), Error);  // wrong channel count
    Tensor nan({1, 1, 16, 16});
    nan.data()[17] = std::nanf("");
    try {
        model.forward(nan);
        FAIL() << "NaN input accepted";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("non-finite"), std::string::npos);
    }
    Model fast = Model::builtin("fast");
    EXPECT_THROW(fast.forward(Tensor({1, 3, 20, 16})), Error);  // not a multiple of 8: the levels differ
}

TEST(Learning, SingleConvRecoversAKnownKernel) {
    // y = k * x + b with a known 3x3 kernel; MSE is convex in (k, b), Adam with a cosine schedule finds it.
    const float known[9] = {0.05f, -0.2f, 0.1f, 0.3f, 0.5f, -0.4f, -0.1f, 0.25f, 0.15f};
    const float knownBias = 0.07f;
    Conv2dDesc d;
    d.batch = 4, d.inChannels = 1, d.outChannels = 1, d.inHeight = 24, d.inWidth = 24;
    d.kernelHeight = d.kernelWidth = 3;
    d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
    const Tensor x = randomTensor({4, 1, 24, 24}, 11, -1.0f, 1.0f);
    Tensor target({4, 1, 24, 24});
    conv2dForward(target.data(), x.data(), known, &knownBias, d);

    std::vector<float> params(10, 0.0f), grads(10);
    OptimizerConfig config;
    config.learningRate = 0.05;
    Optimizer optimizer(config, 10);
    LrSchedule schedule;
    schedule.kind = LrSchedule::Kind::Cosine;
    schedule.baseRate = 0.05;
    schedule.totalSteps = 1500;
    Tensor y({4, 1, 24, 24}), dy({4, 1, 24, 24});
    for (int step = 0; step < 1500; ++step) {
        conv2dForward(y.data(), x.data(), params.data(), params.data() + 9, d);
        dy.zero();
        mseLossBackward(dy.data(), y.data(), target.data(), y.numel(), 1.0);
        std::fill(grads.begin(), grads.end(), 0.0f);
        conv2dBackward<float>(nullptr, grads.data(), grads.data() + 9, dy.data(), x.data(), params.data(), d);
        optimizer.step(params.data(), grads.data(), schedule.rateAt(step));
    }
    for (int i = 0; i < 9; ++i) EXPECT_NEAR(params[size_t(i)], known[i], 1e-4) << "tap " << i;
    EXPECT_NEAR(params[9], knownBias, 1e-4);
}

// Synthetic aliasing: a hard-edged pattern (no anti-aliasing) against its box-filtered version.
void syntheticPairs(Tensor& aliased, Tensor& truth, uint64_t seed) {
    Rng rng(seed);
    const int64_t N = aliased.dim(0), H = aliased.dim(2), W = aliased.dim(3);
    for (int64_t n = 0; n < N; ++n) {
        const float angle = rng.uniform(0.2f, 1.3f), offset = rng.uniform(0.0f, 8.0f),
                    period = rng.uniform(5.0f, 11.0f);
        auto edge = [&](float x, float y) {
            const float u = x * std::cos(angle) + y * std::sin(angle) + offset;
            return std::fmod(std::abs(u), period) < period * 0.5f ? 0.85f : 0.15f;
        };
        for (int64_t y = 0; y < H; ++y)
            for (int64_t x = 0; x < W; ++x) {
                aliased.at(n, 0, y, x) = edge(float(x) + 0.5f, float(y) + 0.5f);
                float sum = 0.0f;
                for (int sy = 0; sy < 4; ++sy)
                    for (int sx = 0; sx < 4; ++sx)
                        sum += edge(float(x) + (sx + 0.5f) / 4, float(y) + (sy + 0.5f) / 4);
                truth.at(n, 0, y, x) = sum / 16.0f;
            }
    }
}

TEST(Learning, Seed2020LowersOneMinusSsimOnSyntheticAliasing) {
    Model model = Model::builtin("seed2020");
    model.initialize(2020);
    Tensor aliased({4, 1, 32, 32}), truth({4, 1, 32, 32});
    Tensor heldOutAliased({4, 1, 32, 32}), heldOutTruth({4, 1, 32, 32});
    syntheticPairs(heldOutAliased, heldOutTruth, 999);
    const SsimLossDesc shape{4, 1, 32, 32, 1.0};
    auto heldOutLoss = [&] {
        return ssimLoss(model.forward(heldOutAliased).data(), heldOutTruth.data(), shape);
    };
    const double before = heldOutLoss();
    OptimizerConfig config;
    Optimizer optimizer(config, model.parameterCount());
    for (int step = 0; step < 60; ++step) {
        syntheticPairs(aliased, truth, uint64_t(step));
        const Tensor& out = model.forward(aliased);
        Tensor dout(out.shape());
        ssimLossBackward(dout.data(), out.data(), truth.data(), shape, 1.0);
        model.backward(dout);
        optimizer.step(model.parameterData(), model.gradientData(), 2e-3);
    }
    const double after = heldOutLoss();
    std::printf("[learning] seed2020, 60 Adam steps: held-out 1 - SSIM %.4f -> %.4f\n", before, after);
    EXPECT_LT(after, 0.5 * before);
}

}  // namespace
}  // namespace dejag::nn

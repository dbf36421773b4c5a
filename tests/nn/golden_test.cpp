// dejag's nn against PyTorch: every layer, loss and optimizer on the committed fixtures of
// tests/golden/make_nn_golden.py. Forward relative error <= 1e-5, backward <= 1e-4, where the relative
// error is max |dejag - torch| / max |torch| over the tensor (torch computed in float64).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "nn/layers.h"
#include "nn/losses.h"
#include "nn/optim.h"
#include "nn/safetensors.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

constexpr double kForwardTolerance = 1e-5, kBackwardTolerance = 1e-4;

double relativeError(const std::vector<float>& got, const std::vector<double>& want) {
    EXPECT_EQ(got.size(), want.size());
    double worst = 0.0, scale = 0.0;
    for (size_t i = 0; i < std::min(got.size(), want.size()); ++i) {
        worst = std::max(worst, std::abs(double(got[i]) - want[i]));
        scale = std::max(scale, std::abs(want[i]));
    }
    return scale > 0 ? worst / scale : worst;
}

struct Fixture {
    std::string name;
    SafetensorsFile file;
    nlohmann::json config;
    std::vector<float> f(const std::string& key) const { return file.at(key).asFloat(); }
    std::vector<double> d(const std::string& key) const { return file.at(key).asDouble(); }
    bool has(const std::string& key) const { return file.tensors.count(key) > 0; }
};

std::vector<Fixture> loadFixtures(const std::string& layer) {
    std::vector<Fixture> fixtures;
    const std::filesystem::path folder = testing::sourcePath("tests/golden/nn");
    for (const auto& entry : std::filesystem::directory_iterator(folder)) {
        if (entry.path().extension() != ".safetensors") continue;
        Fixture fixture;
        fixture.name = entry.path().stem().string();
        fixture.file = readSafetensors(entry.path().string());
        fixture.config = nlohmann::json::parse(fixture.file.metadata.at("config"));
        if (fixture.config["layer"] == layer) fixtures.push_back(std::move(fixture));
    }
    std::sort(fixtures.begin(), fixtures.end(),
              [](const Fixture& a, const Fixture& b) { return a.name < b.name; });
    return fixtures;
}

void report(const Fixture& fixture, double forward, double backward) {
    std::printf("[golden] %-32s forward %.2e  backward %.2e\n", fixture.name.c_str(), forward, backward);
    EXPECT_LE(forward, kForwardTolerance) << fixture.name << " forward";
    EXPECT_LE(backward, kBackwardTolerance) << fixture.name << " backward";
}

TEST(NnGolden, Conv2d) {
    const auto fixtures = loadFixtures("conv2d");
    ASSERT_GE(fixtures.size(), 8u);
    for (const Fixture& x : fixtures) {
        const auto& c = x.config;
        Conv2dDesc d;
        d.batch = c["batch"], d.inChannels = c["in_channels"], d.outChannels = c["out_channels"];
        d.inHeight = c["height"], d.inWidth = c["width"];
        d.kernelHeight = c["kernel"][0], d.kernelWidth = c["kernel"][1];
        d.strideH = d.strideW = c["stride"];
        d.padTop = c["pad"][0], d.padBottom = c["pad"][1], d.padLeft = c["pad"][2], d.padRight = c["pad"][3];
        d.dilationH = d.dilationW = c["dilation"];
        d.bias = c["bias"];
        const auto input = x.f("input"), weight = x.f("weight"), dout = x.f("dout");
        const auto bias = d.bias ? x.f("bias") : std::vector<float>();
        std::vector<float> out(size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth()));
        conv2dForward(out.data(), input.data(), weight.data(), d.bias ? bias.data() : nullptr, d);
        std::vector<float> dinput(input.size()), dweight(weight.size()), dbias(bias.size());
        conv2dBackward(dinput.data(), dweight.data(), d.bias ? dbias.data() : nullptr, dout.data(),
                       input.data(), weight.data(), d);
        double backward =
            std::max(relativeError(dinput, x.d("dinput")), relativeError(dweight, x.d("dweight")));
        if (d.bias) backward = std::max(backward, relativeError(dbias, x.d("dbias")));
        report(x, relativeError(out, x.d("output")), backward);
    }
}

TEST(NnGolden, ConvTranspose2d) {
    const auto fixtures = loadFixtures("conv_transpose2d");
    ASSERT_GE(fixtures.size(), 6u);
    for (const Fixture& x : fixtures) {
        const auto& c = x.config;
        ConvTranspose2dDesc d;
        d.batch = c["batch"], d.inChannels = c["in_channels"], d.outChannels = c["out_channels"];
        d.inHeight = c["height"], d.inWidth = c["width"];
        d.kernelHeight = d.kernelWidth = c["kernel"];
        d.strideH = d.strideW = c["stride"];
        d.padH = d.padW = c["pad"];
        d.outputPaddingH = d.outputPaddingW = c["output_padding"];
        d.dilationH = d.dilationW = c["dilation"];
        d.bias = c["bias"];
        const auto input = x.f("input"), weight = x.f("weight"), dout = x.f("dout");
        const auto bias = d.bias ? x.f("bias") : std::vector<float>();
        std::vector<float> out(size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth()));
        convTranspose2dForward(out.data(), input.data(), weight.data(), d.bias ? bias.data() : nullptr, d);
        std::vector<float> dinput(input.size()), dweight(weight.size()), dbias(bias.size());
        convTranspose2dBackward(dinput.data(), dweight.data(), d.bias ? dbias.data() : nullptr, dout.data(),
                                input.data(), weight.data(), d);
        double backward =
            std::max(relativeError(dinput, x.d("dinput")), relativeError(dweight, x.d("dweight")));
        if (d.bias) backward = std::max(backward, relativeError(dbias, x.d("dbias")));
        report(x, relativeError(out, x.d("output")), backward);
    }
}

TEST(NnGolden, MaxPool2d) {
    const auto fixtures = loadFixtures("maxpool2d");
    ASSERT_GE(fixtures.size(), 4u);
    for (const Fixture& x : fixtures) {
        const auto& c = x.config;
        MaxPool2dDesc d;
        d.batch = c["batch"], d.channels = c["channels"], d.inHeight = c["height"], d.inWidth = c["width"];
        d.kernel = c["kernel"], d.stride = c["stride"], d.padding = c["pad"];
        const auto input = x.f("input"), dout = x.f("dout");
        const size_t outCount = size_t(d.batch * d.channels * d.outHeight() * d.outWidth());
        std::vector<float> out(outCount), dinput(input.size());
        std::vector<int32_t> argmax(outCount);
        maxPool2dForward(out.data(), argmax.data(), input.data(), d);
        maxPool2dBackward(dinput.data(), dout.data(), argmax.data(), d);
        report(x, relativeError(out, x.d("output")), relativeError(dinput, x.d("dinput")));
    }
}

TEST(NnGolden, Activations) {
    const auto fixtures = loadFixtures("activation");
    ASSERT_EQ(fixtures.size(), 4u);
    for (const Fixture& x : fixtures) {
        const auto& c = x.config;
        ActivationDesc d;
        d.kind = parseActivation(c["kind"]);
        if (c.contains("slope")) d.slope = c["slope"];
        if (c.contains("low")) d.low = c["low"], d.high = c["high"];
        const auto input = x.f("input"), dout = x.f("dout");
        std::vector<float> out(input.size()), dinput(input.size());
        activationForward(out.data(), input.data(), int64_t(input.size()), d);
        activationBackward(dinput.data(), dout.data(), input.data(), out.data(), int64_t(input.size()), d);
        report(x, relativeError(out, x.d("output")), relativeError(dinput, x.d("dinput")));
    }
}

TEST(NnGolden, Resampling) {
    int count = 0;
    for (const char* layer : {"nearest", "bilinear", "pixel_shuffle"}) {
        for (const Fixture& x : loadFixtures(layer)) {
            ++count;
            const auto& c = x.config;
            ResampleDesc d;
            d.batch = c["batch"], d.channels = c["channels"], d.inHeight = c["height"],
            d.inWidth = c["width"];
            d.factor = c["factor"];
            const auto input = x.f("input"), dout = x.f("dout");
            std::vector<float> out(input.size() *
                                   (std::string(layer) == "pixel_shuffle" ? 1 : d.factor * d.factor));
            std::vector<float> dinput(input.size());
            if (std::string(layer) == "nearest") {
                upsampleNearestForward(out.data(), input.data(), d);
                upsampleNearestBackward(dinput.data(), dout.data(), d);
            } else if (std::string(layer) == "bilinear") {
                upsampleBilinearForward(out.data(), input.data(), d);
                upsampleBilinearBackward(dinput.data(), dout.data(), d);
            } else {
                pixelShuffleForward(out.data(), input.data(), d);
                pixelShuffleBackward(dinput.data(), dout.data(), d);
            }
            report(x, relativeError(out, x.d("output")), relativeError(dinput, x.d("dinput")));
        }
    }
    EXPECT_EQ(count, 4);
}

TEST(NnGolden, KernelFilter) {
    const auto fixtures = loadFixtures("kernel_filter");
    ASSERT_EQ(fixtures.size(), 4u);
    for (const Fixture& x : fixtures) {
        const auto& c = x.config;
        KernelFilterDesc d;
        d.batch = c["batch"], d.channels = c["channels"], d.height = c["height"], d.width = c["width"];
        d.kernel = c["kernel"], d.centreBias = c["centre_bias"];
        const auto input = x.f("input"), logits = x.f("logits"), dout = x.f("dout");
        std::vector<float> out(input.size()), dinput(input.size()), dlogits(logits.size());
        kernelFilterForward(out.data(), input.data(), logits.data(), d);
        kernelFilterBackward(dinput.data(), dlogits.data(), dout.data(), input.data(), logits.data(), d);
        report(x, relativeError(out, x.d("output")),
               std::max(relativeError(dinput, x.d("dinput")), relativeError(dlogits, x.d("dlogits"))));
    }
}

TEST(NnGolden, Losses) {
    const auto fixtures = loadFixtures("loss");
    ASSERT_EQ(fixtures.size(), 5u);
    for (const Fixture& x : fixtures) {
        const auto& c = x.config;
        const auto pred = x.f("pred"), target = x.f("target");
        SsimLossDesc d;
        d.batch = c["shape"][0], d.channels = c["shape"][1], d.height = c["shape"][2],
        d.width = c["shape"][3];
        d.dataRange = c["data_range"];
        const int64_t n = int64_t(pred.size());
        std::vector<float> dpred(pred.size());
        double value = 0.0;
        if (c["kind"] == "ssim") {
            value = ssimLoss(pred.data(), target.data(), d);
            ssimLossBackward(dpred.data(), pred.data(), target.data(), d, 1.0);
        } else if (c["kind"] == "l1") {
            value = l1Loss(pred.data(), target.data(), n);
            l1LossBackward(dpred.data(), pred.data(), target.data(), n, 1.0);
        } else {
            value = mseLoss(pred.data(), target.data(), n);
            mseLossBackward(dpred.data(), pred.data(), target.data(), n, 1.0);
        }
        const double want = x.d("loss")[0];
        report(x, std::abs(value - want) / std::max(1e-12, std::abs(want)),
               relativeError(dpred, x.d("dpred")));
    }
}

TEST(NnGolden, Optimizers) {
    const auto fixtures = loadFixtures("optimizer");
    ASSERT_EQ(fixtures.size(), 5u);
    for (const Fixture& x : fixtures) {
        const auto& c = x.config;
        OptimizerConfig config;
        config.kind = OptimizerConfig::parseKind(c["kind"]);
        if (c.contains("momentum")) config.momentum = c["momentum"];
        if (c.contains("weight_decay"))
            config.weightDecay = c["weight_decay"];
        else
            config.weightDecay =
                config.kind == OptimizerConfig::Kind::AdamW ? 0.01 : 0.0;  // PyTorch defaults
        if (c.contains("betas")) config.beta1 = c["betas"][0], config.beta2 = c["betas"][1];
        if (c.contains("eps")) config.epsilon = c["eps"];
        auto params = x.f("params");
        Optimizer optimizer(config, int64_t(params.size()));
        double worst = 0.0;
        for (int step = 0; step < int(c["steps"]); ++step) {
            const auto grads = x.f("grad" + std::to_string(step));
            optimizer.step(params.data(), grads.data(), c["lrs"][step].get<double>());
            worst = std::max(worst, relativeError(params, x.d("after" + std::to_string(step))));
        }
        report(x, worst, 0.0);
    }
}

}  // namespace
}  // namespace dejag::nn

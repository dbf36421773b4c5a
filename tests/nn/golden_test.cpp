// dejag's losses and optimizers against PyTorch on the committed fixtures of
// tests/golden/make_nn_golden.py. Forward relative error <= 1e-5, backward <= 1e-4, where the relative
// error is max |dejag - torch| / max |torch| over the tensor (torch computed in float64). The layers'
// fixtures are cases of the op harness (tests/nn/ops_test.cpp).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <nlohmann/json.hpp>

#include "nn/losses.h"
#include "nn/optim.h"
#include "nn/safetensors.h"
#include "tests/nn/relative_error.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

constexpr double kForwardTolerance = 1e-5, kBackwardTolerance = 1e-4;

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

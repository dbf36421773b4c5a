// The inference plan (blocked layout, fast kernels, one arena) against the reference Model::forward, on
// every SIMD path; no allocation per run.
#include "nn/inference.h"

#include <gtest/gtest.h>

#include <cmath>

#include "base/error.h"
#include "base/random.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/init.h"
#include "tests/alloc_counter.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

Tensor randomTensor(const Shape& shape, uint64_t seed) {
    Tensor t(shape);
    Rng rng(seed);
    for (int64_t i = 0; i < t.numel(); ++i) t.data()[i] = rng.uniform(0.0f, 1.0f);
    return t;
}

// Every op, with strides, paddings, a skip connection and unfused activations.
nlohmann::json everyOpArchitecture() {
    using nlohmann::json;
    json nodes = json::array();
    nodes.push_back({{"name", "a"},
                     {"op", "conv2d"},
                     {"inputs", {"input"}},
                     {"out_channels", 20},
                     {"kernel", 3},
                     {"padding", "same"},
                     {"activation", "leaky_relu"},
                     {"slope", 0.1}});
    nodes.push_back({{"name", "down"},
                     {"op", "conv2d"},
                     {"inputs", {"a"}},
                     {"out_channels", 18},
                     {"kernel", 3},
                     {"stride", 2},
                     {"padding", "same"},
                     {"activation", "relu"}});
    nodes.push_back({{"name", "pool"}, {"op", "maxpool2d"}, {"inputs", {"a"}}, {"kernel", 2}});
    nodes.push_back({{"name", "cat"}, {"op", "concat"}, {"inputs", {"down", "pool"}}});
    nodes.push_back({{"name", "v"},
                     {"op", "conv2d"},
                     {"inputs", {"cat"}},
                     {"out_channels", 12},
                     {"kernel", 5},
                     {"padding", 2},
                     {"activation", "clamp"},
                     {"low", -0.2},
                     {"high", 0.8}});
    nodes.push_back({{"name", "up"},
                     {"op", "conv_transpose2d"},
                     {"inputs", {"v"}},
                     {"out_channels", 20},
                     {"kernel", 3},
                     {"stride", 2},
                     {"padding", 1},
                     {"output_padding", 1}});
    nodes.push_back({{"name", "skip"}, {"op", "add"}, {"inputs", {"up", "a"}}});
    nodes.push_back({{"name", "near"}, {"op", "upsample"}, {"inputs", {"v"}}, {"mode", "nearest"}});
    nodes.push_back({{"name", "bil"}, {"op", "upsample"}, {"inputs", {"v"}}, {"mode", "bilinear"}});
    nodes.push_back(
        {{"name", "sub"}, {"op", "conv2d"}, {"inputs", {"v"}}, {"out_channels", 8}, {"kernel", 1}});
    nodes.push_back({{"name", "shuf"}, {"op", "pixel_shuffle"}, {"inputs", {"sub"}}});
    nodes.push_back(
        {{"name", "taps"}, {"op", "conv2d"}, {"inputs", {"v"}}, {"out_channels", 9}, {"kernel", 1}});
    nodes.push_back(
        {{"name", "kf"}, {"op", "kernel_filter"}, {"inputs", {"v", "taps"}}, {"centre_bias", 1.5}});
    nodes.push_back({{"name", "kfup"}, {"op", "upsample"}, {"inputs", {"kf"}}, {"mode", "nearest"}});
    nodes.push_back({{"name", "all"}, {"op", "concat"}, {"inputs", {"skip", "near", "bil", "shuf", "kfup"}}});
    nodes.push_back({{"name", "out"},
                     {"op", "conv2d"},
                     {"inputs", {"all"}},
                     {"out_channels", 3},
                     {"kernel", 3},
                     {"padding", "same"},
                     {"activation", "sigmoid"}});
    return {{"name", "every_op"}, {"input_channels", 3}, {"nodes", nodes}};
}

class Inference : public testing::SimdLevelTest {};

void expectPlanMatchesReference(Model& model, const Shape& shape) {
    model.initialize(11);
    // Biases start at zero; non-zero ones check that every fused path adds them.
    uint64_t state = 13;
    for (const ParameterInfo& p : model.parameters())
        if (p.isBias)
            for (int64_t i = p.offset; i < p.offset + shapeNumel(p.shape); ++i)
                model.parameterData()[i] = float(unitInterval(state = splitMix64(state), -0.5, 0.5));
    const Tensor input = randomTensor(shape, 12);
    const Tensor want = model.forward(input).clone();
    InferencePlan plan(model, shape);
    const Tensor& got = plan.run(input);
    ASSERT_EQ(got.shape(), want.shape());
    double worst = 0.0, scale = 1e-6;
    for (int64_t i = 0; i < want.numel(); ++i) {
        worst = std::max(worst, double(std::abs(got.data()[i] - want.data()[i])));
        scale = std::max(scale, double(std::abs(want.data()[i])));
    }
    EXPECT_LE(worst / scale, 1e-5) << model.name();
}

TEST_P(Inference, Seed2020MatchesTheReference) {
    Model model = Model::builtin("seed2020");
    expectPlanMatchesReference(model, {2, 1, 32, 28});
}

TEST_P(Inference, FastFamilyMatchesTheReference) {
    Model model = Model::builtin("fast");
    expectPlanMatchesReference(model, {1, 3, 40, 32});
}

TEST_P(Inference, KpnFamilyMatchesTheReference) {
    Model model = Model::builtin("kpn");
    expectPlanMatchesReference(model, {1, 3, 40, 32});
    Model narrow = Model::builtin("kpn", {8, 2, 3});
    expectPlanMatchesReference(narrow, {2, 3, 20, 28});
    expectPlanMatchesReference(narrow, {1, 3, 4, 8});  // narrower than a vector: the edge path only
    // The output stage with a 5x5 kernel, a factor of 3 and a width that is no multiple of a vector.
    using nlohmann::json;
    const json nodes =
        json::array({{{"name", "down"},
                      {"op", "conv2d"},
                      {"inputs", {"input"}},
                      {"out_channels", 8},
                      {"kernel", 3},
                      {"stride", 3},
                      {"padding", "same"},
                      {"activation", "relu"}},
                     {{"name", "taps"},
                      {"op", "conv2d"},
                      {"inputs", {"down"}},
                      {"out_channels", 9 * 25},
                      {"kernel", 1},
                      {"init_scale", 8.0}},
                     {{"name", "shuffle"}, {"op", "pixel_shuffle"}, {"inputs", {"taps"}}, {"factor", 3}},
                     {{"name", "filter"},
                      {"op", "kernel_filter"},
                      {"inputs", {"input", "shuffle"}},
                      {"kernel", 5},
                      {"centre_bias", -1.0}}});
    Model wide = Model::fromArchitecture({{"name", "k5"}, {"input_channels", 2}, {"nodes", nodes}});
    expectPlanMatchesReference(wide, {2, 2, 21, 39});
}

TEST_P(Inference, EveryOpMatchesTheReference) {
    Model model = Model::fromArchitecture(everyOpArchitecture());
    expectPlanMatchesReference(model, {2, 3, 20, 24});
}

INSTANTIATE_TEST_SUITE_P(SimdLevels, Inference, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);

TEST(InferencePlanning, NoAllocationPerRunAfterWarmUp) {
    Model model = Model::builtin("seed2020");
    model.initialize(3);
    const Tensor input = randomTensor({1, 1, 64, 48}, 4);
    InferencePlan plan(model, input.shape());
    plan.run(input);
    plan.run(input);
    const int64_t before = testing::allocationCount();
    for (int i = 0; i < 3; ++i) plan.run(input);
    EXPECT_EQ(testing::allocationCount() - before, 0) << "heap allocations during 3 runs";
}

TEST(InferencePlanning, ArenaReusesMemoryAndThreadsDoNotChangeResults) {
    Model model = Model::builtin("seed2020");
    model.initialize(5);
    const Tensor input = randomTensor({1, 1, 64, 64}, 6);
    setThreadCount(1);
    InferencePlan plan(model, input.shape());
    EXPECT_LT(plan.arenaBytes(), plan.unpackedBytes() * 3 / 4);
    const Tensor one = plan.run(input).clone();
    setThreadCount(2);
    const Tensor& two = plan.run(input);
    setThreadCount(0);
    for (int64_t i = 0; i < one.numel(); ++i) ASSERT_EQ(one.data()[i], two.data()[i]);
    EXPECT_EQ(plan.macs(), model.macs(input.shape()));
}

TEST(InferencePlanning, BadInputsAreClearErrors) {
    Model model = Model::builtin("fast");
    model.initialize(1);
    EXPECT_THROW(InferencePlan(model, {1, 3, 20, 16}), Error);  // not a multiple of 8: the levels differ
    InferencePlan plan(model, {1, 3, 16, 16});
    EXPECT_THROW(plan.run(Tensor({1, 3, 16, 18})), Error);
    Tensor nan({1, 3, 16, 16});
    nan.data()[7] = std::nanf("");
    EXPECT_THROW(plan.run(nan), Error);
}

}  // namespace
}  // namespace dejag::nn

// Tensor, safetensors, RNG, schedules, clipping, loss parsing and the losses on degenerate inputs.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "base/error.h"
#include "nn/init.h"
#include "nn/losses.h"
#include "nn/optim.h"
#include "nn/safetensors.h"
#include "nn/tensor.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

TEST(Tensor, AlignedZeroedAndShapeChecked) {
    Tensor t({2, 3, 5, 7});
    EXPECT_EQ(t.numel(), 210);
    EXPECT_EQ(reinterpret_cast<uintptr_t>(t.data()) % 64, 0u);
    for (int64_t i = 0; i < t.numel(); ++i) ASSERT_EQ(t.data()[i], 0.0f);
    t.at(1, 2, 4, 6) = 3.0f;
    EXPECT_EQ(t.data()[209], 3.0f);
    EXPECT_EQ(t.dim(-1), 7);
    EXPECT_THROW(t.dim(4), Error);
    EXPECT_THROW(t.requireShape({2, 3, 5, 6}, "x"), Error);
    EXPECT_NO_THROW(t.requireShape({2, 3, 5, 7}, "x"));
    EXPECT_THROW(Tensor({2, -1}), Error);
    EXPECT_THROW(Tensor({int64_t(1) << 40, int64_t(1) << 40}), Error);
    Tensor c = t.clone();
    EXPECT_EQ(c.at(1, 2, 4, 6), 3.0f);
    EXPECT_NE(c.data(), t.data());
    EXPECT_EQ(t.findNonFinite(), -1);
    t.data()[11] = std::numeric_limits<float>::infinity();
    EXPECT_EQ(t.findNonFinite(), 11);
}

std::string withHeader(const std::string& json, const std::string& data = "") {
    std::string bytes(8, '\0');
    uint64_t n = json.size();
    for (int i = 0; i < 8; ++i) bytes[size_t(i)] = char((n >> (8 * i)) & 0xff);
    return bytes + json + data;
}

TEST(Safetensors, RoundTripAndMetadata) {
    testing::TempDir dir;
    const float a[6] = {1, 2, 3, 4, 5, 6}, b[1] = {-7};
    writeSafetensors(dir.file("t.safetensors"), {{"a", {2, 3}, a}, {"b.bias", {1}, b}}, {{"k", "v"}});
    const SafetensorsFile file = readSafetensors(dir.file("t.safetensors"));
    EXPECT_EQ(file.metadata.at("k"), "v");
    EXPECT_EQ(file.at("a").shape, (Shape{2, 3}));
    EXPECT_EQ(file.at("a").f32, std::vector<float>(a, a + 6));
    EXPECT_EQ(file.at("b.bias").f32[0], -7.0f);
    EXPECT_THROW(file.at("c"), Error);
}

TEST(Safetensors, EveryMalformedHeaderIsAClearError) {
    const std::string eight(8, 'x');
    const std::vector<std::string> bad = {
        "",                                                                               // empty
        "abc",                                                                            // shorter than 8
        withHeader("{}").substr(0, 9),                                                    // header cut
        withHeader("[1,2]"),                                                              // not an object
        withHeader("{not json"),                                                          // not JSON
        withHeader(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})"),          // data missing
        withHeader(R"({"a":{"dtype":"F32","shape":[3],"data_offsets":[0,8]}})", eight),   // size mismatch
        withHeader(R"({"a":{"dtype":"I8","shape":[8],"data_offsets":[0,8]}})", eight),    // dtype
        withHeader(R"({"a":{"dtype":"F32","shape":[-2],"data_offsets":[0,8]}})", eight),  // negative dim
        withHeader(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[8,0]}})", eight),   // reversed
        withHeader(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]},)"
                   R"("b":{"dtype":"F32","shape":[1],"data_offsets":[4,8]}})",
                   eight),                                          // overlap
        withHeader(R"({"a":{"dtype":"F32","shape":[2]}})", eight),  // no offsets
        withHeader(R"({"__metadata__":{"k":3}})"),                  // metadata type
        withHeader(R"({"a":{"dtype":"F32","shape":[4294967296,4294967296],"data_offsets":[0,8]}})", eight),
    };
    for (size_t i = 0; i < bad.size(); ++i) {
        std::string bytes = bad[i];
        if (i == 2) {  // claims a longer header than the file has
            bytes = withHeader("{}");
            bytes[0] = 100;
        }
        EXPECT_THROW(parseSafetensors(bytes, "case" + std::to_string(i)), Error) << "case " << i;
    }
    EXPECT_NO_THROW(parseSafetensors(
        withHeader(R"({"a":{"dtype":"F32","shape":[2],"data_offsets":[0,8]}})", eight), "ok"));
}

TEST(Rng, IsDeterministicAndWellSpread) {
    Rng a(123), b(123);
    for (int i = 0; i < 100; ++i) ASSERT_EQ(a.next(), b.next());
    Rng d(5);
    double sum = 0, squares = 0;
    for (int i = 0; i < 100000; ++i) {
        const double v = d.normal();
        sum += v;
        squares += v * v;
    }
    EXPECT_NEAR(sum / 100000, 0.0, 0.02);
    EXPECT_NEAR(squares / 100000, 1.0, 0.02);
    Rng e(6);
    for (int i = 0; i < 1000; ++i) {
        const float u = e.uniform();
        ASSERT_GE(u, 0.0f);
        ASSERT_LT(u, 1.0f);
        ASSERT_LT(e.below(7), 7u);
    }
    // Different seeds give different streams.
    Rng f(1), g(2);
    int same = 0;
    for (int i = 0; i < 64; ++i) same += f.next() == g.next();
    EXPECT_LT(same, 2);
}

TEST(Initialisation, HeAndGlorotHaveTheirVariance) {
    std::vector<float> w(200000);
    Rng rng(9);
    heNormal(w.data(), int64_t(w.size()), 50, rng);
    double squares = 0;
    for (float v : w) squares += double(v) * v;
    EXPECT_NEAR(squares / double(w.size()), 2.0 / 50.0, 0.002);
    glorotUniform(w.data(), int64_t(w.size()), 30, 70, rng);
    const float limit = std::sqrt(6.0f / 100.0f);
    for (float v : w) ASSERT_LE(std::abs(v), limit);
}

TEST(Schedules, StepCosineAndWarmup) {
    LrSchedule s;
    s.baseRate = 1.0;
    EXPECT_EQ(s.rateAt(12345), 1.0);
    s.kind = LrSchedule::Kind::Step;
    s.stepEvery = 10, s.gamma = 0.5;
    EXPECT_EQ(s.rateAt(9), 1.0);
    EXPECT_EQ(s.rateAt(10), 0.5);
    EXPECT_EQ(s.rateAt(25), 0.25);
    s.kind = LrSchedule::Kind::Cosine;
    s.totalSteps = 100, s.minRate = 0.1;
    EXPECT_NEAR(s.rateAt(0), 1.0, 1e-12);
    EXPECT_NEAR(s.rateAt(50), 0.55, 1e-12);
    EXPECT_NEAR(s.rateAt(100), 0.1, 1e-12);
    EXPECT_NEAR(s.rateAt(1000), 0.1, 1e-12);
    s.warmupSteps = 4;
    EXPECT_NEAR(s.rateAt(0), 0.25, 1e-6);
    EXPECT_NEAR(s.rateAt(3), s.minRate + 0.5 * 0.9 * (1 + std::cos(M_PI * 0.03)), 1e-9);
}

TEST(Clipping, GlobalNormIsBounded) {
    std::vector<float> g = {3, 4, 0, 0};
    EXPECT_NEAR(clipGradientNorm(g.data(), 4, 1.0), 5.0, 1e-9);
    EXPECT_NEAR(gradientNorm(g.data(), 4), 1.0, 1e-5);
    std::vector<float> small = {0.1f, 0.1f};
    clipGradientNorm(small.data(), 2, 1.0);
    EXPECT_EQ(small[0], 0.1f);  // under the limit: untouched
}

TEST(Losses, CompositeSpecsParseAndBadOnesAreErrors) {
    const CompositeLoss loss = CompositeLoss::parse("0.84*ssim+0.16*l1");
    ASSERT_EQ(loss.terms.size(), 2u);
    EXPECT_EQ(loss.terms[0].kind, LossKind::Ssim);
    EXPECT_DOUBLE_EQ(loss.terms[1].weight, 0.16);
    EXPECT_EQ(CompositeLoss::parse("mse").terms[0].kind, LossKind::Mse);
    for (const char* bad : {"", "ssim+", "huber", "-1*l1", "x*l1", "0*ssim"})
        EXPECT_THROW(CompositeLoss::parse(bad), Error) << bad;
}

TEST(Losses, SsimLossIsStableOnDegenerateInputs) {
    const SsimLossDesc d{1, 1, 16, 16, 1.0};
    std::vector<float> a(256, 0.5f), b(256, 0.5f), g(256, 0.0f);
    // Identical constant images: no variance at all; loss 0, gradient 0.
    EXPECT_NEAR(ssimLoss(a.data(), b.data(), d), 0.0, 1e-12);
    ssimLossBackward(g.data(), a.data(), b.data(), d, 1.0);
    for (float v : g) ASSERT_NEAR(v, 0.0f, 1e-9f);
    // Different constants, a single bright pixel, huge and tiny values: finite loss and gradient.
    std::vector<std::pair<std::vector<float>, std::vector<float>>> cases;
    cases.push_back({std::vector<float>(256, 0.2f), std::vector<float>(256, 0.9f)});
    std::vector<float> spike(256, 0.0f);
    spike[120] = 1.0f;
    cases.push_back({spike, std::vector<float>(256, 0.0f)});
    std::vector<float> huge(256), tiny(256), checker(256);
    for (int i = 0; i < 256; ++i) {
        huge[size_t(i)] = 1e6f * float(i % 7);
        tiny[size_t(i)] = 1e-30f * float(i % 5);
        checker[size_t(i)] = float(((i % 16) + (i / 16)) % 2);
    }
    cases.push_back({huge, std::vector<float>(256, 1e6f)});
    cases.push_back({tiny, std::vector<float>(256, 0.0f)});
    cases.push_back({checker, std::vector<float>(256, 0.5f)});
    for (size_t k = 0; k < cases.size(); ++k) {
        const auto& [pred, target] = cases[k];
        const double loss = ssimLoss(pred.data(), target.data(), d);
        EXPECT_TRUE(std::isfinite(loss)) << "case " << k;
        EXPECT_GE(loss, 0.0) << "case " << k;
        EXPECT_LE(loss, 2.0) << "case " << k;
        std::vector<float> grad(256, 0.0f);
        ssimLossBackward(grad.data(), pred.data(), target.data(), d, 1.0);
        for (float v : grad) ASSERT_TRUE(std::isfinite(v)) << "case " << k;
    }
    EXPECT_THROW(ssimLoss(a.data(), b.data(), SsimLossDesc{1, 1, 10, 16, 1.0}),
                 Error);  // smaller than the window
}

}  // namespace
}  // namespace dejag::nn

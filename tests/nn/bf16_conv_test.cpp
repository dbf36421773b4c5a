// The fast convolution with bf16 activations (AVX-512 BF16, nn/fast_conv.h) against the reference kernel
// run on the same values rounded to bf16: inputs and weights rounded, sums in float. A bf16 output is the
// float result rounded once more. On a CPU without AVX-512 BF16, the check is that bf16 is refused.
#include "nn/fast_conv.h"

#include <gtest/gtest.h>

#include <cmath>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/init.h"
#include "nn/layers.h"
#include "tests/nn/blocked_test_util.h"

namespace dejag::nn {
namespace {

std::vector<float> randomValues(size_t n, Rng& rng, float scale = 1.0f) {
    std::vector<float> v(n);
    for (float& x : v) x = rng.uniform(-scale, scale);
    return v;
}

std::vector<float> roundedToBf16(std::vector<float> v) {
    for (float& x : v) x = fromBf16(toBf16(x));
    return v;
}

// Runs `conv` on a plain input (converted to the blocked layout, as bf16 elements when inBf16) and
// returns its plain output (read back from bf16 elements when outBf16). Checks that the output border
// stays zero, as the next layer needs.
std::vector<float> runBlocked(const BlockedConv& conv, const std::vector<float>& input, int64_t outCount,
                              bool inBf16, bool outBf16) {
    const int border = conv.requiredInputBorder() + 1;
    const BlockedShape inShape = conv.inputShape(border), outShape = conv.outputShape(border);
    Tensor in = allocateBlocked(inShape), out = allocateBlocked(outShape);
    toBlocked(in.data(), input.data(), inShape);
    std::vector<uint16_t> inBits;
    if (inBf16) {
        inBits.resize(size_t(inShape.floatCount()));
        for (size_t i = 0; i < inBits.size(); ++i) inBits[i] = toBf16(in.data()[i]);
    }
    // A bf16 output fills the first half of the float tensor's bytes; fill all of them with a pattern so
    // a missed store shows.
    std::fill(out.data(), out.data() + out.numel(), 0.0f);
    conv.forward(out.data(), outShape, inBf16 ? reinterpret_cast<const float*>(inBits.data()) : in.data(),
                 inShape, inBf16, outBf16);
    Tensor outFloat = allocateBlocked(outShape);
    const uint16_t* outBits = reinterpret_cast<const uint16_t*>(out.data());
    for (int64_t i = 0; i < outShape.floatCount(); ++i)
        outFloat.data()[i] = outBf16 ? fromBf16(outBits[i]) : out.data()[i];
    testing::expectZeroBorder(outFloat.data(), outShape);
    std::vector<float> plain(static_cast<size_t>(outCount));
    fromBlocked(plain.data(), outFloat.data(), outShape);
    return plain;
}

// Float sums of the same bf16 products: the float tolerance of the other fast-conv tests. A bf16 output
// adds one rounding: half a bf16 unit (2^-9 relative) of each value.
void expectClose(const std::vector<float>& got, const std::vector<float>& want, bool outBf16) {
    ASSERT_EQ(got.size(), want.size());
    double scale = 1e-6;
    for (float w : want) scale = std::max(scale, double(std::abs(w)));
    double worst = 0.0;
    size_t worstIndex = 0;
    for (size_t i = 0; i < want.size(); ++i) {
        const double allowed = 1e-5 * scale + (outBf16 ? std::ldexp(std::abs(double(want[i])), -8) : 0.0);
        const double excess = std::abs(double(got[i]) - double(want[i])) / allowed;
        if (excess > worst) worst = excess, worstIndex = i;
    }
    EXPECT_LE(worst, 1.0) << "element " << worstIndex << ": got " << got[worstIndex] << ", want "
                          << want[worstIndex];
}

struct Case {
    Conv2dDesc desc;
    ActivationDesc activation;
    bool pooled = false;
    int inputBlock = 0;
};

// The reference on rounded values: conv (and pooling) of bf16(input) with bf16(weights), float bias.
std::vector<float> reference(const Case& c, const std::vector<float>& input, const std::vector<float>& weight,
                             const std::vector<float>& bias, bool inBf16) {
    const Conv2dDesc& d = c.desc;
    const std::vector<float> in = inBf16 ? roundedToBf16(input) : input;
    const std::vector<float> w = inBf16 ? roundedToBf16(weight) : weight;
    std::vector<float> out(size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth()));
    conv2dForward(out.data(), in.data(), w.data(), d.bias ? bias.data() : nullptr, d);
    activationForward(out.data(), out.data(), int64_t(out.size()), c.activation);
    if (!c.pooled) return out;
    MaxPool2dDesc pool;
    pool.batch = d.batch, pool.channels = d.outChannels, pool.inHeight = d.outHeight(),
    pool.inWidth = d.outWidth();
    std::vector<float> pooled(size_t(d.batch * d.outChannels * pool.outHeight() * pool.outWidth()));
    std::vector<int32_t> argmax(pooled.size());
    maxPool2dForward(pooled.data(), argmax.data(), out.data(), pool);
    return pooled;
}

// On a CPU without AVX-512 BF16 (or with a lower SIMD level forced) the plan never asks for bf16; there
// the check is that asking is refused. Returns whether the bf16 kernels can run.
bool bf16KernelsOrTheirRefusal() {
    if (bf16Available()) return true;
    Conv2dDesc d;
    d.inChannels = 16, d.outChannels = 16, d.inHeight = 4, d.inWidth = 4;
    const std::vector<float> weight(size_t(d.weightCount()), 0.1f), bias(16, 0.0f);
    BlockedConv conv(d, weight.data(), bias.data(), ActivationDesc{});
    EXPECT_THROW(conv.useBf16Input(), Error);
    return false;
}

TEST(Bf16Conv, EveryInputAndOutputTypeMatchesTheReferenceOnRoundedValues) {
    if (!bf16KernelsOrTheirRefusal()) return;
    Rng rng(91);
    const Activation kinds[] = {Activation::None, Activation::ReLU, Activation::LeakyReLU, Activation::Clamp};
    for (int trial = 0; trial < 48; ++trial) {
        Case c;
        Conv2dDesc& d = c.desc;
        d.batch = 1 + rng.below(2);
        // Channel counts around the block: partial blocks, odd counts (a pair's second half is padding).
        d.inChannels = 1 + rng.below(trial < 8 ? 3 : 40);
        d.outChannels = 5 + rng.below(36);
        const int k = int(1 + 2 * rng.below(3));
        d.kernelHeight = d.kernelWidth = k;
        d.padTop = d.padBottom = d.padLeft = d.padRight = k / 2;
        if (trial % 3 == 1) {  // strides and dilations
            d.strideH = int(1 + rng.below(2)), d.strideW = int(1 + rng.below(2));
            d.dilationH = int(1 + rng.below(2)), d.dilationW = d.dilationH;
            d.padTop = int(rng.below(3)), d.padLeft = int(rng.below(3));
        }
        d.inHeight = d.dilationH * (k - 1) + 2 + rng.below(19);
        d.inWidth = d.dilationW * (k - 1) + 2 + rng.below(41);
        d.bias = rng.below(4) != 0;
        c.activation.kind = kinds[trial % 4];
        c.pooled = trial % 3 == 2 && d.outHeight() >= 2 && d.outWidth() >= 2;
        c.inputBlock = d.inChannels <= 16 && trial % 2 == 1 ? 1 : 0;
        SCOPED_TRACE("trial " + std::to_string(trial) + ": " + std::to_string(d.inChannels) + "->" +
                     std::to_string(d.outChannels) + " k" + std::to_string(k) + " s" +
                     std::to_string(d.strideH) + "," + std::to_string(d.strideW) +
                     (c.pooled ? " pooled" : "") + (c.inputBlock == 1 ? " planar" : ""));
        const auto input = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
        const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
        const auto bias = randomValues(size_t(d.outChannels), rng);
        BlockedConv conv(d, weight.data(), bias.data(), c.activation, c.inputBlock);
        if (c.pooled) conv.fuseMaxPool2x2();
        ASSERT_TRUE(conv.canWriteBf16());
        const int64_t outCount =
            d.batch * d.outChannels * conv.outputShape(0).height * conv.outputShape(0).width;
        for (const bool inBf16 : {false, true}) {
            if (inBf16) {
                if (!conv.canReadBf16()) continue;  // a planar input stays float
                conv.useBf16Input();
            }
            const std::vector<float> want = reference(c, input, weight, bias, inBf16);
            for (const bool outBf16 : {false, true}) {
                if (!inBf16 && !outBf16) continue;  // the float kernel: fast_conv_test
                SCOPED_TRACE(std::string(inBf16 ? "bf16" : "float") + " in, " + (outBf16 ? "bf16" : "float") +
                             " out");
                expectClose(runBlocked(conv, input, outCount, inBf16, outBf16), want, outBf16);
            }
        }
    }
}

// The transposed convolution's parity passes and a layer whose output is streamed past the caches.
TEST(Bf16Conv, TransposedAndLargeLayersMatchTheReference) {
    if (!bf16KernelsOrTheirRefusal()) return;
    Rng rng(92);
    for (int trial = 0; trial < 8; ++trial) {
        ConvTranspose2dDesc d;
        d.inChannels = 3 + rng.below(40), d.outChannels = 5 + rng.below(40);
        d.kernelHeight = d.kernelWidth = 3, d.strideH = d.strideW = 2, d.padH = d.padW = 1;
        d.outputPaddingH = d.outputPaddingW = 1;
        d.inHeight = 3 + rng.below(15), d.inWidth = 3 + rng.below(30);
        SCOPED_TRACE("transposed " + std::to_string(d.inChannels) + "->" + std::to_string(d.outChannels));
        const auto input = randomValues(size_t(d.inChannels * d.inHeight * d.inWidth), rng);
        const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
        const auto bias = randomValues(size_t(d.outChannels), rng);
        const ActivationDesc relu{Activation::ReLU};
        std::vector<float> want(size_t(d.outChannels * d.outHeight() * d.outWidth()));
        const auto in = roundedToBf16(input), w = roundedToBf16(weight);
        convTranspose2dForward(want.data(), in.data(), w.data(), bias.data(), d);
        activationForward(want.data(), want.data(), int64_t(want.size()), relu);
        BlockedConv conv(d, weight.data(), bias.data(), relu);
        conv.useBf16Input();
        for (const bool outBf16 : {false, true})
            expectClose(runBlocked(conv, input, int64_t(want.size()), true, outBf16), want, outBf16);
    }
    // 16 -> 32 at 301 x 297: 11.6 MB of float output, 5.8 MB as bf16; and 12 -> 8 at 601 x 597 (half a
    // vector of outputs: two pixels per vector), 23 and 11.5 MB: all streamed past a threshold of 4 MB.
    for (const int outChannels : {32, 8}) {
        Conv2dDesc d;
        d.inChannels = outChannels == 8 ? 12 : 16, d.outChannels = outChannels;
        d.inHeight = outChannels == 8 ? 601 : 301, d.inWidth = outChannels == 8 ? 597 : 297;
        d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
        SCOPED_TRACE(std::to_string(d.inChannels) + " -> " + std::to_string(outChannels));
        Case c{d, ActivationDesc{Activation::ReLU}};
        const auto input = randomValues(size_t(d.inChannels * d.inHeight * d.inWidth), rng);
        const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
        const auto bias = randomValues(size_t(outChannels), rng);
        BlockedConv conv(d, weight.data(), bias.data(), c.activation);
        conv.useBf16Input();
        conv.setStreamedOutputBytes(int64_t(4) << 20);  // bf16 outputs of 5.8 and 11.5 MB streamed too
        const std::vector<float> want = reference(c, input, weight, bias, true);
        for (const bool outBf16 : {false, true})
            expectClose(runBlocked(conv, input, int64_t(want.size()), true, outBf16), want, outBf16);
    }
}

TEST(Bf16Conv, SameResultForEveryThreadCount) {
    if (!bf16KernelsOrTheirRefusal()) return;
    Rng rng(93);
    Conv2dDesc d;
    d.batch = 2, d.inChannels = 19, d.outChannels = 35, d.inHeight = 23, d.inWidth = 37;
    d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
    const auto input = randomValues(size_t(2 * 19 * 23 * 37), rng);
    const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
    const auto bias = randomValues(35, rng);
    BlockedConv conv(d, weight.data(), bias.data(), ActivationDesc{Activation::ReLU});
    conv.useBf16Input();
    const int64_t outCount = 2 * 35 * 23 * 37;
    setThreadCount(1);
    const auto one = runBlocked(conv, input, outCount, true, true);
    setThreadCount(3);
    const auto three = runBlocked(conv, input, outCount, true, true);
    setThreadCount(0);
    EXPECT_EQ(one, three);
}

TEST(Bf16ConvLimits, RefusesWhatItCannotRun) {
    // Rounding: nearest even, NaN kept.
    EXPECT_EQ(toBf16(1.0f), 0x3f80);
    EXPECT_EQ(fromBf16(toBf16(1.0f + std::ldexp(1.0f, -8))), 1.0f);  // a tie rounds to even (down)
    EXPECT_EQ(fromBf16(toBf16(1.0f + 3 * std::ldexp(1.0f, -8))), 1.0f + std::ldexp(1.0f, -6));  // up
    EXPECT_TRUE(std::isnan(fromBf16(toBf16(std::nanf("")))));
    EXPECT_TRUE(std::isinf(fromBf16(toBf16(INFINITY))));
    Conv2dDesc d;
    d.inChannels = 16, d.outChannels = 16, d.inHeight = 8, d.inWidth = 8;
    const std::vector<float> weight(size_t(d.weightCount()), 0.1f), bias(16, 0.0f);
    BlockedConv conv(d, weight.data(), bias.data(), ActivationDesc{});
    Tensor in = allocateBlocked(conv.inputShape(1)), out = allocateBlocked(conv.outputShape(1));
    // A bf16 input before its weights are packed is refused.
    EXPECT_THROW(conv.forward(out.data(), conv.outputShape(1), in.data(), conv.inputShape(1), true, false),
                 Error);
    if (!bf16Available()) {
        EXPECT_THROW(conv.useBf16Input(), Error);
        return;
    }
    // A layer the narrow kernel runs (1-4 outputs) neither reads nor writes bf16.
    Conv2dDesc narrow = d;
    narrow.outChannels = 3;
    BlockedConv three(narrow, weight.data(), bias.data(), ActivationDesc{});
    EXPECT_FALSE(three.canReadBf16());
    EXPECT_FALSE(three.canWriteBf16());
    EXPECT_THROW(three.useBf16Input(), Error);
}

}  // namespace
}  // namespace dejag::nn

// The fast convolution against the reference kernel, on every SIMD path this CPU has: random shapes with
// odd sizes, 1-3 channels and channel counts that are not multiples of the block.
#include "nn/fast_conv.h"

#include "nn/layers.h"

#include <gtest/gtest.h>

#include <cmath>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/init.h"
#include "tests/nn/blocked_test_util.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

class FastConv : public testing::SimdLevelTest {};

std::vector<float> randomValues(size_t n, Rng& rng, float scale = 1.0f) {
    std::vector<float> v(n);
    for (float& x : v) x = rng.uniform(-scale, scale);
    return v;
}

// Runs the fast path on plain tensors (converting to and from the blocked layout).
std::vector<float> runBlocked(const BlockedConv& conv, const std::vector<float>& input, int64_t outCount) {
    const int border = conv.requiredInputBorder() + 1;
    const BlockedShape inShape = conv.inputShape(border), outShape = conv.outputShape(border);
    Tensor in = allocateBlocked(inShape), out = allocateBlocked(outShape);
    toBlocked(in.data(), input.data(), inShape);
    conv.forward(out.data(), outShape, in.data(), inShape);
    testing::expectZeroBorder(out.data(), outShape);
    std::vector<float> plain(static_cast<size_t>(outCount));
    fromBlocked(plain.data(), out.data(), outShape);
    return plain;
}

void expectClose(const std::vector<float>& got, const std::vector<float>& want) {
    ASSERT_EQ(got.size(), want.size());
    double worst = 0.0, scale = 1e-6;
    for (size_t i = 0; i < want.size(); ++i) {
        worst = std::max(worst, double(std::abs(got[i] - want[i])));
        scale = std::max(scale, double(std::abs(want[i])));
    }
    EXPECT_LE(worst / scale, 1e-5);
}

// A convolution's random input, weights and bias (weights ±0.3) and its reference output before any
// activation.
struct RandomConv {
    std::vector<float> input, weight, bias, linear;
    RandomConv(const Conv2dDesc& d, Rng& rng)
        : input(randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng)),
          weight(randomValues(size_t(d.weightCount()), rng, 0.3f)),
          bias(randomValues(size_t(d.outChannels), rng)),
          linear(size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth())) {
        conv2dForward(linear.data(), input.data(), weight.data(), bias.data(), d);
    }
    // The reference output after `activation`.
    std::vector<float> activated(const ActivationDesc& activation) const {
        std::vector<float> out(linear);
        activationForward(out.data(), out.data(), int64_t(out.size()), activation);
        return out;
    }
};

const Activation kActivations[] = {Activation::None, Activation::ReLU, Activation::LeakyReLU,
                                   Activation::Clamp};

TEST_P(FastConv, Conv2dMatchesTheReferenceOnRandomShapes) {
    Rng rng(77);
    for (int trial = 0; trial < 40; ++trial) {
        Conv2dDesc d;
        d.batch = 1 + rng.below(2);
        d.inChannels = 1 + rng.below(trial < 10 ? 3 : 40);
        d.outChannels = 1 + rng.below(trial % 3 == 0 ? 3 : 40);
        const int k = int(1 + 2 * rng.below(3));  // 1, 3, 5
        d.kernelHeight = k;
        d.kernelWidth = trial % 5 == 4 ? int(1 + rng.below(4)) : k;  // some non-square kernels
        if (trial % 2 == 0) {
            d.padTop = d.padBottom = k / 2;
            d.padLeft = d.padRight = int(d.kernelWidth / 2);
        } else {  // strides, dilations, asymmetric padding
            d.strideH = int(1 + rng.below(2)), d.strideW = int(1 + rng.below(3));
            d.dilationH = int(1 + rng.below(2)), d.dilationW = int(1 + rng.below(2));
            d.padTop = int(rng.below(3)), d.padBottom = int(rng.below(3));
            d.padLeft = int(rng.below(3)), d.padRight = int(rng.below(2));
        }
        d.inHeight = d.dilationH * (d.kernelHeight - 1) + 1 + rng.below(19);
        d.inWidth = d.dilationW * (d.kernelWidth - 1) + 1 + rng.below(41);
        d.bias = rng.below(2) == 1;
        const Activation activation = kActivations[trial % 4];
        SCOPED_TRACE("trial " + std::to_string(trial) + ": " + std::to_string(d.inChannels) + "->" +
                     std::to_string(d.outChannels) + " k" + std::to_string(d.kernelHeight) + "x" +
                     std::to_string(d.kernelWidth) + " s" + std::to_string(d.strideH) + "," +
                     std::to_string(d.strideW) + " " + std::to_string(d.inHeight) + "x" +
                     std::to_string(d.inWidth));
        const auto input = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
        const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
        const auto bias = randomValues(size_t(d.outChannels), rng);
        const int64_t outCount = d.batch * d.outChannels * d.outHeight() * d.outWidth();
        std::vector<float> want(static_cast<size_t>(outCount));
        conv2dForward(want.data(), input.data(), weight.data(), d.bias ? bias.data() : nullptr, d);
        ActivationDesc act;
        act.kind = activation;
        activationForward(want.data(), want.data(), outCount, act);
        ActivationDesc fusedActivation;
        fusedActivation.kind = activation;
        // Few input channels: sometimes the planar (block 1) input layout.
        const int inputBlock = d.inChannels <= 16 && trial % 2 == 1 ? 1 : 0;
        BlockedConv conv(d, weight.data(), bias.data(), fusedActivation, inputBlock);
        expectClose(runBlocked(conv, input, outCount), want);
        // A narrow layer's compact output (1, 2 or 4 floats per pixel) holds the same values.
        if (conv.compactOutputBlock() > 0) {
            SCOPED_TRACE("compact output");
            conv.useCompactOutput();
            EXPECT_LT(conv.outputShape(0).block, conv.block());
            expectClose(runBlocked(conv, input, outCount), want);
        }
    }
}

// Layers whose output exceeds this stream their stores past the caches in these tests (the default,
// 32 MB, would need frames four times the size).
constexpr int64_t kStreamedTestBytes = int64_t(8) << 20;

// A layer with a few outputs over a large frame streams its stores past the caches (above 8 MB of
// output); that path, its row remainders and its border must match the reference like the cached one.
TEST_P(FastConv, NarrowLayerOverALargeFrameMatchesTheReference) {
    Rng rng(78);
    Conv2dDesc d;
    d.inChannels = 16, d.outChannels = 3;
    d.inHeight = 181, d.inWidth = 1467;  // 8-float blocks (AVX2) x 183 x 1469 padded pixels: 8.6 MB
    d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
    const RandomConv data(d, rng);
    const ActivationDesc relu{Activation::ReLU};
    BlockedConv conv(d, data.weight.data(), data.bias.data(), relu);
    conv.setStreamedOutputBytes(kStreamedTestBytes);
    expectClose(runBlocked(conv, data.input, int64_t(data.linear.size())), data.activated(relu));
}

// The compact output (4 floats per pixel for 3 channels) streamed past the caches: above 8 MB of
// output, rows that start anywhere within a vector (a partial tile up to the first whole vector, then
// whole vectors, then a partial tail), and the same for every activation the kernel fuses.
TEST_P(FastConv, NarrowLayerWithCompactOutputOverALargeFrameMatchesTheReference) {
    Rng rng(79);
    Conv2dDesc d;
    d.inChannels = 16, d.outChannels = 3;
    d.inHeight = 601, d.inWidth = 901;  // 4 floats x 603 x 903 padded pixels: 8.7 MB (> 8 MiB)
    d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
    const RandomConv data(d, rng);
    const int64_t outCount = int64_t(data.linear.size());
    for (const Activation kind : kActivations) {
        ActivationDesc activation{kind};
        activation.low = 0.1f, activation.high = 0.5f;  // a clamp whose low end is not zero
        const std::vector<float> want = data.activated(activation);
        BlockedConv conv(d, data.weight.data(), data.bias.data(), activation);
        conv.setStreamedOutputBytes(kStreamedTestBytes);
        if (GetParam() == SimdLevel::Scalar) {  // no narrow kernel: the scalar layout is planar already
            EXPECT_EQ(conv.compactOutputBlock(), 0);
            EXPECT_EQ(conv.outputShape(1).block, 1);
            EXPECT_THROW(conv.useCompactOutput(), Error);
            continue;
        }
        conv.useCompactOutput();
        ASSERT_EQ(conv.outputShape(1).block, 4);
        expectClose(runBlocked(conv, data.input, outCount), want);
    }
}

TEST_P(FastConv, ConvTranspose2dMatchesTheReferenceOnRandomShapes) {
    Rng rng(78);
    for (int trial = 0; trial < 40; ++trial) {
        ConvTranspose2dDesc d;
        d.batch = 1 + rng.below(2);
        d.inChannels = 1 + rng.below(trial < 10 ? 3 : 40);
        d.outChannels = 1 + rng.below(trial % 3 == 0 ? 3 : 40);
        d.kernelHeight = int(1 + rng.below(4)), d.kernelWidth = int(1 + rng.below(4));
        d.strideH = int(1 + rng.below(3)), d.strideW = int(1 + rng.below(3));
        d.dilationH = int(1 + rng.below(2)), d.dilationW = 1;
        d.padH = int(rng.below(2)), d.padW = int(rng.below(2));
        d.outputPaddingH = int(rng.below(uint32_t(std::max(d.strideH, d.dilationH))));
        d.outputPaddingW = int(rng.below(uint32_t(std::max(d.strideW, d.dilationW))));
        d.inHeight = 1 + rng.below(9), d.inWidth = 1 + rng.below(17);
        d.bias = rng.below(2) == 1;
        if (trial == 0) {  // the seed2020 upsampler exactly
            d.kernelHeight = d.kernelWidth = 3, d.strideH = d.strideW = 2, d.padH = d.padW = 1;
            d.outputPaddingH = d.outputPaddingW = 1, d.dilationH = 1;
        }
        if (d.outHeight() < 1 || d.outWidth() < 1) continue;
        const Activation activation = kActivations[trial % 4];
        SCOPED_TRACE("trial " + std::to_string(trial));
        const auto input = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
        const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
        const auto bias = randomValues(size_t(d.outChannels), rng);
        const int64_t outCount = d.batch * d.outChannels * d.outHeight() * d.outWidth();
        std::vector<float> want(static_cast<size_t>(outCount));
        convTranspose2dForward(want.data(), input.data(), weight.data(), d.bias ? bias.data() : nullptr, d);
        ActivationDesc act;
        act.kind = activation;
        activationForward(want.data(), want.data(), outCount, act);
        ActivationDesc fusedActivation;
        fusedActivation.kind = activation;
        // Few input channels: sometimes the planar (block 1) input layout.
        const int inputBlock = d.inChannels <= 16 && trial % 2 == 1 ? 1 : 0;
        const BlockedConv conv(d, weight.data(), bias.data(), fusedActivation, inputBlock);
        expectClose(runBlocked(conv, input, outCount), want);
    }
}

// Weight, bias and input gradients of the fast path against the reference backward kernels.
template <class Desc>
void checkBackward(const Desc& d, Rng& rng, bool transposed, bool planarInput) {
    const int64_t inCount = d.batch * d.inChannels * d.inHeight * d.inWidth;
    const int64_t outCount = d.batch * d.outChannels * d.outHeight() * d.outWidth();
    const auto input = randomValues(size_t(inCount), rng);
    const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
    const auto dout = randomValues(size_t(outCount), rng);
    std::vector<float> wantDin(static_cast<size_t>(inCount)), wantDw(weight.size()),
        wantDb(size_t(d.outChannels));
    if (transposed) {
        convTranspose2dBackward(wantDin.data(), wantDw.data(), wantDb.data(), dout.data(), input.data(),
                                weight.data(), reinterpret_cast<const ConvTranspose2dDesc&>(d));
    } else {
        conv2dBackward(wantDin.data(), wantDw.data(), wantDb.data(), dout.data(), input.data(), weight.data(),
                       reinterpret_cast<const Conv2dDesc&>(d));
    }
    const BlockedConv conv(d, weight.data(), nullptr, ActivationDesc{Activation::None}, planarInput ? 1 : 0);
    const int border = conv.requiredInputBorder();
    const BlockedShape inShape = conv.inputShape(border), outShape = conv.outputShape(0);
    Tensor in = allocateBlocked(inShape), g = allocateBlocked(outShape);
    toBlocked(in.data(), input.data(), inShape);
    toBlocked(g.data(), dout.data(), outShape);
    std::vector<float> dw(weight.size(), 0.0f), db(size_t(d.outChannels), 0.0f);
    conv.backwardWeights(dw.data(), db.data(), g.data(), outShape, in.data(), inShape);
    expectClose(dw, wantDw);
    expectClose(db, wantDb);

    const auto adjoint = BlockedConv::inputGradient(d, weight.data());
    ASSERT_TRUE(adjoint.has_value());
    const BlockedShape gShape = adjoint->inputShape(adjoint->requiredInputBorder());
    Tensor gb = allocateBlocked(gShape), din = allocateBlocked(adjoint->outputShape(0));
    toBlocked(gb.data(), dout.data(), gShape);
    adjoint->forward(din.data(), adjoint->outputShape(0), gb.data(), gShape);
    std::vector<float> got(static_cast<size_t>(inCount));
    fromBlocked(got.data(), din.data(), adjoint->outputShape(0));
    expectClose(got, wantDin);
}

TEST_P(FastConv, BackwardMatchesTheReference) {
    Rng rng(79);
    for (int trial = 0; trial < 16; ++trial) {
        SCOPED_TRACE("trial " + std::to_string(trial));
        if (trial % 2 == 0) {
            Conv2dDesc d;
            d.batch = 1 + rng.below(2), d.inChannels = 1 + rng.below(trial % 4 == 0 ? 4 : 35);
            d.outChannels = 1 + rng.below(35);
            const int k = int(1 + 2 * rng.below(3));
            d.kernelHeight = d.kernelWidth = k;
            d.padTop = d.padBottom = d.padLeft = d.padRight = k / 2;
            if (trial % 4 == 2)
                d.strideH = d.strideW = 2, d.padTop = d.padLeft = k / 2, d.padBottom = d.padRight = k / 2;
            d.inHeight = k + rng.below(12), d.inWidth = k + rng.below(20);
            if (!BlockedConv::inputGradient(d, std::vector<float>(size_t(d.weightCount())).data())) continue;
            checkBackward(d, rng, false, d.inChannels <= 8 && trial % 4 == 0);
        } else {
            ConvTranspose2dDesc d;
            d.batch = 1 + rng.below(2), d.inChannels = 1 + rng.below(35), d.outChannels = 1 + rng.below(35);
            d.kernelHeight = d.kernelWidth = 3, d.strideH = d.strideW = int(1 + rng.below(2));
            d.padH = d.padW = 1, d.outputPaddingH = d.outputPaddingW = d.strideH - 1;
            d.inHeight = 1 + rng.below(10), d.inWidth = 1 + rng.below(14);
            checkBackward(d, rng, true, d.inChannels <= 8);
        }
    }
}

// Conv2D + activation + 2x2 max pooling fused, against the three reference kernels in sequence: odd
// sizes (the last row and column have no pooled output), strides, planar inputs, few output channels.
TEST_P(FastConv, FusedMaxPoolingMatchesTheReference) {
    Rng rng(80);
    for (int trial = 0; trial < 24; ++trial) {
        Conv2dDesc d;
        d.batch = 1 + rng.below(2);
        d.inChannels = 1 + rng.below(trial < 6 ? 3 : 40);
        d.outChannels = 1 + rng.below(trial % 3 == 0 ? 4 : 40);
        const int k = int(1 + 2 * rng.below(3));
        d.kernelHeight = d.kernelWidth = k;
        d.padTop = d.padBottom = d.padLeft = d.padRight = k / 2;
        d.strideH = d.strideW = trial % 4 == 3 ? 2 : 1;
        d.inHeight = k + 1 + rng.below(20), d.inWidth = k + 1 + rng.below(45);
        if (d.outHeight() < 2 || d.outWidth() < 2) continue;
        const Activation activation = kActivations[trial % 4];
        SCOPED_TRACE("trial " + std::to_string(trial) + ": " + std::to_string(d.inChannels) + "->" +
                     std::to_string(d.outChannels) + " k" + std::to_string(k) + " " +
                     std::to_string(d.inHeight) + "x" + std::to_string(d.inWidth));
        const auto input = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
        const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
        const auto bias = randomValues(size_t(d.outChannels), rng);
        const int64_t convCount = d.batch * d.outChannels * d.outHeight() * d.outWidth();
        std::vector<float> conv(static_cast<size_t>(convCount));
        conv2dForward(conv.data(), input.data(), weight.data(), bias.data(), d);
        ActivationDesc act;
        act.kind = activation;
        activationForward(conv.data(), conv.data(), convCount, act);
        MaxPool2dDesc pool;
        pool.batch = d.batch, pool.channels = d.outChannels, pool.inHeight = d.outHeight(),
        pool.inWidth = d.outWidth();
        const int64_t outCount = d.batch * d.outChannels * pool.outHeight() * pool.outWidth();
        std::vector<float> want(static_cast<size_t>(outCount));
        std::vector<int32_t> argmax(static_cast<size_t>(outCount));
        maxPool2dForward(want.data(), argmax.data(), conv.data(), pool);
        BlockedConv fused(d, weight.data(), bias.data(), act, d.inChannels <= 8 && trial % 2 == 1 ? 1 : 0);
        fused.fuseMaxPool2x2();
        ASSERT_EQ(fused.outputShape(0).height, pool.outHeight());
        ASSERT_EQ(fused.outputShape(0).width, pool.outWidth());
        expectClose(runBlocked(fused, input, outCount), want);
    }
}

// Wide layers whose output exceeds 8 MB stream their stores past the caches: two output blocks from a
// planar input, and one block with fused pooling (the pooled output is what is streamed).
TEST_P(FastConv, WideLayersOverALargeFrameMatchTheReference) {
    Rng rng(81);
    for (const bool pooled : {false, true}) {
        Conv2dDesc d;
        d.inChannels = 3, d.outChannels = pooled ? 16 : 32;
        d.inHeight = pooled ? 731 : 301, d.inWidth = pooled ? 729 : 297;  // 8.6 and 11.6 MB of output
        d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
        SCOPED_TRACE(pooled ? "pooled" : "two output blocks");
        const RandomConv data(d, rng);
        const ActivationDesc relu{Activation::ReLU};
        std::vector<float> want = data.activated(relu);
        BlockedConv conv(d, data.weight.data(), data.bias.data(), relu, 1);
        conv.setStreamedOutputBytes(kStreamedTestBytes);
        int64_t outCount = int64_t(want.size());
        if (pooled) {
            MaxPool2dDesc pool;
            pool.channels = d.outChannels, pool.inHeight = d.outHeight(), pool.inWidth = d.outWidth();
            outCount = d.outChannels * pool.outHeight() * pool.outWidth();
            std::vector<float> full(std::move(want));
            want.assign(size_t(outCount), 0.0f);
            std::vector<int32_t> argmax(static_cast<size_t>(outCount));
            maxPool2dForward(want.data(), argmax.data(), full.data(), pool);
            conv.fuseMaxPool2x2();
        }
        ASSERT_GT(conv.outputShape(1).floatCount() * int64_t(sizeof(float)), int64_t(8) << 20);
        expectClose(runBlocked(conv, data.input, outCount), want);
    }
    // 8 outputs (half a vector: AVX-512 runs two pixels per vector, nn/fast_conv_kernels.cpp), streamed.
    Conv2dDesc d;
    d.inChannels = 3, d.outChannels = 8, d.inHeight = 601, d.inWidth = 597;
    d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
    const RandomConv data(d, rng);
    const ActivationDesc relu{Activation::ReLU};
    BlockedConv conv(d, data.weight.data(), data.bias.data(), relu, 1);
    conv.setStreamedOutputBytes(kStreamedTestBytes);
    ASSERT_GT(conv.outputShape(1).floatCount() * int64_t(sizeof(float)), int64_t(8) << 20);
    const std::vector<float> want = data.activated(relu);
    expectClose(runBlocked(conv, data.input, int64_t(want.size())), want);
}

// Planar stride-2 layers with a few outputs (a network's first layer on a frame: AVX-512 puts 16 output
// pixels in the lanes, nn/fast_conv_kernels.cpp): widths with whole vectors and a tail, 1-4 inputs,
// 1-8 outputs, 3x3 and 5x5, a dilation, a stride in one direction only, every activation.
TEST_P(FastConv, PlanarStrideTwoLayersMatchTheReference) {
    Rng rng(91);
    for (int trial = 0; trial < 12; ++trial) {
        Conv2dDesc d;
        d.inChannels = 1 + trial % 4, d.outChannels = 1 + (trial * 3) % 8;
        d.kernelHeight = d.kernelWidth = trial % 3 == 2 ? 5 : 3;
        d.strideH = trial % 4 == 3 ? 1 : 2, d.strideW = 2;
        d.dilationW = trial == 5 ? 2 : 1;
        d.padTop = d.padBottom = d.kernelHeight / 2;
        d.padLeft = d.padRight = d.dilationW * (d.kernelWidth / 2);
        d.inHeight = 9 + trial, d.inWidth = 2 * 16 * (1 + trial % 3) + trial % 5;
        SCOPED_TRACE("trial " + std::to_string(trial));
        const RandomConv data(d, rng);
        const ActivationDesc activation{kActivations[trial % 4], 0.1f, -0.5f, 0.5f};
        const BlockedConv conv(d, data.weight.data(), data.bias.data(), activation, 1);
        const std::vector<float> want = data.activated(activation);
        expectClose(runBlocked(conv, data.input, int64_t(want.size())), want);
    }
}

// An input given band by band (BlockedConv::forwardBanded, a frame streamed into a first layer) gives
// forward()'s output bit for bit, whatever the number of band buffers.
TEST_P(FastConv, BandedInputEqualsTheWholeInput) {
    Rng rng(93);
    for (int trial = 0; trial < 6; ++trial) {
        Conv2dDesc d;
        d.inChannels = 1 + trial % 3, d.outChannels = trial % 2 == 0 ? 8 : 20;
        d.kernelHeight = d.kernelWidth = trial < 3 ? 3 : 5;
        d.strideH = d.strideW = 1 + trial % 2;
        d.padTop = d.padBottom = d.padLeft = d.padRight = d.kernelHeight / 2;
        d.inHeight = 37 + trial, d.inWidth = 45 - trial;
        SCOPED_TRACE("trial " + std::to_string(trial));
        const RandomConv data(d, rng);
        const BlockedConv conv(d, data.weight.data(), data.bias.data(), ActivationDesc{Activation::ReLU}, 1);
        ASSERT_TRUE(conv.canBandInput());
        const int border = conv.requiredInputBorder();
        const BlockedShape inShape = conv.inputShape(border), outShape = conv.outputShape(border);
        Tensor in = allocateBlocked(inShape), want = allocateBlocked(outShape);
        toBlocked(in.data(), data.input.data(), inShape);
        conv.forward(want.data(), outShape, in.data(), inShape);
        // Rows from the whole input (zero outside it), counted.
        struct Rows final : BlockedConv::BandInput {
            const float* plain = nullptr;
            int64_t channels = 0, height = 0, width = 0, filled = 0;
            void fill(int64_t firstRow, int64_t rows, float* band, const BlockedShape& shape) override {
                for (int64_t y = firstRow; y < firstRow + rows; ++y)
                    for (int64_t c = 0; c < channels; ++c) {
                        float* row = band + shape.offset(0, c, y - firstRow, 0);
                        for (int64_t x = 0; x < width; ++x)
                            row[x] = y < 0 || y >= height ? 0.0f : plain[(c * height + y) * width + x];
                    }
                filled += rows;
            }
        } rows;
        rows.plain = data.input.data(), rows.channels = d.inChannels, rows.height = d.inHeight;
        rows.width = d.inWidth;
        for (int buffers : {1, 3}) {
            const BlockedShape bandShape = conv.bandShape(inShape);
            std::vector<Tensor> bands;
            std::vector<float*> pointers;
            for (int k = 0; k < buffers; ++k) bands.push_back(allocateBlocked(bandShape));
            for (Tensor& t : bands) pointers.push_back(t.data());
            Tensor got = allocateBlocked(outShape);
            conv.forwardBanded(got.data(), outShape, inShape, rows, pointers.data(), buffers);
            for (int64_t i = 0; i < got.numel(); ++i)
                ASSERT_EQ(got.data()[i], want.data()[i]) << buffers << " buffers, element " << i;
        }
        EXPECT_GE(rows.filled, 2 * d.inHeight) << "every input row given at least once per run";
    }
}

TEST_P(FastConv, SameResultForEveryThreadCount) {
    Rng rng(5);
    Conv2dDesc d;
    d.batch = 2, d.inChannels = 19, d.outChannels = 35, d.inHeight = 23, d.inWidth = 37;
    d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
    const auto input = randomValues(size_t(2 * 19 * 23 * 37), rng);
    const auto weight = randomValues(size_t(d.weightCount()), rng, 0.3f);
    const auto bias = randomValues(35, rng);
    const BlockedConv conv(d, weight.data(), bias.data(), ActivationDesc{Activation::ReLU});
    const int64_t outCount = 2 * 35 * 23 * 37;
    setThreadCount(1);
    const auto one = runBlocked(conv, input, outCount);
    setThreadCount(3);
    const auto three = runBlocked(conv, input, outCount);
    setThreadCount(0);
    EXPECT_EQ(one, three);
}

INSTANTIATE_TEST_SUITE_P(SimdLevels, FastConv, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);

TEST(FastConvLimits, RefusesWhatItDoesNotSupport) {
    Conv2dDesc d;
    d.inChannels = 4, d.outChannels = 4, d.inHeight = 8, d.inWidth = 8;
    d.padTop = d.padBottom = d.padLeft = d.padRight = 1;
    std::vector<float> w(size_t(d.weightCount())), b(4);
    EXPECT_THROW(BlockedConv(d, w.data(), b.data(), ActivationDesc{Activation::Sigmoid}), Error);
    const BlockedConv conv(d, w.data(), b.data(), ActivationDesc{Activation::None});
    EXPECT_EQ(conv.requiredInputBorder(), 1);
    Tensor in = allocateBlocked(conv.inputShape(0)), out = allocateBlocked(conv.outputShape(0));
    EXPECT_THROW(conv.forward(out.data(), conv.outputShape(0), in.data(), conv.inputShape(0)),
                 Error);  // border 0 < 1
    std::vector<float> dw(w.size()), db(4);
    BlockedConv pooled(d, w.data(), b.data(), ActivationDesc{Activation::None});
    pooled.fuseMaxPool2x2();
    Tensor full = allocateBlocked(conv.outputShape(1)), input = allocateBlocked(conv.inputShape(1));
    EXPECT_THROW(pooled.backwardWeights(dw.data(), db.data(), full.data(), conv.outputShape(1), input.data(),
                                        conv.inputShape(1)),
                 Error);  // fused pooling is for inference
    ConvTranspose2dDesc t;
    t.inChannels = 4, t.outChannels = 4, t.inHeight = 4, t.inWidth = 4, t.strideH = t.strideW = 2;
    BlockedConv transposed(t, w.data(), b.data(), ActivationDesc{Activation::None});
    EXPECT_THROW(transposed.fuseMaxPool2x2(), Error);
    // Compact outputs: for a stride-1 lattice without pooling, and then only in the compact layout.
    EXPECT_EQ(pooled.compactOutputBlock(), 0);
    EXPECT_EQ(transposed.compactOutputBlock(), 0);
    EXPECT_THROW(transposed.useCompactOutput(), Error);
    BlockedConv compact(d, w.data(), b.data(), ActivationDesc{Activation::None});
    if (compact.compactOutputBlock() > 0) {
        compact.useCompactOutput();
        EXPECT_THROW(compact.fuseMaxPool2x2(), Error);
        EXPECT_THROW(compact.forward(full.data(), conv.outputShape(1), input.data(), conv.inputShape(1)),
                     Error);  // the blocked layout where the compact one is expected
    }
}

}  // namespace
}  // namespace dejag::nn

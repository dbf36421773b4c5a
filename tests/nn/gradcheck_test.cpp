// Finite-difference gradient checks in double for every layer and loss, on random shapes.
// L = sum(y * r) for a random r; the backward with dout = r must match central differences of L.
// Step h = 1e-5 (1e-4 for the losses, whose per-pixel gradients are ~1e-5 of a mean over thousands of
// terms): small enough for O(h^2) truncation, large enough that double rounding stays far below 1e-6.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <random>
#include <vector>

#include "nn/gradient_check.h"
#include "nn/layers.h"
#include "nn/losses.h"

namespace dejag::nn {
namespace {

using Vec = std::vector<double>;

// nn::checkGradient (nn/gradient_check.h) at up to `samples` coordinates, step h; the relative error's
// denominator is at least 1e-6 and a thousandth of the gradient's largest component (as in `dejag bench
// stability`: a tiny component is measured against the differences' rounding noise, not itself).
double checkGradient(Vec& v, const Vec& analytic, const std::function<double()>& scalar, std::mt19937& rng,
                     int samples = 40, double h = 1e-5) {
    std::mt19937_64 coordinates(rng());
    GradientCheckOptions options;
    options.samples = samples, options.step = h, options.floorOfLargest = 1e-3;
    return nn::checkGradient(v, analytic, scalar, coordinates, options).worst;
}

constexpr double kTolerance = 1e-6;

TEST(GradCheck, Conv2dRandomShapes) {
    std::mt19937 rng(1);
    for (int trial = 0; trial < 24; ++trial) {
        Conv2dDesc d;
        d.batch = 1 + rng() % 2, d.inChannels = 1 + rng() % 3, d.outChannels = 1 + rng() % 3;
        d.kernelHeight = 1 + rng() % 5, d.kernelWidth = 1 + rng() % 5;
        d.strideH = 1 + rng() % 2, d.strideW = 1 + rng() % 3;
        d.dilationH = 1 + rng() % 2, d.dilationW = 1 + rng() % 2;
        d.padTop = rng() % 3, d.padBottom = rng() % 3, d.padLeft = rng() % 3, d.padRight = rng() % 2;
        d.inHeight = d.dilationH * (d.kernelHeight - 1) + 1 + rng() % 6;
        d.inWidth = d.dilationW * (d.kernelWidth - 1) + 1 + rng() % 6;
        d.bias = rng() % 2;
        SCOPED_TRACE("trial " + std::to_string(trial));
        Vec x = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
        Vec w = randomValues(size_t(d.weightCount()), rng), b = randomValues(size_t(d.outChannels), rng);
        const size_t outCount = size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth());
        const Vec r = randomValues(outCount, rng);
        Vec y(outCount);
        auto loss = [&] {
            conv2dForward(y.data(), x.data(), w.data(), d.bias ? b.data() : nullptr, d);
            return dot(y, r);
        };
        Vec dx(x.size()), dw(w.size()), db(b.size());
        conv2dBackward(dx.data(), dw.data(), d.bias ? db.data() : nullptr, r.data(), x.data(), w.data(), d);
        EXPECT_LE(checkGradient(x, dx, loss, rng), kTolerance) << "dinput";
        EXPECT_LE(checkGradient(w, dw, loss, rng), kTolerance) << "dweight";
        if (d.bias) {
            EXPECT_LE(checkGradient(b, db, loss, rng), kTolerance) << "dbias";
        }
    }
}

TEST(GradCheck, ConvTranspose2dRandomShapes) {
    std::mt19937 rng(2);
    for (int trial = 0; trial < 24; ++trial) {
        ConvTranspose2dDesc d;
        d.batch = 1 + rng() % 2, d.inChannels = 1 + rng() % 3, d.outChannels = 1 + rng() % 3;
        d.kernelHeight = 1 + rng() % 4, d.kernelWidth = 1 + rng() % 4;
        d.strideH = 1 + rng() % 3, d.strideW = 1 + rng() % 2;
        d.dilationH = 1 + rng() % 2, d.dilationW = 1;
        d.padH = rng() % 2, d.padW = rng() % 2;
        d.outputPaddingH = rng() % std::max(d.strideH, d.dilationH);
        d.outputPaddingW = rng() % std::max(d.strideW, d.dilationW);
        d.inHeight = 2 + rng() % 4, d.inWidth = 2 + rng() % 4;
        d.bias = rng() % 2;
        if (d.outHeight() < 1 || d.outWidth() < 1) continue;
        SCOPED_TRACE("trial " + std::to_string(trial));
        Vec x = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
        Vec w = randomValues(size_t(d.weightCount()), rng), b = randomValues(size_t(d.outChannels), rng);
        const size_t outCount = size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth());
        const Vec r = randomValues(outCount, rng);
        Vec y(outCount);
        auto loss = [&] {
            convTranspose2dForward(y.data(), x.data(), w.data(), d.bias ? b.data() : nullptr, d);
            return dot(y, r);
        };
        Vec dx(x.size()), dw(w.size()), db(b.size());
        convTranspose2dBackward(dx.data(), dw.data(), d.bias ? db.data() : nullptr, r.data(), x.data(),
                                w.data(), d);
        EXPECT_LE(checkGradient(x, dx, loss, rng), kTolerance) << "dinput";
        EXPECT_LE(checkGradient(w, dw, loss, rng), kTolerance) << "dweight";
        if (d.bias) {
            EXPECT_LE(checkGradient(b, db, loss, rng), kTolerance) << "dbias";
        }
    }
}

TEST(GradCheck, MaxPool2dRandomShapes) {
    std::mt19937 rng(3);
    for (int trial = 0; trial < 16; ++trial) {
        MaxPool2dDesc d;
        d.batch = 1 + rng() % 2, d.channels = 1 + rng() % 3;
        d.kernel = 1 + rng() % 3, d.stride = 1 + rng() % 3, d.padding = rng() % (d.kernel / 2 + 1);
        d.inHeight = d.kernel + rng() % 6, d.inWidth = d.kernel + rng() % 6;
        SCOPED_TRACE("trial " + std::to_string(trial));
        Vec x = randomValues(size_t(d.batch * d.channels * d.inHeight * d.inWidth), rng);
        const size_t outCount = size_t(d.batch * d.channels * d.outHeight() * d.outWidth());
        const Vec r = randomValues(outCount, rng);
        Vec y(outCount);
        std::vector<int32_t> argmax(outCount);
        auto loss = [&] {
            maxPool2dForward(y.data(), argmax.data(), x.data(), d);
            return dot(y, r);
        };
        loss();
        Vec dx(x.size());
        maxPool2dBackward(dx.data(), r.data(), argmax.data(), d);
        EXPECT_LE(checkGradient(x, dx, loss, rng), kTolerance);
    }
}

TEST(GradCheck, Activations) {
    std::mt19937 rng(4);
    for (Activation kind : {Activation::None, Activation::ReLU, Activation::LeakyReLU, Activation::Sigmoid,
                            Activation::Clamp}) {
        ActivationDesc d;
        d.kind = kind;
        d.slope = 0.2f;
        d.low = -0.5f, d.high = 0.7f;
        Vec x = randomValues(97, rng, -3, 3), y(97);
        const Vec r = randomValues(97, rng);
        auto loss = [&] {
            activationForward(y.data(), x.data(), 97, d);
            return dot(y, r);
        };
        loss();
        Vec dx(97);
        activationBackward(dx.data(), r.data(), x.data(), y.data(), 97, d);
        EXPECT_LE(checkGradient(x, dx, loss, rng, 97), kTolerance) << activationName(kind);
    }
}

TEST(GradCheck, AddAndConcat) {
    std::mt19937 rng(5);
    Vec a = randomValues(60, rng), b = randomValues(60, rng), y(60);
    const Vec r = randomValues(60, rng);
    auto addLoss = [&] {
        addForward(y.data(), a.data(), b.data(), 60);
        return dot(y, r);
    };
    Vec da(60), db(60);
    addBackward(da.data(), db.data(), r.data(), 60);
    EXPECT_LE(checkGradient(a, da, addLoss, rng), kTolerance);
    EXPECT_LE(checkGradient(b, db, addLoss, rng), kTolerance);

    // Concat of (2, 1, 3, 4) and (2, 3, 3, 4) along channels.
    Vec p = randomValues(24, rng), q = randomValues(72, rng), z(96);
    const Vec s = randomValues(96, rng);
    auto concatLoss = [&] {
        concatForward<double>(z.data(), {p.data(), q.data()}, {1, 3}, 2, 12);
        return dot(z, s);
    };
    Vec dp(24), dq(72);
    concatBackward<double>({dp.data(), dq.data()}, s.data(), {1, 3}, 2, 12);
    EXPECT_LE(checkGradient(p, dp, concatLoss, rng), kTolerance);
    EXPECT_LE(checkGradient(q, dq, concatLoss, rng), kTolerance);
}

TEST(GradCheck, Resampling) {
    std::mt19937 rng(6);
    for (int factor : {2, 3}) {
        ResampleDesc d{2, 4, 3, 5, factor};
        const size_t in = size_t(2 * 4 * 3 * 5), out = in * size_t(factor * factor);
        for (int kind = 0; kind < 3; ++kind) {
            if (kind == 2 && factor == 3) continue;  // pixel shuffle needs channels % factor^2 == 0
            Vec x = randomValues(in, rng), y(kind == 2 ? in : out);
            const Vec r = randomValues(y.size(), rng);
            auto loss = [&] {
                if (kind == 0)
                    upsampleNearestForward(y.data(), x.data(), d);
                else if (kind == 1)
                    upsampleBilinearForward(y.data(), x.data(), d);
                else
                    pixelShuffleForward(y.data(), x.data(), d);
                return dot(y, r);
            };
            Vec dx(in);
            if (kind == 0)
                upsampleNearestBackward(dx.data(), r.data(), d);
            else if (kind == 1)
                upsampleBilinearBackward(dx.data(), r.data(), d);
            else
                pixelShuffleBackward(dx.data(), r.data(), d);
            EXPECT_LE(checkGradient(x, dx, loss, rng), kTolerance) << "kind " << kind << " factor " << factor;
        }
    }
}

TEST(GradCheck, KernelFilterRandomShapes) {
    std::mt19937 rng(9);
    for (int trial = 0; trial < 6; ++trial) {
        KernelFilterDesc d;
        d.batch = 1 + int(rng() % 2), d.channels = 1 + int(rng() % 3);
        d.height = 1 + int(rng() % 6), d.width = 1 + int(rng() % 7);  // smaller than the kernel too
        d.kernel = 1 + 2 * int(rng() % 3);
        d.centreBias = float(int(rng() % 5) - 1);
        const size_t image = size_t(d.batch * d.channels * d.height * d.width),
                     logits = size_t(d.batch * d.taps() * d.height * d.width);
        Vec x = randomValues(image, rng), l = randomValues(logits, rng, -3.0, 3.0), y(image);
        const Vec r = randomValues(image, rng);
        auto loss = [&] {
            kernelFilterForward(y.data(), x.data(), l.data(), d);
            return dot(y, r);
        };
        Vec dx(image), dl(logits);
        kernelFilterBackward(dx.data(), dl.data(), r.data(), x.data(), l.data(), d);
        EXPECT_LE(checkGradient(x, dx, loss, rng), kTolerance) << "input, trial " << trial;
        EXPECT_LE(checkGradient(l, dl, loss, rng), kTolerance) << "logits, trial " << trial;
    }
}

TEST(GradCheck, LossesRandomShapes) {
    std::mt19937 rng(7);
    for (int trial = 0; trial < 8; ++trial) {
        SsimLossDesc d;
        d.batch = 1 + rng() % 2, d.channels = 1 + rng() % 3, d.height = 11 + rng() % 7,
        d.width = 11 + rng() % 9;
        d.dataRange = trial % 4 == 3 ? 10.0 : 1.0;
        const size_t n = size_t(d.batch * d.channels * d.height * d.width);
        Vec target = randomValues(n, rng, 0.0, d.dataRange), pred = randomValues(n, rng, 0.0, d.dataRange);
        SCOPED_TRACE("trial " + std::to_string(trial));
        for (const char* spec : {"ssim", "l1", "mse", "0.84*ssim+0.16*l1"}) {
            const CompositeLoss loss = CompositeLoss::parse(spec);
            Vec dpred(n);
            loss.evaluate(dpred.data(), pred.data(), target.data(), d);
            auto value = [&] { return loss.evaluate<double>(nullptr, pred.data(), target.data(), d); };
            EXPECT_LE(checkGradient(pred, dpred, value, rng, 40, 1e-4 * d.dataRange), kTolerance) << spec;
        }
    }
}

}  // namespace
}  // namespace dejag::nn

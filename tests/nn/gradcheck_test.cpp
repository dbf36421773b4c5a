// Finite-difference gradient checks in double for every loss, on random shapes (the layers' are cases of
// the op harness, tests/nn/ops_test.cpp).
// L = sum(y * r) for a random r; the backward with dout = r must match central differences of L.
// Step h = 1e-5 (1e-4 for the losses, whose per-pixel gradients are ~1e-5 of a mean over thousands of
// terms): small enough for O(h^2) truncation, large enough that double rounding stays far below 1e-6.
#include <gtest/gtest.h>

#include "base/error.h"

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

// The harm term: per-sample hinge on the excess MSE over the input's. Some samples are harmed (the
// prediction noisier than the input), some helped (closer); none sits on the hinge, where the one-sided
// derivatives differ.
TEST(GradCheck, HarmTermHarmedAndHelpedSamples) {
    std::mt19937 rng(11);
    SsimLossDesc d;
    d.batch = 4, d.channels = 3, d.height = 11, d.width = 12;
    const size_t n = size_t(d.batch * d.channels * d.height * d.width), per = n / size_t(d.batch);
    Vec target = randomValues(n, rng, 0.0, 1.0), input(n), pred(n);
    std::normal_distribution<double> noise(0.0, 1.0);
    for (size_t i = 0; i < n; ++i) {
        const size_t sample = i / per;
        input[i] = target[i] + 0.05 * noise(rng);
        pred[i] = target[i] + (sample % 2 ? 0.02 : 0.09) * noise(rng);  // odd samples helped, even harmed
    }
    const CompositeLoss loss = CompositeLoss::parse("0.84*ssim+0.16*l1+0.5*harm");
    EXPECT_TRUE(loss.needsInput());
    EXPECT_THROW(loss.evaluate<double>(nullptr, pred.data(), target.data(), d), Error);
    Vec dpred(n);
    loss.evaluate(dpred.data(), pred.data(), target.data(), d, 1.0, input.data());
    auto value = [&] {
        return loss.evaluate<double>(nullptr, pred.data(), target.data(), d, 1.0, input.data());
    };
    EXPECT_LE(checkGradient(pred, dpred, value, rng, 60, 1e-5), kTolerance);
    // The value by hand: only the harmed samples count, each by its relative excess error.
    double expected = 0;
    for (size_t s = 0; s < size_t(d.batch); ++s) {
        double p = 0, g = 0;
        for (size_t i = s * per; i < (s + 1) * per; ++i)
            p += (pred[i] - target[i]) * (pred[i] - target[i]),
                g += (input[i] - target[i]) * (input[i] - target[i]);
        p /= double(per), g /= double(per);
        if (s % 2 == 0) {
            EXPECT_GT(p, g);
        }
        expected += std::max(0.0, p - g) / (g + kHarmEpsilon);
    }
    EXPECT_NEAR(harmLoss(pred.data(), input.data(), target.data(), d.batch, int64_t(per)), expected / d.batch,
                1e-12);
    // A prediction equal to its input, or closer to the target, costs nothing and pulls nowhere.
    Vec zero(n, 0.0);
    EXPECT_EQ(harmLoss(input.data(), input.data(), target.data(), d.batch, int64_t(per)), 0.0);
    harmLossBackward(zero.data(), input.data(), input.data(), target.data(), d.batch, int64_t(per), 1.0);
    EXPECT_EQ(zero, Vec(n, 0.0));
}

// Harm per block ("harm5" on 11 x 12 samples: blocks of 5, 5 and a last 1 or 2 wide): the gradient
// against finite differences; the value by hand; a block the size of the sample is the per-sample term.
TEST(GradCheck, HarmTermPerBlock) {
    std::mt19937 rng(12);
    SsimLossDesc d;
    d.batch = 2, d.channels = 3, d.height = 11, d.width = 12;
    const size_t n = size_t(d.batch * d.channels * d.height * d.width);
    Vec target = randomValues(n, rng, 0.0, 1.0), input(n), pred(n);
    std::normal_distribution<double> noise(0.0, 1.0);
    for (size_t i = 0; i < n; ++i) {
        const size_t x = i % size_t(d.width);
        input[i] = target[i] + 0.05 * noise(rng);
        pred[i] = target[i] + (x < 5 ? 0.02 : 0.09) * noise(rng);  // the left blocks helped, the rest harmed
    }
    const CompositeLoss loss = CompositeLoss::parse("0.84*ssim+0.5*harm5");
    ASSERT_EQ(loss.terms[1].tile, 5);
    Vec dpred(n);
    loss.evaluate(dpred.data(), pred.data(), target.data(), d, 1.0, input.data());
    auto value = [&] {
        return loss.evaluate<double>(nullptr, pred.data(), target.data(), d, 1.0, input.data());
    };
    EXPECT_LE(checkGradient(pred, dpred, value, rng, 60, 1e-5), kTolerance);
    double expected = 0;
    int blocks = 0;
    for (int s = 0; s < d.batch; ++s)
        for (int y0 = 0; y0 < d.height; y0 += 5)
            for (int x0 = 0; x0 < d.width; x0 += 5, ++blocks) {
                double p = 0, g = 0;
                int count = 0;
                for (int c = 0; c < d.channels; ++c)
                    for (int y = y0; y < std::min(y0 + 5, int(d.height)); ++y)
                        for (int x = x0; x < std::min(x0 + 5, int(d.width)); ++x, ++count) {
                            const size_t i = size_t(((s * d.channels + c) * d.height + y) * d.width + x);
                            p += (pred[i] - target[i]) * (pred[i] - target[i]);
                            g += (input[i] - target[i]) * (input[i] - target[i]);
                        }
                p /= count, g /= count;
                expected += std::max(0.0, p - g) / (g + kHarmEpsilon);
            }
    EXPECT_EQ(blocks, 2 * 3 * 3);
    EXPECT_NEAR(harmTilesLoss(pred.data(), input.data(), target.data(), d, 5), expected / blocks, 1e-12);
    EXPECT_NEAR(harmTilesLoss(pred.data(), input.data(), target.data(), d, 12),
                harmLoss(pred.data(), input.data(), target.data(), d.batch, int64_t(n) / d.batch), 1e-12);
    EXPECT_THROW(CompositeLoss::parse("harm0"), Error);
    EXPECT_THROW(CompositeLoss::parse("harmx"), Error);
}

// Harm on masked pixels ("texharm"): the gradient against finite differences; the value by hand (only the
// masked pixels count, weighted by the mask); an empty mask costs nothing; a full mask is the plain term.
TEST(GradCheck, HarmTermOnMaskedPixels) {
    std::mt19937 rng(13);
    SsimLossDesc d;
    d.batch = 3, d.channels = 3, d.height = 11, d.width = 12;
    const int64_t plane = d.height * d.width;
    const size_t n = size_t(d.batch * d.channels * plane);
    Vec target = randomValues(n, rng, 0.0, 1.0), input(n), pred(n), mask(size_t(d.batch * plane), 0.0);
    std::normal_distribution<double> noise(0.0, 1.0);
    for (size_t i = 0; i < n; ++i) {
        const size_t x = i % size_t(d.width);
        input[i] = target[i] + 0.05 * noise(rng);
        pred[i] = target[i] + (x < 6 ? 0.02 : 0.09) * noise(rng);  // the right half harmed
    }
    // Sample 0: the right half masked (harmed); 1: the left half (helped); 2: nothing. Some weights 0.5.
    for (int64_t s = 0; s < 2; ++s)
        for (int64_t i = 0; i < plane; ++i)
            if ((i % d.width < 6) == (s == 1)) mask[size_t(s * plane + i)] = i % 5 == 0 ? 0.5 : 1.0;
    const CompositeLoss loss = CompositeLoss::parse("0.84*ssim+0.5*texharm");
    EXPECT_TRUE(loss.needsInput());
    EXPECT_TRUE(loss.needsMask());
    EXPECT_FALSE(CompositeLoss::parse("0.84*ssim+0.5*harm").needsMask());
    EXPECT_THROW(loss.evaluate<double>(nullptr, pred.data(), target.data(), d, 1.0, input.data()), Error);
    Vec dpred(n);
    loss.evaluate(dpred.data(), pred.data(), target.data(), d, 1.0, input.data(), mask.data());
    auto value = [&] {
        return loss.evaluate<double>(nullptr, pred.data(), target.data(), d, 1.0, input.data(), mask.data());
    };
    EXPECT_LE(checkGradient(pred, dpred, value, rng, 60, 1e-5), kTolerance);
    double expected = 0;
    for (int64_t s = 0; s < d.batch; ++s) {
        double p = 0, g = 0, w = 0;
        for (int64_t c = 0; c < d.channels; ++c)
            for (int64_t i = 0; i < plane; ++i) {
                const size_t at = size_t((s * d.channels + c) * plane + i);
                const double m = mask[size_t(s * plane + i)];
                p += m * (pred[at] - target[at]) * (pred[at] - target[at]);
                g += m * (input[at] - target[at]) * (input[at] - target[at]);
                w += m;
            }
        if (w == 0) continue;
        p /= w, g /= w;
        if (s == 0) {
            EXPECT_GT(p, g);
        }
        if (s == 1) {
            EXPECT_LT(p, g);
        }
        expected += std::max(0.0, p - g) / (g + kHarmEpsilon);
    }
    EXPECT_GT(expected, 0);
    EXPECT_NEAR(maskedHarmLoss(pred.data(), input.data(), target.data(), mask.data(), d), expected / d.batch,
                1e-12);
    Vec ones(mask.size(), 1.0), zero(n, 0.0);
    EXPECT_NEAR(maskedHarmLoss(pred.data(), input.data(), target.data(), ones.data(), d),
                harmLoss(pred.data(), input.data(), target.data(), d.batch, int64_t(n) / d.batch), 1e-12);
    Vec none(mask.size(), 0.0);
    EXPECT_EQ(maskedHarmLoss(pred.data(), input.data(), target.data(), none.data(), d), 0.0);
    maskedHarmLossBackward(zero.data(), pred.data(), input.data(), target.data(), none.data(), d, 1.0);
    EXPECT_EQ(zero, Vec(n, 0.0));
}

}  // namespace
}  // namespace dejag::nn

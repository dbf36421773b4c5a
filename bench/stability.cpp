#include "bench/stability.h"

#include <algorithm>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <random>

#include "nn/gradient_check.h"
#include "nn/layers.h"
#include "nn/losses.h"

namespace dejag::bench {

namespace {

using Vec = std::vector<double>;
using Rng = std::mt19937_64;
using nn::dot;
using nn::randomValues;

std::vector<float> toFloat(const Vec& v) {
    return std::vector<float>(v.begin(), v.end());
}

// Normwise relative error of a float result against the double one.
double floatError(const std::vector<float>& f, const Vec& d) {
    double diff = 0, norm = 0;
    for (size_t i = 0; i < d.size(); ++i) {
        diff = std::max(diff, std::abs(double(f[i]) - d[i]));
        norm = std::max(norm, std::abs(d[i]));
    }
    return diff / std::max(norm, 1e-30);
}

struct Accumulator {
    StabilityRow row;
    std::vector<double> errors;  // per configuration: the worst checked coordinate
};

// The double gradient check of nn/gradient_check.h with this bench's settings: 16 coordinates, the
// denominator at least a thousandth of the gradient's largest component (a component many orders
// smaller than the rest is measured against the differences' rounding noise, about 1e-16 |L| / h, not
// against itself), kinks skipped for the piecewise-linear kinds.
double checkGradient(Vec& v, const Vec& analytic, const std::function<double()>& scalar, Rng& rng, double h,
                     Accumulator& acc, bool piecewise = false) {
    nn::GradientCheckOptions options;
    options.samples = 16, options.step = h, options.floor = 1e-12, options.floorOfLargest = 1e-3;
    options.piecewise = piecewise;
    const nn::GradientCheckResult result = nn::checkGradient(v, analytic, scalar, rng, options);
    acc.row.coordinates += result.checked, acc.row.kinks += result.kinks;
    return result.worst;
}

void conv2dCase(Rng& rng, Accumulator& acc) {
    nn::Conv2dDesc d;
    d.batch = 1 + rng() % 2, d.inChannels = 1 + rng() % 4, d.outChannels = 1 + rng() % 4;
    d.kernelHeight = 1 + rng() % 5, d.kernelWidth = 1 + rng() % 5;
    d.strideH = 1 + rng() % 3, d.strideW = 1 + rng() % 3;
    d.dilationH = 1 + rng() % 2, d.dilationW = 1 + rng() % 2;
    d.padTop = rng() % 3, d.padBottom = rng() % 3, d.padLeft = rng() % 3, d.padRight = rng() % 3;
    d.inHeight = d.dilationH * (d.kernelHeight - 1) + 1 + rng() % 7;
    d.inWidth = d.dilationW * (d.kernelWidth - 1) + 1 + rng() % 7;
    d.bias = rng() % 2;
    Vec x = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
    Vec w = randomValues(size_t(d.weightCount()), rng), b = randomValues(size_t(d.outChannels), rng);
    const size_t outCount = size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth());
    const Vec r = randomValues(outCount, rng);
    Vec y(outCount);
    auto loss = [&] {
        nn::conv2dForward(y.data(), x.data(), w.data(), d.bias ? b.data() : nullptr, d);
        return dot(y, r);
    };
    loss();
    const Vec yDouble = y;
    Vec dx(x.size()), dw(w.size()), db(b.size());
    nn::conv2dBackward(dx.data(), dw.data(), d.bias ? db.data() : nullptr, r.data(), x.data(), w.data(), d);
    double worst =
        std::max(checkGradient(x, dx, loss, rng, 1e-5, acc), checkGradient(w, dw, loss, rng, 1e-5, acc));
    if (d.bias) worst = std::max(worst, checkGradient(b, db, loss, rng, 1e-5, acc));
    acc.errors.push_back(worst);
    // float32
    const auto xf = toFloat(x), wf = toFloat(w), bf = toFloat(b), rf = toFloat(r);
    std::vector<float> yf(outCount), dxf(x.size()), dwf(w.size()), dbf(b.size());
    nn::conv2dForward(yf.data(), xf.data(), wf.data(), d.bias ? bf.data() : nullptr, d);
    nn::conv2dBackward(dxf.data(), dwf.data(), d.bias ? dbf.data() : nullptr, rf.data(), xf.data(), wf.data(),
                       d);
    acc.row.worstFloat =
        std::max({acc.row.worstFloat, floatError(yf, yDouble), floatError(dxf, dx), floatError(dwf, dw)});
}

void convTransposeCase(Rng& rng, Accumulator& acc) {
    nn::ConvTranspose2dDesc d;
    do {
        d.batch = 1 + rng() % 2, d.inChannels = 1 + rng() % 4, d.outChannels = 1 + rng() % 4;
        d.kernelHeight = 1 + rng() % 4, d.kernelWidth = 1 + rng() % 4;
        d.strideH = 1 + rng() % 3, d.strideW = 1 + rng() % 3;
        d.dilationH = 1 + rng() % 2, d.dilationW = 1 + rng() % 2;
        d.padH = rng() % 2, d.padW = rng() % 2;
        d.outputPaddingH = int(rng() % uint64_t(std::max(d.strideH, d.dilationH)));
        d.outputPaddingW = int(rng() % uint64_t(std::max(d.strideW, d.dilationW)));
        d.inHeight = 2 + rng() % 5, d.inWidth = 2 + rng() % 5;
        d.bias = rng() % 2;
    } while (d.outHeight() < 1 || d.outWidth() < 1);
    Vec x = randomValues(size_t(d.batch * d.inChannels * d.inHeight * d.inWidth), rng);
    Vec w = randomValues(size_t(d.weightCount()), rng), b = randomValues(size_t(d.outChannels), rng);
    const size_t outCount = size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth());
    const Vec r = randomValues(outCount, rng);
    Vec y(outCount);
    auto loss = [&] {
        nn::convTranspose2dForward(y.data(), x.data(), w.data(), d.bias ? b.data() : nullptr, d);
        return dot(y, r);
    };
    loss();
    const Vec yDouble = y;
    Vec dx(x.size()), dw(w.size()), db(b.size());
    nn::convTranspose2dBackward(dx.data(), dw.data(), d.bias ? db.data() : nullptr, r.data(), x.data(),
                                w.data(), d);
    double worst =
        std::max(checkGradient(x, dx, loss, rng, 1e-5, acc), checkGradient(w, dw, loss, rng, 1e-5, acc));
    if (d.bias) worst = std::max(worst, checkGradient(b, db, loss, rng, 1e-5, acc));
    acc.errors.push_back(worst);
    const auto xf = toFloat(x), wf = toFloat(w), bf = toFloat(b), rf = toFloat(r);
    std::vector<float> yf(outCount), dxf(x.size()), dwf(w.size()), dbf(b.size());
    nn::convTranspose2dForward(yf.data(), xf.data(), wf.data(), d.bias ? bf.data() : nullptr, d);
    nn::convTranspose2dBackward(dxf.data(), dwf.data(), d.bias ? dbf.data() : nullptr, rf.data(), xf.data(),
                                wf.data(), d);
    acc.row.worstFloat =
        std::max({acc.row.worstFloat, floatError(yf, yDouble), floatError(dxf, dx), floatError(dwf, dw)});
}

void maxPoolCase(Rng& rng, Accumulator& acc) {
    nn::MaxPool2dDesc d;
    d.batch = 1 + rng() % 2, d.channels = 1 + rng() % 3;
    d.kernel = 1 + rng() % 3, d.stride = 1 + rng() % 3, d.padding = int(rng() % uint64_t(d.kernel / 2 + 1));
    d.inHeight = d.kernel + rng() % 7, d.inWidth = d.kernel + rng() % 7;
    Vec x = randomValues(size_t(d.batch * d.channels * d.inHeight * d.inWidth), rng);
    const size_t outCount = size_t(d.batch * d.channels * d.outHeight() * d.outWidth());
    const Vec r = randomValues(outCount, rng);
    Vec y(outCount);
    std::vector<int32_t> argmax(outCount);
    auto loss = [&] {
        nn::maxPool2dForward(y.data(), argmax.data(), x.data(), d);
        return dot(y, r);
    };
    loss();
    const Vec yDouble = y;
    Vec dx(x.size());
    nn::maxPool2dBackward(dx.data(), r.data(), argmax.data(), d);
    acc.errors.push_back(checkGradient(x, dx, loss, rng, 1e-5, acc, true));
    loss();  // argmax of the unperturbed input again
    const auto xf = toFloat(x), rf = toFloat(r);
    std::vector<float> yf(outCount), dxf(x.size());
    std::vector<int32_t> argmaxF(outCount);
    nn::maxPool2dForward(yf.data(), argmaxF.data(), xf.data(), d);
    nn::maxPool2dBackward(dxf.data(), rf.data(), argmaxF.data(), d);
    acc.row.worstFloat = std::max({acc.row.worstFloat, floatError(yf, yDouble), floatError(dxf, dx)});
}

void activationCase(Rng& rng, Accumulator& acc) {
    nn::ActivationDesc d;
    const nn::Activation kinds[] = {nn::Activation::ReLU, nn::Activation::LeakyReLU, nn::Activation::Sigmoid,
                                    nn::Activation::Clamp};
    d.kind = kinds[rng() % 4];
    d.slope = float(0.01 + 0.3 * double(rng() % 1000) / 1000.0);
    d.low = -0.5f, d.high = 0.7f;
    const size_t n = 16 + rng() % 200;
    Vec x = randomValues(n, rng, -4, 4), y(n);
    const Vec r = randomValues(n, rng);
    auto loss = [&] {
        nn::activationForward(y.data(), x.data(), int64_t(n), d);
        return dot(y, r);
    };
    loss();
    const Vec yDouble = y;
    Vec dx(n);
    nn::activationBackward(dx.data(), r.data(), x.data(), y.data(), int64_t(n), d);
    acc.errors.push_back(checkGradient(x, dx, loss, rng, 1e-5, acc, d.kind != nn::Activation::Sigmoid));
    const auto xf = toFloat(x), rf = toFloat(r);
    std::vector<float> yf(n), dxf(n);
    nn::activationForward(yf.data(), xf.data(), int64_t(n), d);
    nn::activationBackward(dxf.data(), rf.data(), xf.data(), yf.data(), int64_t(n), d);
    acc.row.worstFloat = std::max({acc.row.worstFloat, floatError(yf, yDouble), floatError(dxf, dx)});
}

void resampleCase(Rng& rng, Accumulator& acc) {
    nn::ResampleDesc d;
    d.factor = 2 + int(rng() % 2);
    const bool shuffle = rng() % 2 == 0;
    d.batch = 1 + rng() % 2, d.inHeight = 1 + rng() % 6, d.inWidth = 1 + rng() % 6;
    d.channels = shuffle ? int64_t(d.factor * d.factor) * int64_t(1 + rng() % 2) : int64_t(1 + rng() % 3);
    const size_t in = size_t(d.batch * d.channels * d.inHeight * d.inWidth);
    const size_t out = shuffle ? in : in * size_t(d.factor * d.factor);
    Vec x = randomValues(in, rng), y(out);
    const Vec r = randomValues(out, rng);
    auto loss = [&] {
        shuffle ? nn::pixelShuffleForward(y.data(), x.data(), d)
                : nn::upsampleBilinearForward(y.data(), x.data(), d);
        return dot(y, r);
    };
    loss();
    const Vec yDouble = y;
    Vec dx(in);
    shuffle ? nn::pixelShuffleBackward(dx.data(), r.data(), d)
            : nn::upsampleBilinearBackward(dx.data(), r.data(), d);
    acc.errors.push_back(checkGradient(x, dx, loss, rng, 1e-5, acc));
    const auto xf = toFloat(x), rf = toFloat(r);
    std::vector<float> yf(out), dxf(in);
    shuffle ? nn::pixelShuffleForward(yf.data(), xf.data(), d)
            : nn::upsampleBilinearForward(yf.data(), xf.data(), d);
    shuffle ? nn::pixelShuffleBackward(dxf.data(), rf.data(), d)
            : nn::upsampleBilinearBackward(dxf.data(), rf.data(), d);
    acc.row.worstFloat = std::max({acc.row.worstFloat, floatError(yf, yDouble), floatError(dxf, dx)});
}

void lossCase(Rng& rng, Accumulator& acc, const char* spec) {
    nn::SsimLossDesc d;
    d.batch = 1 + rng() % 2, d.channels = 1 + rng() % 3, d.height = 11 + rng() % 8, d.width = 11 + rng() % 8;
    d.dataRange = rng() % 4 == 0 ? 10.0 : 1.0;
    const size_t n = size_t(d.batch * d.channels * d.height * d.width);
    Vec target = randomValues(n, rng, 0.0, d.dataRange), pred = randomValues(n, rng, 0.0, d.dataRange);
    const nn::CompositeLoss loss = nn::CompositeLoss::parse(spec);
    Vec dpred(n);
    const double value = loss.evaluate(dpred.data(), pred.data(), target.data(), d);
    auto scalar = [&] { return loss.evaluate<double>(nullptr, pred.data(), target.data(), d); };
    const bool piecewise = std::string(spec).find("l1") != std::string::npos;
    acc.errors.push_back(checkGradient(pred, dpred, scalar, rng, 1e-4 * d.dataRange, acc, piecewise));
    const auto pf = toFloat(pred), tf = toFloat(target);
    std::vector<float> dpf(n);
    const double valueFloat = loss.evaluate(dpf.data(), pf.data(), tf.data(), d);
    acc.row.worstFloat =
        std::max({acc.row.worstFloat, std::abs(valueFloat - value) / std::max(std::abs(value), 1e-30),
                  floatError(dpf, dpred)});
}

}  // namespace

std::vector<StabilityRow> benchStability(const StabilityOptions& options) {
    using Case = std::function<void(Rng&, Accumulator&)>;
    const std::vector<std::pair<std::string, Case>> kinds = {
        {"conv2d", conv2dCase},
        {"conv_transpose2d", convTransposeCase},
        {"max_pool2d", maxPoolCase},
        {"activation", activationCase},
        {"upsample/pixel_shuffle", resampleCase},
        {"loss 1-ssim", [](Rng& r, Accumulator& a) { lossCase(r, a, "ssim"); }},
        {"loss l1", [](Rng& r, Accumulator& a) { lossCase(r, a, "l1"); }},
        {"loss mse", [](Rng& r, Accumulator& a) { lossCase(r, a, "mse"); }},
        {"loss 0.84*ssim+0.16*l1", [](Rng& r, Accumulator& a) { lossCase(r, a, "0.84*ssim+0.16*l1"); }},
    };
    std::vector<Accumulator> accumulators(kinds.size());
    Rng rng(options.seed);
    for (int c = 0; c < options.configurations; ++c) {
        const size_t k = size_t(c) % kinds.size();
        kinds[k].second(rng, accumulators[k]);
        ++accumulators[k].row.configurations;
    }
    std::vector<StabilityRow> rows;
    for (size_t k = 0; k < kinds.size(); ++k) {
        Accumulator& acc = accumulators[k];
        acc.row.kind = kinds[k].first;
        if (!acc.errors.empty()) {
            std::sort(acc.errors.begin(), acc.errors.end());
            acc.row.worstGradient = acc.errors.back();
            acc.row.medianGradient = acc.errors[acc.errors.size() / 2];
            acc.row.overTolerance = int(std::count_if(acc.errors.begin(), acc.errors.end(),
                                                      [&](double e) { return e > options.tolerance; }));
        }
        rows.push_back(acc.row);
    }
    return rows;
}

std::vector<SsimDegenerateRow> ssimDegenerateChecks() {
    constexpr int64_t kSide = 16, kCount = kSide * kSide;
    const nn::SsimLossDesc desc{1, 1, kSide, kSide, 1.0};
    struct Patch {
        std::string name;
        Vec pred, target;
        double step;  // h, relative to the values' scale
    };
    std::vector<Patch> patches;
    auto filled = [&](double v) { return Vec(kCount, v); };
    patches.push_back({"constant, equal (zero variance)", filled(0.5), filled(0.5), 1e-4});
    patches.push_back({"constant, different", filled(0.2), filled(0.9), 1e-4});
    Vec spike = filled(0.0);
    spike[kCount / 2 + kSide / 2] = 1.0;
    patches.push_back({"single bright pixel", spike, filled(0.0), 1e-4});
    Rng rng(17);
    Vec hdr(kCount), hdrTarget(kCount), tiny(kCount), checker(kCount), inverted(kCount);
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int64_t i = 0; i < kCount; ++i) {
        hdr[size_t(i)] = std::pow(10.0, 4.0 * unit(rng));  // 1 .. 1e4
        hdrTarget[size_t(i)] = hdr[size_t(i)] * (1.0 + 0.01 * (unit(rng) - 0.5));
        tiny[size_t(i)] = 1e-8 * unit(rng);
        checker[size_t(i)] = double(((i % kSide) + (i / kSide)) % 2);
        inverted[size_t(i)] = 1.0 - checker[size_t(i)];
    }
    patches.push_back({"HDR up to 1e4", hdr, hdrTarget, 1e-1});
    // (A step near the values: smaller ones move the loss by less than its rounding, 1e-16.)
    patches.push_back({"tiny values (1e-8)", tiny, filled(0.0), 1e-8});
    patches.push_back({"checkerboard at Nyquist vs 0.5", checker, filled(0.5), 1e-4});
    patches.push_back({"checkerboard vs its inverse", checker, inverted, 1e-4});

    std::vector<SsimDegenerateRow> rows;
    for (Patch& p : patches) {
        SsimDegenerateRow row;
        row.patch = p.name;
        Vec direction = randomValues(size_t(kCount), rng);
        const double norm = std::sqrt(dot(direction, direction));
        for (double& d : direction) d /= norm;
        auto lossAt = [&](double t) {
            Vec x = p.pred;
            for (size_t i = 0; i < x.size(); ++i) x[i] += t * direction[i];
            return nn::ssimLoss(x.data(), p.target.data(), desc);
        };
        row.loss = lossAt(0.0);
        Vec gradient(size_t(kCount), 0.0);
        nn::ssimLossBackward(gradient.data(), p.pred.data(), p.target.data(), desc, 1.0);
        row.finite = std::isfinite(row.loss) &&
                     std::all_of(gradient.begin(), gradient.end(), [](double g) { return std::isfinite(g); });
        const double h = p.step;
        const double analytic = dot(gradient, direction), numeric = (lossAt(h) - lossAt(-h)) / (2.0 * h);
        const double floor = 1e-6 * std::sqrt(dot(gradient, gradient)) + 1e-12;
        row.directionalError =
            std::abs(numeric - analytic) / std::max({std::abs(numeric), std::abs(analytic), floor});
        auto largestSlope = [&](double dt) {
            double slope = 0;
            for (int k = 0; k <= 40; ++k) {
                const double t = (k - 20) * h, a = lossAt(t), b = lossAt(t + dt);
                slope = std::max(slope, std::abs(b - a) / dt);
                row.finite = row.finite && std::isfinite(a) && std::isfinite(b);
            }
            return slope;
        };
        row.slope = largestSlope(h), row.slopeFine = largestSlope(h / 100.0);
        // The loss is 1 - mean SSIM: near a perfect match (tiny values) it is known to ~1e-16 absolute,
        // so differences of it carry that rounding over their step; the checks allow it, no more.
        const double rounding = 64.0 * std::numeric_limits<double>::epsilon();
        const bool derivativeOk =
            std::abs(numeric - analytic) <=
            1e-4 * std::max({std::abs(numeric), std::abs(analytic), floor}) + rounding / h;
        row.passed = row.finite && derivativeOk && row.slopeFine <= 2.0 * row.slope + rounding / (h / 100.0);
        rows.push_back(row);
    }
    return rows;
}

}  // namespace dejag::bench

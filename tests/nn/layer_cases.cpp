// The layer cases of the op harness: each golden fixture of tests/golden/nn made into the layer call it
// checks, and the random shapes of the gradient checks (seeded, so the same shapes every run).
#include "tests/nn/layer_cases.h"

#include <algorithm>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <random>

#include "nn/layers.h"
#include "nn/safetensors.h"
#include "tests/test_util.h"

namespace dejag::nn::harness {
namespace {

using nlohmann::json;

std::string describe(const Conv2dDesc& d) {
    return "N" + std::to_string(d.batch) + " Cin" + std::to_string(d.inChannels) + " Cout" +
           std::to_string(d.outChannels) + " " + std::to_string(d.inHeight) + "x" +
           std::to_string(d.inWidth) + " k" + std::to_string(d.kernelHeight) + "x" +
           std::to_string(d.kernelWidth) + " s" + std::to_string(d.strideH) + "," +
           std::to_string(d.strideW) + " d" + std::to_string(d.dilationH) + "," +
           std::to_string(d.dilationW) + " pad " + std::to_string(d.padTop) + "," +
           std::to_string(d.padBottom) + "," + std::to_string(d.padLeft) + "," + std::to_string(d.padRight) +
           (d.bias ? " bias" : " no bias");
}
std::string describe(const ConvTranspose2dDesc& d) {
    return "N" + std::to_string(d.batch) + " Cin" + std::to_string(d.inChannels) + " Cout" +
           std::to_string(d.outChannels) + " " + std::to_string(d.inHeight) + "x" +
           std::to_string(d.inWidth) + " k" + std::to_string(d.kernelHeight) + "x" +
           std::to_string(d.kernelWidth) + " s" + std::to_string(d.strideH) + "," +
           std::to_string(d.strideW) + " d" + std::to_string(d.dilationH) + "," +
           std::to_string(d.dilationW) + " pad " + std::to_string(d.padH) + "," + std::to_string(d.padW) +
           " op " + std::to_string(d.outputPaddingH) + "," + std::to_string(d.outputPaddingW) +
           (d.bias ? " bias" : " no bias");
}
std::string describe(const MaxPool2dDesc& d) {
    return "N" + std::to_string(d.batch) + " C" + std::to_string(d.channels) + " " +
           std::to_string(d.inHeight) + "x" + std::to_string(d.inWidth) + " k" + std::to_string(d.kernel) +
           " s" + std::to_string(d.stride) + " pad " + std::to_string(d.padding);
}
std::string describe(const ResampleDesc& d) {
    return "N" + std::to_string(d.batch) + " C" + std::to_string(d.channels) + " " +
           std::to_string(d.inHeight) + "x" + std::to_string(d.inWidth) + " factor " +
           std::to_string(d.factor);
}
std::string describe(const KernelFilterDesc& d) {
    return "N" + std::to_string(d.batch) + " C" + std::to_string(d.channels) + " " +
           std::to_string(d.height) + "x" + std::to_string(d.width) + " k" + std::to_string(d.kernel) +
           " centre bias " + std::to_string(d.centreBias) + (d.history ? " history" : "");
}

std::string describe(const WarpDesc& d) {
    return "N" + std::to_string(d.batch) + " C" + std::to_string(d.channels) + " " +
           std::to_string(d.height) + "x" + std::to_string(d.width) + " " + warpFilterName(d.filter);
}

// A convolution's case (conv2d or conv_transpose2d: input, weight and an optional bias), given its layer
// functions as generic lambdas forward(out, in, weight, bias) and backward(dIn, dWeight, dBias, dOut, in,
// weight).
template <class Desc, class F, class B>
LayerCase convolution(const std::string& label, const Desc& d, F forward, B backward) {
    const size_t out = size_t(d.batch * d.outChannels * d.outHeight() * d.outWidth());
    std::vector<std::string> names{"input", "weight"};
    std::vector<size_t> sizes{size_t(d.batch * d.inChannels * d.inHeight * d.inWidth),
                              size_t(d.weightCount())};
    if (d.bias) names.push_back("bias"), sizes.push_back(size_t(d.outChannels));
    return layerCase(
        label + ": " + describe(d), names, sizes, out,
        [d, forward](const auto& call) {
            forward(call.out, call.in[0], call.in[1], d.bias ? call.in[2] : nullptr);
        },
        [d, backward](const auto& g) {
            backward(g.dIn[0], g.dIn[1], d.bias ? g.dIn[2] : nullptr, g.dOut, g.in[0], g.in[1]);
        });
}

LayerCase conv2d(const std::string& label, const Conv2dDesc& d) {
    return convolution(
        "conv2d " + label, d, [d](auto* out, auto in, auto w, auto b) { conv2dForward(out, in, w, b, d); },
        [d](auto* di, auto* dw, auto* db, auto dout, auto in, auto w) {
            conv2dBackward(di, dw, db, dout, in, w, d);
        });
}

LayerCase convTranspose2d(const std::string& label, const ConvTranspose2dDesc& d) {
    return convolution(
        "conv_transpose2d " + label, d,
        [d](auto* out, auto in, auto w, auto b) { convTranspose2dForward(out, in, w, b, d); },
        [d](auto* di, auto* dw, auto* db, auto dout, auto in, auto w) {
            convTranspose2dBackward(di, dw, db, dout, in, w, d);
        });
}

LayerCase maxPool2d(const std::string& label, const MaxPool2dDesc& d) {
    const size_t out = size_t(d.batch * d.channels * d.outHeight() * d.outWidth());
    auto argmax = std::make_shared<std::vector<int32_t>>(out);  // the forward's, for the backward
    LayerCase c = layerCase(
        "maxpool2d " + label + ": " + describe(d), {"input"},
        {size_t(d.batch * d.channels * d.inHeight * d.inWidth)}, out,
        [d, argmax](const auto& call) { maxPool2dForward(call.out, argmax->data(), call.in[0], d); },
        [d, argmax](const auto& g) { maxPool2dBackward(g.dIn[0], g.dOut, argmax->data(), d); });
    c.piecewise = true;
    return c;
}

LayerCase activation(const std::string& label, const ActivationDesc& d, size_t n) {
    LayerCase c = layerCase(
        std::string("activation ") + activationName(d.kind) + " " + label, {"input"}, {n}, n,
        [d, n](const auto& call) { activationForward(call.out, call.in[0], int64_t(n), d); },
        [d, n](const auto& g) { activationBackward(g.dIn[0], g.dOut, g.in[0], g.out, int64_t(n), d); });
    c.piecewise = d.kind != Activation::Sigmoid && d.kind != Activation::None;
    c.inputLow = -3, c.inputHigh = 3;
    return c;
}

// kind: "nearest", "bilinear" or "pixel_shuffle".
LayerCase resample(const std::string& label, const std::string& kind, const ResampleDesc& d) {
    const size_t in = size_t(d.batch * d.channels * d.inHeight * d.inWidth);
    const size_t out = kind == "pixel_shuffle" ? in : in * size_t(d.factor * d.factor);
    return layerCase(
        kind + " " + label + ": " + describe(d), {"input"}, {in}, out,
        [d, kind](const auto& call) {
            if (kind == "nearest")
                upsampleNearestForward(call.out, call.in[0], d);
            else if (kind == "bilinear")
                upsampleBilinearForward(call.out, call.in[0], d);
            else
                pixelShuffleForward(call.out, call.in[0], d);
        },
        [d, kind](const auto& g) {
            if (kind == "nearest")
                upsampleNearestBackward(g.dIn[0], g.dOut, d);
            else if (kind == "bilinear")
                upsampleBilinearBackward(g.dIn[0], g.dOut, d);
            else
                pixelShuffleBackward(g.dIn[0], g.dOut, d);
        });
}

LayerCase kernelFilter(const std::string& label, const KernelFilterDesc& d) {
    const size_t image = size_t(d.batch * d.channels * d.height * d.width),
                 logits = size_t(d.batch * d.weights() * d.height * d.width);
    std::vector<std::string> names = {"input", "logits"};
    std::vector<size_t> sizes = {image, logits};
    if (d.history) names.push_back("history"), sizes.push_back(image);
    LayerCase c = layerCase(
        "kernel_filter " + label + ": " + describe(d), names, sizes, image,
        [d](const auto& call) {
            kernelFilterForward(call.out, call.in[0], call.in[1], d, d.history ? call.in[2] : nullptr);
        },
        [d](const auto& g) {
            kernelFilterBackward(g.dIn[0], g.dIn[1], g.dOut, g.in[0], g.in[1], d,
                                 d.history ? g.dIn[2] : nullptr, d.history ? g.in[2] : nullptr);
        });
    c.inputLow = -3, c.inputHigh = 3;
    return c;
}

// The accumulate blend: image, logits and history (colour and confidence) drawn from [0, 1), the
// history's confidence inside the clamp but for the capped cases' largest.
LayerCase accumulate(const std::string& label, const AccumulateDesc& d) {
    const int64_t plane = d.height * d.width;
    const size_t image = size_t(d.batch * d.channels * plane),
                 logits = size_t(d.batch * (d.taps() + 1) * plane),
                 history = size_t(d.batch * (d.channels + 1) * plane);
    LayerCase c = layerCase(
        "accumulate " + label + ": N" + std::to_string(d.batch) + " C" + std::to_string(d.channels) + " " +
            std::to_string(d.height) + "x" + std::to_string(d.width) + " k" + std::to_string(d.kernel) +
            " max count " + std::to_string(d.maxCount) + (d.clip ? " clip" : ""),
        {"input", "logits", "history"}, {image, logits, history},
        image * 2 + history / size_t(d.channels + 1),
        [d](const auto& call) { accumulateForward(call.out, call.in[0], call.in[1], call.in[2], d); },
        [d](const auto& g) {
            accumulateBackward(g.dIn[0], g.dIn[1], g.dIn[2], g.dOut, g.in[0], g.in[1], g.in[2], d);
        });
    c.inputLow = 0, c.inputHigh = 0.97;
    c.piecewise = d.maxCount < 100;  // the clamp and the cap
    return c;
}

// The motion warp: input and motion (up to `reach` pixels, so that reads leave the image at its borders).
LayerCase warp(const std::string& label, const WarpDesc& d, double reach) {
    const size_t image = size_t(d.batch * d.channels * d.height * d.width),
                 motion = size_t(d.batch * 2 * d.height * d.width);
    LayerCase c = layerCase(
        "warp " + label + ": " + describe(d), {"input", "motion"}, {image, motion}, image,
        [d](const auto& call) { warpForward(call.out, call.in[0], call.in[1], d); },
        [d](const auto& g) { warpBackward(g.dIn[0], g.dIn[1], g.dOut, g.in[0], g.in[1], d); });
    c.inputLow = -reach, c.inputHigh = reach;
    c.piecewise = d.filter == WarpFilter::Bilinear;  // its weights have kinks at whole pixels
    return c;
}

// The golden fixtures of the layers (losses and optimizers are not layers: tests/nn/golden_test.cpp).
void goldenCases(std::vector<LayerCase>& cases) {
    const std::filesystem::path folder = ::dejag::testing::sourcePath("tests/golden/nn");
    std::vector<std::filesystem::path> files;
    for (const auto& entry : std::filesystem::directory_iterator(folder))
        if (entry.path().extension() == ".safetensors") files.push_back(entry.path());
    std::sort(files.begin(), files.end());
    for (const std::filesystem::path& file : files) {
        const std::string name = file.stem().string();
        const json c = json::parse(readSafetensors(file.string()).metadata.at("config"));
        const std::string layer = c["layer"];
        const std::string label = "golden " + name;
        LayerCase lc;
        if (layer == "conv2d") {
            Conv2dDesc d;
            d.batch = c["batch"], d.inChannels = c["in_channels"], d.outChannels = c["out_channels"];
            d.inHeight = c["height"], d.inWidth = c["width"];
            d.kernelHeight = c["kernel"][0], d.kernelWidth = c["kernel"][1];
            d.strideH = d.strideW = c["stride"];
            d.padTop = c["pad"][0], d.padBottom = c["pad"][1], d.padLeft = c["pad"][2],
            d.padRight = c["pad"][3];
            d.dilationH = d.dilationW = c["dilation"];
            d.bias = c["bias"];
            lc = conv2d(label, d);
        } else if (layer == "conv_transpose2d") {
            ConvTranspose2dDesc d;
            d.batch = c["batch"], d.inChannels = c["in_channels"], d.outChannels = c["out_channels"];
            d.inHeight = c["height"], d.inWidth = c["width"];
            d.kernelHeight = d.kernelWidth = c["kernel"];
            d.strideH = d.strideW = c["stride"];
            d.padH = d.padW = c["pad"];
            d.outputPaddingH = d.outputPaddingW = c["output_padding"];
            d.dilationH = d.dilationW = c["dilation"];
            d.bias = c["bias"];
            lc = convTranspose2d(label, d);
        } else if (layer == "maxpool2d") {
            MaxPool2dDesc d;
            d.batch = c["batch"], d.channels = c["channels"], d.inHeight = c["height"],
            d.inWidth = c["width"];
            d.kernel = c["kernel"], d.stride = c["stride"], d.padding = c["pad"];
            lc = maxPool2d(label, d);
        } else if (layer == "activation") {
            ActivationDesc d;
            d.kind = parseActivation(c["kind"]);
            if (c.contains("slope")) d.slope = c["slope"];
            if (c.contains("low")) d.low = c["low"], d.high = c["high"];
            const size_t n = readSafetensors(file.string()).at("input").asFloat().size();
            lc = activation(label, d, n);
        } else if (layer == "nearest" || layer == "bilinear" || layer == "pixel_shuffle") {
            ResampleDesc d;
            d.batch = c["batch"], d.channels = c["channels"], d.inHeight = c["height"],
            d.inWidth = c["width"];
            d.factor = c["factor"];
            lc = resample(label, layer, d);
        } else if (layer == "kernel_filter") {
            KernelFilterDesc d;
            d.batch = c["batch"], d.channels = c["channels"], d.height = c["height"], d.width = c["width"];
            d.kernel = c["kernel"], d.centreBias = c["centre_bias"];
            d.history = c.value("history", false);
            lc = kernelFilter(label, d);
        } else if (layer == "accumulate") {
            AccumulateDesc d;
            d.batch = c["batch"], d.channels = c["channels"], d.height = c["height"], d.width = c["width"];
            d.kernel = c["kernel"], d.maxCount = c["max_count"], d.clip = c.value("clip", false);
            lc = accumulate(label, d);
        } else if (layer == "warp") {
            WarpDesc d;
            d.batch = c["batch"], d.channels = c["channels"], d.height = c["height"], d.width = c["width"];
            d.filter = parseWarpFilter(c["filter"]);
            lc = warp(label, d, 1.0);
        } else {
            continue;  // a loss or an optimizer
        }
        lc.golden = name;
        cases.push_back(std::move(lc));
    }
}

// The random shapes of the gradient checks, each layer from its own seed.
void randomCases(std::vector<LayerCase>& cases) {
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
        cases.push_back(conv2d("random " + std::to_string(trial), d));
    }
    rng.seed(2);
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
        cases.push_back(convTranspose2d("random " + std::to_string(trial), d));
    }
    rng.seed(3);
    for (int trial = 0; trial < 16; ++trial) {
        MaxPool2dDesc d;
        d.batch = 1 + rng() % 2, d.channels = 1 + rng() % 3;
        d.kernel = 1 + rng() % 3, d.stride = 1 + rng() % 3, d.padding = rng() % (d.kernel / 2 + 1);
        d.inHeight = d.kernel + rng() % 6, d.inWidth = d.kernel + rng() % 6;
        cases.push_back(maxPool2d("random " + std::to_string(trial), d));
    }
    for (Activation kind : {Activation::None, Activation::ReLU, Activation::LeakyReLU, Activation::Sigmoid,
                            Activation::Clamp}) {
        ActivationDesc d;
        d.kind = kind, d.slope = 0.2f, d.low = -0.5f, d.high = 0.7f;
        cases.push_back(activation("97 values", d, 97));
    }
    for (int factor : {2, 3})
        for (const char* kind : {"nearest", "bilinear", "pixel_shuffle"}) {
            if (std::string(kind) == "pixel_shuffle" && factor == 3) continue;  // channels % factor^2 == 0
            cases.push_back(resample("random", kind, ResampleDesc{2, 4, 3, 5, factor}));
        }
    rng.seed(9);
    for (int trial = 0; trial < 6; ++trial) {
        KernelFilterDesc d;
        d.batch = 1 + int(rng() % 2), d.channels = 1 + int(rng() % 3);
        d.height = 1 + int(rng() % 6), d.width = 1 + int(rng() % 7);  // smaller than the kernel too
        d.kernel = 1 + 2 * int(rng() % 3);
        d.centreBias = float(int(rng() % 5) - 1);
        d.history = trial % 2 == 1;
        cases.push_back(kernelFilter("random " + std::to_string(trial), d));
    }
    rng.seed(11);
    for (int trial = 0; trial < 6; ++trial) {
        AccumulateDesc d;
        d.batch = 1 + int(rng() % 2), d.channels = 1 + int(rng() % 3);
        d.height = 1 + int(rng() % 6), d.width = 1 + int(rng() % 7);
        d.kernel = 1 + 2 * int(rng() % 2);
        d.maxCount = trial % 3 == 2 ? 4.0f : 1000.0f;
        cases.push_back(accumulate("random " + std::to_string(trial), d));
    }
    rng.seed(12);
    for (int trial = 0; trial < 4; ++trial) {  // the history clamped to the neighbourhood
        AccumulateDesc d;
        d.batch = 1 + int(rng() % 2), d.channels = 1 + int(rng() % 3);
        d.height = 2 + int(rng() % 5), d.width = 2 + int(rng() % 6);
        d.kernel = trial == 3 ? 1 : 3, d.clip = true;
        d.maxCount = trial % 2 == 1 ? 4.0f : 1000.0f;
        cases.push_back(accumulate("clip random " + std::to_string(trial), d));
    }
    rng.seed(10);
    for (int trial = 0; trial < 9; ++trial) {
        WarpDesc d;
        d.batch = 1 + int(rng() % 2), d.channels = 1 + int(rng() % 3);
        d.height = 1 + int(rng() % 7), d.width = 1 + int(rng() % 8);  // smaller than the taps too
        d.filter = WarpFilter(trial % 3);
        cases.push_back(warp("random " + std::to_string(trial), d, 1.0 + double(trial % 4)));
    }
}

}  // namespace

std::vector<LayerCase> goldenLayerCases() {
    std::vector<LayerCase> cases;
    goldenCases(cases);
    return cases;
}

std::vector<LayerCase> randomLayerCases() {
    std::vector<LayerCase> cases;
    randomCases(cases);
    return cases;
}

}  // namespace dejag::nn::harness

// ONNX export (nn/onnx.h) checked by independent runtimes: OpenCV's DNN module loads each exported file
// and its output must match Model::forward within 1e-4, for every op the exporter writes and for the
// shipped single-frame models, at fixed sizes (OpenCV 4.6 cannot infer shapes at a symbolic one). The
// warp's GatherElements is beyond OpenCV 4.6: those exports are checked against golden outputs of a NumPy
// evaluator of the ONNX operators (tests/golden/make_onnx_golden.py).
#include "nn/onnx.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <nlohmann/json.hpp>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/dnn.hpp>

#include "base/error.h"
#include "base/random.h"
#include "nn/init.h"
#include "nn/safetensors.h"
#include "tests/nn/exportable_ops.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

Tensor randomInput(const Shape& shape, uint64_t seed) {
    Tensor t(shape);
    Rng rng(seed);
    for (int64_t i = 0; i < t.numel(); ++i) t.data()[i] = rng.uniform(0.0f, 1.0f);
    return t;
}

// The largest |OpenCV - dejag| over the output, from the exported bytes.
double largestDifference(Model& model, const std::string& onnx, const Tensor& input) {
    cv::utils::logging::setLogLevel(cv::utils::logging::LOG_LEVEL_ERROR);
    cv::dnn::Net net = cv::dnn::readNetFromONNX(onnx.data(), onnx.size());
    const Shape& s = input.shape();
    const int dims[4] = {int(s[0]), int(s[1]), int(s[2]), int(s[3])};
    cv::Mat blob(4, dims, CV_32F, const_cast<float*>(input.data()));
    net.setInput(blob, "input");
    const cv::Mat out = net.forward("output");
    const Tensor& expected = model.forward(input);
    EXPECT_EQ(int64_t(out.total()), expected.numel());
    if (int64_t(out.total()) != expected.numel()) return 1e9;
    double worst = 0;
    const float* got = out.ptr<float>();
    for (int64_t i = 0; i < expected.numel(); ++i)
        worst = std::max(worst, std::abs(double(got[i]) - double(expected.data()[i])));
    std::printf("largest |OpenCV - dejag| %.3g\n", worst);
    return worst;
}

TEST(Onnx, EveryExportableOpMatchesOpenCvDnn) {
    Model model = Model::fromArchitecture(everyExportableOp());
    model.initialize(7);
    // Biases too, so that a bias in the wrong place shows.
    Rng rng(3);
    for (const ParameterInfo& p : model.parameters())
        if (p.isBias)
            for (int64_t i = 0; i < p.shape[0]; ++i)
                model.parameterData()[p.offset + i] = rng.uniform(-0.3f, 0.3f);
    for (auto [width, height] : {std::pair{40, 24}, std::pair{38, 22}}) {
        OnnxOptions options;
        options.width = width, options.height = height;
        const Tensor input = randomInput({1, 4, height, width}, 11);
        EXPECT_LE(largestDifference(model, exportOnnx(model, options), input), 1e-4)
            << width << "x" << height;
    }
}

TEST(Onnx, ShippedSingleFrameModelsMatchOpenCvDnn) {
    for (const char* name : {"dejag-fast", "dejag-guided", "seed2020-gray"}) {
        Model model = loadModel(testing::sourcePath(std::string("models/") + name + ".safetensors"));
        const Tensor input = randomInput({1, model.inputChannels(), 48, 64}, 5);
        OnnxOptions options;
        options.width = 64, options.height = 48;
        EXPECT_LE(largestDifference(model, exportOnnx(model, options), input), 1e-4) << name << " fixed";
        // OpenCV 4.6 cannot infer shapes at a symbolic size: that export is checked by python3-onnx's
        // checker with strict shape inference (tests/golden/check_onnx.py); here, that its size is symbolic.
        EXPECT_NE(exportOnnx(model).find("height"), std::string::npos);
    }
}

// The accumulate blend (the recurrent network's output) without a warp: OpenCV 4.6 reads every operator
// of its decomposition. Input channels: the frame 0..2, the logits 3..12, the history 13..16.
TEST(Onnx, AccumulateMatchesOpenCvDnn) {
    using nlohmann::json;
    const auto slice = [](const char* name, int from, int to) {
        return json{{"name", name}, {"op", "slice"}, {"inputs", {"input"}}, {"from", from}, {"to", to}};
    };
    json nodes = {slice("frame", 0, 3), slice("logits", 3, 13), slice("history", 13, 17)};
    nodes.push_back({{"name", "kept"},
                     {"op", "accumulate"},
                     {"inputs", {"frame", "logits", "history"}},
                     {"kernel", 3},
                     {"max_count", 32}});
    nodes.push_back({{"name", "clipped"},
                     {"op", "accumulate"},
                     {"inputs", {"frame", "logits", "history"}},
                     {"kernel", 3},
                     {"max_count", 8},
                     {"clip", true}});
    nodes.push_back({{"name", "out"}, {"op", "concat"}, {"inputs", {"kept", "clipped"}}});
    Model model = Model::fromArchitecture(
        {{"name", "accumulate_only"}, {"input_channels", 17}, {"nodes", nodes}, {"output", "out"}});
    Tensor input = randomInput({1, 17, 20, 28}, 9);
    Rng rng(4);
    const int64_t plane = 20 * 28;
    for (int64_t i = 3 * plane; i < 13 * plane; ++i) input.data()[i] = rng.uniform(-4.0f, 4.0f);  // logits
    // The confidence from below 0 to above N / (N + 1) (clamped).
    for (int64_t i = 16 * plane; i < 17 * plane; ++i) input.data()[i] = rng.uniform(-0.1f, 1.0f);
    OnnxOptions options;
    options.width = 28, options.height = 20;
    EXPECT_LE(largestDifference(model, exportOnnx(model, options), input), 1e-4);
}

// The ModelProto's graph (field 7, length-delimited) as bytes: what onnx.load(...).graph.SerializeToString()
// gives for dejag's files, whose graph fields are in field-number order.
std::string graphBytes(const std::string& model) {
    size_t at = 0;
    const auto varint = [&] {
        uint64_t value = 0;
        for (int shift = 0; at < model.size(); shift += 7) {
            const auto byte = static_cast<unsigned char>(model[at++]);
            value |= uint64_t(byte & 0x7f) << shift;
            if (!(byte & 0x80)) break;
        }
        return value;
    };
    while (at < model.size()) {
        const uint64_t key = varint();
        switch (key & 7) {
            case 0:
                varint();
                break;
            case 1:
                at += 8;
                break;
            case 5:
                at += 4;
                break;
            case 2: {
                const size_t length = size_t(varint());
                if (key >> 3 == 7) return model.substr(at, length);
                at += length;
                break;
            }
            default:
                return {};
        }
    }
    return {};
}

// FNV-1a 64 of some bytes, as make_onnx_golden.py computes it.
std::string fnv1a(const std::string& bytes) {
    uint64_t h = 0xcbf29ce484222325ull;
    for (unsigned char c : bytes) h = (h ^ c) * 0x100000001b3ull;
    char text[17];
    std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(h));
    return text;
}

// The warps (GatherElements, which OpenCV 4.6 cannot load) and the whole recurrent network, against the
// outputs of tests/golden/check_onnx.py's NumPy evaluator of the same exported files
// (tests/golden/make_onnx_golden.py): two steps each, the second dejag-temporal step on the first's output.
TEST(Onnx, RecurrentExportsMatchTheGoldenEvaluation) {
    for (const char* name : {"recurrent_ops", "dejag_temporal"}) {
        SCOPED_TRACE(name);
        const SafetensorsFile golden = readSafetensors(
            testing::sourcePath(std::string("tests/golden/onnx/") + name + ".golden.safetensors"));
        const nlohmann::json config = nlohmann::json::parse(golden.metadata.at("config"));
        const std::string modelName = config["model"];
        Model model = loadModel(testing::sourcePath(
            modelName.find('/') == std::string::npos ? "models/" + modelName + ".safetensors" : modelName));
        OnnxOptions options;
        options.width = config["width"], options.height = config["height"];
        const std::string onnx = exportOnnx(model, options);
        ASSERT_EQ(fnv1a(graphBytes(onnx)), config["graph_fnv1a"].get<std::string>())
            << "the export changed since the golden evaluation: run make golden";
        for (int step = 0; step < 2; ++step) {
            const StoredTensor& in = golden.at("input" + std::to_string(step));
            Tensor input(in.shape);
            std::copy(in.f32.begin(), in.f32.end(), input.data());
            const std::vector<double> expected = golden.at("output" + std::to_string(step)).asDouble();
            const Tensor& out = model.forward(input);
            ASSERT_EQ(out.numel(), int64_t(expected.size()));
            double worst = 0;
            for (int64_t i = 0; i < out.numel(); ++i)
                worst = std::max(worst, std::abs(double(out.data()[i]) - expected[size_t(i)]));
            std::printf("%s step %d: largest |evaluator - dejag| %.3g\n", name, step, worst);
            EXPECT_LE(worst, 1e-4) << "step " << step;
        }
    }
}

TEST(Onnx, ImpossibleSizesAreRefused) {
    Model fast = loadModel(testing::sourcePath("models/dejag-fast.safetensors"));
    OnnxOptions options;
    options.width = 30, options.height = 20;  // not divisible by 8: the U-Net's skips cannot meet
    EXPECT_THROW(exportOnnx(fast, options), Error);
}

}  // namespace
}  // namespace dejag::nn

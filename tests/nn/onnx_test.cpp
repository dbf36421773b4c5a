// ONNX export (nn/onnx.h) checked by an independent runtime: OpenCV's DNN module loads each exported file
// and its output must match Model::forward within 1e-4, for every op the exporter writes and for the
// shipped single-frame models, at fixed sizes (OpenCV 4.6 cannot infer shapes at a symbolic one).
#include "nn/onnx.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <opencv2/core/utils/logger.hpp>
#include <opencv2/dnn.hpp>

#include "base/error.h"
#include "base/random.h"
#include "nn/init.h"
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

TEST(Onnx, RecurrentOpsAndImpossibleSizesAreRefused) {
    Model temporal = loadModel(testing::sourcePath("models/dejag-temporal.safetensors"));
    try {
        exportOnnx(temporal);
        FAIL() << "exported a warp";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("'warped' (warp) has no ONNX form"), std::string::npos)
            << e.what();
    }
    Model fast = loadModel(testing::sourcePath("models/dejag-fast.safetensors"));
    OnnxOptions options;
    options.width = 30, options.height = 20;  // not divisible by 8: the U-Net's skips cannot meet
    EXPECT_THROW(exportOnnx(fast, options), Error);
}

}  // namespace
}  // namespace dejag::nn

#include "bench/accuracy.h"

#include <xmmintrin.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <vector>

#include "base/luma.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "nn/inference.h"
#include "nn/losses.h"
#include "nn/model.h"
#include "nn/optim.h"

namespace dejag::bench {

std::vector<float> accuracyTestFrame(int width, int height) {
    std::vector<float> frame(size_t(3) * size_t(width) * size_t(height));
    const double cx = 0.5 * width, cy = 0.5 * height, radius = 0.45 * std::min(width, height);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            const double u = double(x) / width, v = double(y) / height;
            double value[3] = {0.2 + 0.6 * u, 0.3 + 0.4 * v, 0.5};  // gradients
            const double dx = x - cx, dy = y - cy, r2 = dx * dx + dy * dy;
            if (r2 < radius * radius) {
                // Zone plate: frequency rising to Nyquist at the rim.
                const double zone = 0.5 + 0.5 * std::cos(M_PI * r2 / (radius * 2.0));
                value[0] = value[1] = value[2] = zone;
            }
            // A few hard-edged shapes at odd angles, and one-pixel lines.
            for (int k = 0; k < 7; ++k) {
                const double angle = 0.37 + 0.83 * k, s = std::sin(angle), c = std::cos(angle);
                const double ox = width * (0.1 + 0.12 * k), oy = height * (0.15 + 0.1 * k);
                const double a = (x - ox) * c + (y - oy) * s, b = -(x - ox) * s + (y - oy) * c;
                if (std::abs(a) < 0.06 * width && std::abs(b) < 0.04 * height)
                    value[k % 3] = k % 2 ? 0.95 : 0.05;
            }
            if ((x + 3 * y) % 97 == 0) value[0] = value[1] = value[2] = 1.0;
            for (int c = 0; c < 3; ++c)
                frame[(size_t(c) * size_t(height) + size_t(y)) * size_t(width) + size_t(x)] =
                    float(std::clamp(value[c], 0.0, 1.0));
        }
    return frame;
}

namespace {

// The test frame as the model's input (N = 1): RGB, or the luma for a grey model; a guided model's guide
// is the frame itself (what a guide method gives where it finds no edge).
std::vector<float> modelInput(const nn::Model& model, int width, int height) {
    std::vector<float> rgb = accuracyTestFrame(width, height);
    if (model.inputChannels() == 3) return rgb;
    if (model.inputChannels() == 6) {
        const size_t floats = rgb.size();
        rgb.resize(2 * floats);
        std::copy_n(rgb.begin(), floats, rgb.begin() + std::ptrdiff_t(floats));
        return rgb;
    }
    const size_t plane = size_t(width) * size_t(height);
    std::vector<float> luma(plane);
    for (size_t i = 0; i < plane; ++i) luma[i] = ::dejag::luma(rgb[i], rgb[plane + i], rgb[2 * plane + i]);
    return luma;
}

}  // namespace

AccumulationResult benchAccumulation(const std::string& modelPath, int width, int height) {
    const nn::Model model = nn::loadModel(modelPath);
    const nn::Shape shape = {1, model.inputChannels(), height, width};
    const std::vector<float> input = modelInput(model, width, height);
    AccumulationResult r;
    r.model = std::filesystem::path(modelPath).stem().string(), r.width = width, r.height = height;

    nn::InferencePlan plan(model, shape);
    nn::Tensor x(shape);
    std::copy(input.begin(), input.end(), x.data());
    plan.run(x);  // warm-up
    const auto start = std::chrono::steady_clock::now();
    const nn::Tensor& y = plan.run(x);
    r.floatMs = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    const std::vector<float> single(y.data(), y.data() + y.numel());

    const auto startDouble = std::chrono::steady_clock::now();
    const std::vector<double> reference =
        nn::forwardInDouble(model, std::vector<double>(input.begin(), input.end()), shape);
    r.doubleSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - startDouble).count();

    double difference = 0, norm = 0, largestDifference = 0, largestValue = 0;
    for (size_t i = 0; i < reference.size(); ++i) {
        const double d = double(single[i]) - reference[i];
        difference += d * d, norm += reference[i] * reference[i];
        largestDifference = std::max(largestDifference, std::abs(d));
        largestValue = std::max(largestValue, std::abs(reference[i]));
    }
    r.normwise = std::sqrt(difference / std::max(norm, 1e-300));
    r.largest = largestDifference / std::max(largestValue, 1e-300);
    return r;
}

DenormalResult benchDenormals(const std::string& modelPath, int width, int height, int repeat) {
    const nn::Model model = nn::loadModel(modelPath);
    const nn::Shape shape = {1, model.inputChannels(), height, width};
    const std::vector<float> input = modelInput(model, width, height);
    nn::Tensor normal(shape), denormal(shape);
    std::copy(input.begin(), input.end(), normal.data());
    for (int64_t i = 0; i < denormal.numel(); ++i) denormal.data()[i] = input[size_t(i)] * 1e-39f;

    DenormalResult r;
    r.width = width, r.height = height, r.threads = threadCount(), r.repeat = repeat;
    auto time = [&](nn::InferencePlan& plan, const nn::Tensor& x) {
        return medianMilliseconds(repeat, [&] { plan.runUnchecked(x); });  // (after one warm-up run)
    };
    {
        nn::InferencePlan plan(model, shape);
        // Alternate, so the machine's drift falls on both alike.
        std::vector<double> a, b;
        for (int k = 0; k < 3; ++k) a.push_back(time(plan, normal)), b.push_back(time(plan, denormal));
        std::sort(a.begin(), a.end()), std::sort(b.begin(), b.end());
        r.normalMs = a[1], r.denormalMs = b[1];
    }
    // For contrast: one thread (the caller) with FTZ/DAZ cleared.
    const int threads = threadCount();
    setThreadCount(1);
    const unsigned saved = _mm_getcsr();
    _mm_setcsr(saved & ~(0x8000u | 0x0040u));  // FTZ (bit 15), DAZ (bit 6)
    {
        nn::InferencePlan plan(model, shape);
        r.normalMsNoFlush = time(plan, normal);
        r.denormalMsNoFlush = time(plan, denormal);
    }
    _mm_setcsr(saved);
    setThreadCount(threads);
    return r;
}

namespace {

// Weights of the fast network after `steps` steps on batches cut from the test frame (target: a 3x3
// box blur of the input, something to learn), at the current thread count.
std::vector<float> trainBriefly(int steps) {
    constexpr int kBatch = 4, kPatch = 64;
    const std::vector<float> frame = accuracyTestFrame(640, 360);
    nn::Model model = nn::Model::builtin("fast");
    model.initialize(1);
    nn::OptimizerConfig adam;
    adam.learningRate = 2e-3;
    nn::Optimizer optimizer(adam, model.parameterCount());
    const nn::CompositeLoss loss = nn::CompositeLoss::parse("0.84*ssim+0.16*l1");
    nn::Tensor input({kBatch, 3, kPatch, kPatch}), target({kBatch, 3, kPatch, kPatch}), dout;
    for (int step = 0; step < steps; ++step) {
        for (int b = 0; b < kBatch; ++b) {
            const int x0 = (97 * (step * kBatch + b)) % (640 - kPatch - 2) + 1;
            const int y0 = (61 * (step * kBatch + b)) % (360 - kPatch - 2) + 1;
            for (int c = 0; c < 3; ++c)
                for (int y = 0; y < kPatch; ++y)
                    for (int x = 0; x < kPatch; ++x) {
                        auto at = [&](int dy, int dx) {
                            return frame[(size_t(c) * 360 + size_t(y0 + y + dy)) * 640 + size_t(x0 + x + dx)];
                        };
                        const size_t o =
                            ((size_t(b) * 3 + size_t(c)) * kPatch + size_t(y)) * kPatch + size_t(x);
                        input.data()[o] = at(0, 0);
                        float sum = 0;
                        for (int dy = -1; dy <= 1; ++dy)
                            for (int dx = -1; dx <= 1; ++dx) sum += at(dy, dx);
                        target.data()[o] = sum / 9.0f;
                    }
        }
        const nn::Tensor& out = model.forward(input);
        if (dout.shape() != out.shape()) dout = nn::Tensor(out.shape());
        dout.zero();
        loss.evaluate(dout.data(), out.data(), target.data(),
                      nn::SsimLossDesc{out.dim(0), out.dim(1), out.dim(2), out.dim(3), 1.0});
        model.backward(dout);
        nn::clipGradientNorm(model.gradientData(), model.parameterCount(), 1.0);
        optimizer.step(model.parameterData(), model.gradientData(), adam.learningRate);
    }
    return std::vector<float>(model.parameterData(), model.parameterData() + model.parameterCount());
}

double largestRelativeDifference(const std::vector<float>& a, const std::vector<float>& b) {
    double difference = 0, largest = 0;
    for (size_t i = 0; i < a.size(); ++i) {
        difference = std::max(difference, std::abs(double(a[i]) - double(b[i])));
        largest = std::max(largest, std::abs(double(a[i])));
    }
    return difference / std::max(largest, 1e-300);
}

}  // namespace

DeterminismResult benchDeterminism(const std::string& modelPath, int steps, int width, int height) {
    DeterminismResult r;
    r.steps = steps;
    const int saved = threadCount();
    r.threadCounts = {1, std::max(2, hardwareThreadCount())};
    const nn::Model model = nn::loadModel(modelPath);
    const nn::Shape shape = {1, model.inputChannels(), height, width};
    const std::vector<float> input = modelInput(model, width, height);
    nn::Tensor x(shape);
    std::copy(input.begin(), input.end(), x.data());
    std::vector<std::vector<float>> weights, outputs;
    for (int threads : r.threadCounts) {
        setThreadCount(threads);
        const std::vector<float> first = trainBriefly(steps), second = trainBriefly(steps);
        r.trainingRepeatable = r.trainingRepeatable && first == second;
        weights.push_back(first);
        nn::InferencePlan plan(model, shape);
        const nn::Tensor& y1 = plan.run(x);
        const std::vector<float> a(y1.data(), y1.data() + y1.numel());
        const nn::Tensor& y2 = plan.run(x);
        const std::vector<float> b(y2.data(), y2.data() + y2.numel());
        r.inferenceRepeatable = r.inferenceRepeatable && a == b;
        outputs.push_back(a);
    }
    setThreadCount(saved);
    for (size_t k = 1; k < weights.size(); ++k) {
        r.trainingAcrossThreads =
            std::max(r.trainingAcrossThreads, largestRelativeDifference(weights[0], weights[k]));
        r.inferenceAcrossThreads =
            std::max(r.inferenceAcrossThreads, largestRelativeDifference(outputs[0], outputs[k]));
    }
    return r;
}

}  // namespace dejag::bench

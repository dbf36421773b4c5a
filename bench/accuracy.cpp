#include "bench/accuracy.h"

#include <xmmintrin.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <vector>

#include "base/thread_pool.h"
#include "base/timer.h"
#include "nn/inference.h"
#include "nn/model.h"

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

// The test frame as the model's input (N = 1): RGB, or the luma for a grey model.
std::vector<float> modelInput(const nn::Model& model, int width, int height) {
    std::vector<float> rgb = accuracyTestFrame(width, height);
    if (model.inputChannels() == 3) return rgb;
    const size_t plane = size_t(width) * size_t(height);
    std::vector<float> luma(plane);
    for (size_t i = 0; i < plane; ++i)
        luma[i] = 0.21f * rgb[i] + 0.72f * rgb[plane + i] + 0.07f * rgb[2 * plane + i];
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

}  // namespace dejag::bench

#include <cmath>
#include <cstdint>

#include "base/peak.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "bench/bench.h"
#include "data/metrics.h"

namespace dejag::bench {
namespace {

// A reproducible pair: a reference with edges, gradients and texture, and a test with noise and a shift
// of some edges, so SSIM is far from 1 and every code path does real work.
void makePair(int width, int height, Image& reference, Image& test) {
    reference = Image(width, height, {"R", "G", "B"}, PixelType::UInt8);
    test = reference;
    uint32_t state = 12345u;
    auto noise = [&] {
        state = state * 1664525u + 1013904223u;
        return float(state >> 8) / float(1u << 24) - 0.5f;
    };
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < 3; ++c) {
                const float stripes = ((x / (7 + c) + y / 11) % 2) ? 0.8f : 0.2f;
                const float gradient = float(x + y) / float(width + height);
                const float value = 0.5f * stripes + 0.5f * gradient;
                reference.at(x, y, c) = std::round(value * 255.0f) / 255.0f;
                test.at(x, y, c) =
                    std::round(std::clamp(value + 0.05f * noise(), 0.0f, 1.0f) * 255.0f) / 255.0f;
            }
}

}  // namespace

std::vector<Row> benchMetrics(const Options& options) {
    Image reference, test;
    makePair(options.width, options.height, reference, test);
    const double samples = double(reference.sampleCount());
    // Multiply-adds of SSIM per sample: 5 moments x 11 taps, horizontally and vertically.
    const double ssimMacs = samples * 5 * 11 * 2;
    std::vector<Row> rows;
    for (int threads : options.threads) {
        setThreadCount(threads);
        const FmaPeak peak = measureFmaPeak();
        auto addRow = [&](const std::string& name, double ms, double macs, double targetMs) {
            Row row;
            row.name =
                name + " " + std::to_string(options.width) + "x" + std::to_string(options.height) + " RGB";
            row.threads = threads;
            row.simd = simdLevelName(activeSimdLevel());
            row.ms = ms;
            row.gmacs = macs > 0 ? macs / (ms * 1e6) : 0.0;
            row.peakGmacs = peak.gmacsTotal;
            row.peakFraction = row.gmacs / peak.gmacsTotal;
            row.targetMs = targetMs;
            rows.push_back(row);
        };
        double sink = 0.0;
        const double ssimMs = medianMilliseconds(
            options.repeat, [&] { sink += structuralSimilarity(reference, test, 1.0).mean; });
        addRow("ssim", ssimMs, ssimMacs, options.width == 1920 && options.height == 1080 ? 30.0 : 0.0);
        const double allMs =
            medianMilliseconds(options.repeat, [&] { sink += compareImages(reference, test).psnr; });
        addRow("metrics (mse+psnr+snr+ssim)", allMs, ssimMacs, 0.0);
        if (!std::isfinite(sink)) rows.back().name += " (non-finite result!)";
    }
    return rows;
}

double floatPsnr(const std::vector<float>& a, const std::vector<float>& b) {
    double squared = 0;
    for (size_t i = 0; i < a.size(); ++i) squared += double(a[i] - b[i]) * double(a[i] - b[i]);
    return 10 * std::log10(double(a.size()) / std::max(squared, 1e-30));
}

}  // namespace dejag::bench

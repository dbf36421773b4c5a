#include "bench/filter_bench.h"

#include <algorithm>
#include <cmath>

#include "base/thread_pool.h"
#include "base/timer.h"
#include "data/image.h"
#include "infer/fxaa.h"
#include "infer/taa.h"
#include "render/renderer.h"

namespace dejag::bench {

namespace {
double psnr(const std::vector<float>& a, const std::vector<float>& b) {
    double squared = 0;
    for (size_t i = 0; i < a.size(); ++i) squared += double(a[i] - b[i]) * double(a[i] - b[i]);
    return 10 * std::log10(double(a.size()) / std::max(squared, 1e-30));
}
std::vector<float> encoded(const render::Frame& f) {
    std::vector<float> v(f.pixels.size());
    for (size_t i = 0; i < v.size(); ++i)
        v[i] = std::clamp(linearToSrgb(std::max(f.pixels[i], 0.0f)), 0.0f, 1.0f);
    return v;
}
}  // namespace

std::vector<nlohmann::json> benchFilters(const FilterBenchOptions& options) {
    // A frame with distant windows, a wall and a pipe: thin and long edges, large flat areas.
    const auto context = render::createOsMesaContext();
    const render::Scene scene = render::buildScene("hard-edges");
    render::Renderer renderer(*context, scene, options.width, options.height);
    const std::vector<float> frame = encoded(renderer.render({}));
    render::TruthOptions truthOptions;
    truthOptions.samples = 64, truthOptions.adaptive = true;
    const std::vector<float> truth = encoded(renderer.renderTruth(0, truthOptions));
    std::vector<float> out(frame.size());
    std::vector<nlohmann::json> rows;
    for (const int preset : {12, 23, 39}) {
        infer::FxaaOptions fxaaOptions;
        fxaaOptions.preset = preset;
        infer::Fxaa fxaa(fxaaOptions);
        for (const int threads : options.threads) {
            setThreadCount(threads);
            // In place, as a frame pipeline runs it; the frame is restored (untimed) before each run.
            std::vector<double> times;
            for (int i = 0; i <= options.repeat; ++i) {
                std::copy(frame.begin(), frame.end(), out.begin());
                const Stopwatch clock;
                fxaa.applyInPlace(out.data(), options.width, options.height, 3);
                if (i > 0) times.push_back(clock.elapsedMs());  // the first run is the warm-up
            }
            const double ms = median(times);
            rows.push_back({{"name", "fxaa preset " + std::to_string(preset)},
                            {"threads", threads},
                            {"width", options.width},
                            {"height", options.height},
                            {"ms", ms},
                            {"target_ms", 2.0},
                            {"processed_fraction", fxaa.processedFraction()},
                            {"psnr_before", psnr(frame, truth)},
                            {"psnr_after", psnr(out, truth)}});
        }
    }
    // TAA on the same frame with every buffer (history accumulating over the timed runs).
    render::FrameRequest request;
    request.buffers = render::BufferSet::all();
    const render::Frame all = renderer.render(request);
    const size_t pixels = size_t(options.width) * size_t(options.height);
    auto take = [&](int first, int count, bool encode, float scale) {
        std::vector<float> v(pixels * size_t(count));
        for (size_t p = 0; p < pixels; ++p)
            for (int c = 0; c < count; ++c) {
                float x = all.pixels[p * size_t(all.channels()) + size_t(first + c)] * scale;
                v[p * size_t(count) + size_t(c)] =
                    encode ? std::clamp(linearToSrgb(std::max(x, 0.0f)), 0.0f, 1.0f) : x;
            }
        return v;
    };
    const float depthScale = float(1.0 / scene.far);
    const std::vector<float> colour = take(0, 3, true, 1), albedo = take(3, 3, true, 1),
                             depth = take(6, 1, false, depthScale), motion = take(7, 2, false, 1),
                             ids = take(9, 1, false, 1), previousDepth = take(10, 1, false, depthScale);
    infer::TaaFrame frameBuffers;
    frameBuffers.width = options.width, frameBuffers.height = options.height;
    frameBuffers.colour = colour.data(), frameBuffers.albedo = albedo.data(),
    frameBuffers.depth = depth.data();
    frameBuffers.motion = motion.data(), frameBuffers.ids = ids.data(),
    frameBuffers.previousDepth = previousDepth.data();
    for (const bool improved : {false, true}) {
        infer::TaaOptions taaOptions;
        taaOptions.improved = improved;
        infer::Taa taa(taaOptions);
        for (const int threads : options.threads) {
            setThreadCount(threads);
            const double ms =
                medianMilliseconds(options.repeat, [&] { taa.apply(frameBuffers, out.data()); });
            rows.push_back({{"name", improved ? "t-taa" : "u-taa"},
                            {"threads", threads},
                            {"width", options.width},
                            {"height", options.height},
                            {"ms", ms},
                            {"target_ms", improved ? 5.0 : 3.0},
                            {"processed_fraction", 1.0}});
        }
    }
    setThreadCount(0);
    return rows;
}

}  // namespace dejag::bench

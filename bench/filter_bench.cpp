#include "bench/filter_bench.h"

#include <algorithm>
#include <cmath>

#include "base/thread_pool.h"
#include "base/timer.h"
#include "bench/bench.h"
#include "data/frame_image.h"
#include "infer/fxaa.h"
#include "infer/taa.h"
#include "render/renderer.h"

namespace dejag::bench {

std::vector<nlohmann::json> benchFilters(const FilterBenchOptions& options) {
    // A frame with distant windows, a wall and a pipe: thin and long edges, large flat areas.
    const auto context = render::createOsMesaContext();
    const render::Scene scene = render::buildScene("hard-edges");
    render::Renderer renderer(*context, scene, options.width, options.height);
    const std::vector<float> frame = frameChannels(renderer.render({}), 0, 3, true);
    render::TruthOptions truthOptions;
    truthOptions.samples = 64, truthOptions.adaptive = true;
    const std::vector<float> truth = frameChannels(renderer.renderTruth(0, truthOptions), 0, 3, true);
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
                            {"psnr_before", floatPsnr(frame, truth)},
                            {"psnr_after", floatPsnr(out, truth)}});
        }
    }
    // TAA on the same frame with every buffer (history accumulating over the timed runs).
    render::FrameRequest request;
    request.buffers = render::BufferSet::all();
    const render::Frame all = renderer.render(request);
    const float depthScale = float(1.0 / scene.far);
    const std::vector<float> colour = frameChannels(all, 0, 3, true), albedo = frameChannels(all, 3, 3, true),
                             depth = frameChannels(all, 6, 1, false, depthScale),
                             motion = frameChannels(all, 7, 2, false), ids = frameChannels(all, 9, 1, false),
                             previousDepth = frameChannels(all, 10, 1, false, depthScale);
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

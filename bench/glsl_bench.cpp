#include "bench/glsl_bench.h"

#include <algorithm>

#include "base/error.h"
#include "base/timer.h"
#include "data/frame_image.h"
#include "infer/filter.h"
#include "infer/frame.h"
#include "infer/glsl_filter.h"
#include "render/halton.h"
#include "render/renderer.h"

namespace dejag::bench {

std::vector<nlohmann::json> benchGlsl(const GlslBenchOptions& options) {
    const auto context = render::createOsMesaContext();
    const std::string renderer = context->description();
    const bool emulated =
        renderer.find("llvmpipe") != std::string::npos || renderer.find("softpipe") != std::string::npos;
    // A moving view with thin and long edges, every buffer, the TAAs' jitter: the frames of the camera path.
    const render::Scene scene = render::buildScene("hard-edges");
    render::Renderer frames(*context, scene, options.width, options.height);
    infer::GlslFrameImport import(*context);
    infer::GlslBuffer out(*context);
    std::vector<nlohmann::json> rows;
    for (const std::string& method : options.methods) {
        infer::FilterParameters parameters;
        if (options.pathResolver) parameters.setPathResolver(options.pathResolver);
        std::string whyNot;
        const auto gpu = infer::makeGlslFilter(*context, method, parameters, &whyNot);
        if (!gpu) throw Error("'" + method + "': " + whyNot);
        const auto cpu = infer::makeFilter(method, parameters);
        std::vector<double> gpuTimes, cpuTimes;
        std::vector<std::pair<std::string, std::vector<double>>> passes;
        std::vector<float> cpuOut;
        for (int t = 0; t < options.repeat + 2; ++t) {
            render::FrameRequest request;
            request.time = t, request.previousTime = t - 1;
            request.jitter = render::jitterPixels(unsigned(t % 16), 1.0);
            request.previousJitter = render::jitterPixels(unsigned((t + 15) % 16), 1.0);
            request.buffers = render::BufferSet::all();
            const render::Frame rendered = frames.render(request);
            infer::FrameOptions frameOptions;
            frameOptions.wanted = infer::Buffer::Albedo | infer::Buffer::Depth | infer::Buffer::Motion |
                                  infer::Buffer::Ids | infer::Buffer::PreviousDepth;
            frameOptions.depthFar = scene.far;
            frameOptions.keepExtraChannels = false;
            infer::FrameData data = infer::frameFromImage(imageFromFrame(rendered), frameOptions, "frame");
            data.hasJitter = true, data.jitter[0] = float(request.jitter.x),
            data.jitter[1] = float(-request.jitter.y);
            infer::GlslFrame frame = import.run(frames.textures(), options.width, options.height,
                                                frameOptions.wanted, float(scene.far));
            frame.hasJitter = true, frame.jitter[0] = data.jitter[0], frame.jitter[1] = data.jitter[1];
            cpuOut.resize(data.colour.size());
            const Stopwatch clock;
            cpu->apply(data.frame(), cpuOut.data());
            const double cpuMs = clock.elapsedMs();
            render::PassTimer timer;
            timer.wallClock = emulated;
            context->passTimer = &timer;
            gpu->run(frame, out.ensure(cpuOut.size()));
            context->passTimer = nullptr;
            if (t < 2) continue;  // warm-up: compilation, allocation, the histories' first frames
            double gpuMs = 0;
            for (size_t i = 0; i < timer.passes.size(); ++i) {
                gpuMs += timer.passes[i].second;
                if (passes.size() <= i) passes.push_back({timer.passes[i].first, {}});
                passes[i].second.push_back(timer.passes[i].second);
            }
            gpuTimes.push_back(gpuMs), cpuTimes.push_back(cpuMs);
        }
        nlohmann::json row = {{"method", method},
                              {"width", options.width},
                              {"height", options.height},
                              {"frames", gpuTimes.size()},
                              {"gpu_ms", median(gpuTimes)},
                              {"cpu_ms", median(cpuTimes)},
                              {"gpu_over_cpu", median(gpuTimes) / std::max(median(cpuTimes), 1e-9)},
                              {"opengl", renderer},
                              {"emulated", emulated},
                              {"differences", gpu->differences()},
                              {"passes", nlohmann::json::array()}};
        for (const auto& [name, times] : passes)
            row["passes"].push_back({{"name", name}, {"ms", median(times)}});
        rows.push_back(row);
    }
    return rows;
}

}  // namespace dejag::bench

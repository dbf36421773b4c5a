#include "bench/render_bench.h"

#include "bench/bench.h"

#include <cmath>
#include <cstdio>

#include "base/timer.h"
#include "data/spectrum.h"
#include "render/renderer.h"

namespace dejag::bench {

std::vector<nlohmann::json> benchRender(const RenderBenchOptions& options) {
    std::vector<nlohmann::json> rows;
    const auto context = render::createOsMesaContext();
    for (const std::string& name : options.scenes) {
        const render::Scene scene = render::buildScene(name);
        for (const auto& [width, height] : options.sizes) {
            render::Renderer renderer(*context, scene, width, height);
            for (const bool all : {false, true}) {
                render::FrameRequest request;
                request.time = 1, request.previousTime = 0;
                request.buffers = all ? render::BufferSet::all() : render::BufferSet();
                renderer.render(request);  // warm-up
                std::vector<double> times;
                for (int i = 0; i < options.repeat; ++i) {
                    const Stopwatch clock;
                    renderer.render(request);
                    times.push_back(clock.elapsedMs());
                }
                rows.push_back({{"name", "frame " + std::string(all ? "all buffers" : "colour")},
                                {"scene", name},
                                {"width", width},
                                {"height", height},
                                {"buffers", request.buffers.describe()},
                                {"triangles", scene.triangleCount()},
                                {"ms", median(times)}});
            }
        }
    }
    for (const std::string& name : options.truthScenes) {
        const render::Scene scene = render::buildScene(name);
        const auto [width, height] = options.truthSize;
        render::Renderer renderer(*context, scene, width, height);
        const render::Frame aliased = renderer.render({});
        render::TruthOptions truthOptions;
        truthOptions.samples = options.truthSamples;
        render::TruthStats full, adaptive;
        const render::Frame fullTruth = renderer.renderTruth(0, truthOptions, &full);
        truthOptions.adaptive = true;
        const render::Frame adaptiveTruth = renderer.renderTruth(0, truthOptions, &adaptive);
        const double fullPsnr = floatPsnr(aliased.pixels, fullTruth.pixels),
                     adaptivePsnr = floatPsnr(aliased.pixels, adaptiveTruth.pixels);
        rows.push_back({{"name", "truth " + std::to_string(options.truthSamples) + " samples"},
                        {"scene", name},
                        {"width", width},
                        {"height", height},
                        {"ms", full.milliseconds},
                        {"adaptive_ms", adaptive.milliseconds},
                        {"tile_samples_saving", adaptive.saving()},
                        {"aliased_psnr_full_truth", fullPsnr},
                        {"aliased_psnr_adaptive_truth", adaptivePsnr},
                        {"psnr_difference_db", adaptivePsnr - fullPsnr},
                        {"adaptive_vs_full_truth_psnr", floatPsnr(fullTruth.pixels, adaptiveTruth.pixels)}});
    }
    for (const std::string& texture : options.samplerTextures) {
        const auto [width, height] = options.samplerSize;
        const auto toImage = [](const render::Frame& f) {
            Image image(f.width, f.height, f.channelNames);
            image.pixels = f.pixels;
            return image;
        };
        render::SceneOptions sceneOptions;
        sceneOptions.texture = texture, sceneOptions.sampler = render::Sampler::Point;
        const render::Scene truthScene = render::buildScene("planes", sceneOptions);
        render::Renderer truthRenderer(*context, truthScene, width, height);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.samplerTruthSamples;
        const Image truth = toImage(truthRenderer.renderTruth(0, truthOptions));
        for (const render::Sampler sampler :
             {render::Sampler::Point, render::Sampler::Bilinear, render::Sampler::Trilinear,
              render::Sampler::Anisotropic16, render::Sampler::Fourier}) {
            sceneOptions.sampler = sampler;
            const render::Scene scene = render::buildScene("planes", sceneOptions);
            const Stopwatch setup;
            render::Renderer renderer(*context, scene, width, height);
            const double setupMs = setup.elapsedMs();
            const render::Frame frame = renderer.render({});  // (also the warm-up)
            std::vector<double> times;
            for (int i = 0; i < options.repeat; ++i) {
                const Stopwatch clock;
                renderer.render({});
                times.push_back(clock.elapsedMs());
            }
            const AliasingScore score = aliasingScore(toImage(frame), truth);
            rows.push_back({{"name", std::string("sampler ") + render::samplerName(sampler)},
                            {"scene", "planes"},
                            {"texture", texture},
                            {"width", width},
                            {"height", height},
                            {"ms", median(times)},
                            {"aliasing", score.aliasing},
                            {"aliasing_db", score.aliasingDb()},
                            {"detail_kept", score.detailKept},
                            {"psnr", floatPsnr(frame.pixels, truth.pixels)},
                            {"setup_ms", setupMs},
                            {"truth_samples", options.samplerTruthSamples}});
        }
    }
    // The normal-map scene: standard normal mapping and super bump mapping against the surface read at
    // level 0 and averaged over the pixel.
    if (!options.samplerTextures.empty()) {
        const auto [width, height] = options.samplerSize;
        render::SceneOptions sceneOptions;
        sceneOptions.bump = render::Bump::Standard, sceneOptions.sampler = render::Sampler::Bilinear;
        const render::Scene truthScene = render::buildScene("normal-map", sceneOptions);
        render::Renderer truthRenderer(*context, truthScene, width, height);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.samplerTruthSamples;
        const render::Frame truthFrame = truthRenderer.renderTruth(0, truthOptions);
        Image truth(truthFrame.width, truthFrame.height, truthFrame.channelNames);
        truth.pixels = truthFrame.pixels;
        for (const auto& [bump, sampler] : {std::pair{render::Bump::Standard, render::Sampler::Trilinear},
                                            std::pair{render::Bump::Standard, render::Sampler::Anisotropic16},
                                            std::pair{render::Bump::Super, render::Sampler::Trilinear}}) {
            sceneOptions.bump = bump, sceneOptions.sampler = sampler;
            const render::Scene scene = render::buildScene("normal-map", sceneOptions);
            const Stopwatch setup;
            render::Renderer renderer(*context, scene, width, height);
            const double setupMs = setup.elapsedMs();
            const render::Frame frame = renderer.render({});
            std::vector<double> times;
            for (int i = 0; i < options.repeat; ++i) {
                const Stopwatch clock;
                renderer.render({});
                times.push_back(clock.elapsedMs());
            }
            Image image(frame.width, frame.height, frame.channelNames);
            image.pixels = frame.pixels;
            const AliasingScore score = aliasingScore(image, truth);
            rows.push_back({{"name", std::string("bump ") + render::bumpName(bump) +
                                         (sampler == render::Sampler::Anisotropic16 ? " aniso16" : "")},
                            {"scene", "normal-map"},
                            {"texture", "dimples"},
                            {"width", width},
                            {"height", height},
                            {"ms", median(times)},
                            {"aliasing", score.aliasing},
                            {"aliasing_db", score.aliasingDb()},
                            {"detail_kept", score.detailKept},
                            {"psnr", floatPsnr(frame.pixels, truthFrame.pixels)},
                            {"setup_ms", setupMs},
                            {"truth_samples", options.samplerTruthSamples}});
        }
    }
    return rows;
}

}  // namespace dejag::bench

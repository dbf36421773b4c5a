#include "bench/render_bench.h"

#include "bench/bench.h"

#include <cmath>
#include <cstdio>

#include "base/timer.h"
#include "data/spectrum.h"
#include "render/renderer.h"

namespace dejag::bench {

namespace {

// A row of a sampler or a normal-map mode: its frame's time, aliasing and detail against the truth.
nlohmann::json qualityRow(const std::string& name, const char* scene, const std::string& texture,
                          const render::Frame& frame, const render::Frame& truth,
                          const std::vector<double>& times, double setupMs, int truthSamples) {
    const auto toImage = [](const render::Frame& f) {
        Image image(f.width, f.height, f.channelNames);
        image.pixels = f.pixels;
        return image;
    };
    const AliasingScore score = aliasingScore(toImage(frame), toImage(truth));
    return {{"name", name},
            {"scene", scene},
            {"texture", texture},
            {"width", frame.width},
            {"height", frame.height},
            {"ms", median(times)},
            {"aliasing", score.aliasing},
            {"aliasing_db", score.aliasingDb()},
            {"detail_kept", score.detailKept},
            {"psnr", floatPsnr(frame.pixels, truth.pixels)},
            {"setup_ms", setupMs},
            {"truth_samples", truthSamples}};
}

}  // namespace

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
    // A scene's renderer set up (timed), its first frame and the times of `repeat` more.
    const auto timed = [&](const render::Scene& scene, int width, int height, const render::Frame& truth,
                           const std::string& name, const char* sceneName, const std::string& texture) {
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
        rows.push_back(
            qualityRow(name, sceneName, texture, frame, truth, times, setupMs, options.samplerTruthSamples));
    };
    const auto truthOf = [&](const render::Scene& scene, int width, int height) {
        render::Renderer renderer(*context, scene, width, height);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.samplerTruthSamples;
        return renderer.renderTruth(0, truthOptions);
    };
    const auto [width, height] = options.samplerSize;
    for (const std::string& texture : options.samplerTextures) {
        render::SceneOptions sceneOptions;
        sceneOptions.texture = texture, sceneOptions.sampler = render::Sampler::Point;
        const render::Frame truth = truthOf(render::buildScene("planes", sceneOptions), width, height);
        for (const render::Sampler sampler :
             {render::Sampler::Point, render::Sampler::Bilinear, render::Sampler::Trilinear,
              render::Sampler::Anisotropic16, render::Sampler::Fourier}) {
            sceneOptions.sampler = sampler;
            timed(render::buildScene("planes", sceneOptions), width, height, truth,
                  std::string("sampler ") + render::samplerName(sampler), "planes", texture);
        }
        // The Fourier sampler as the thesis reads its bands: one isotropic probe.
        render::Scene isotropic = render::buildScene("planes", sceneOptions);
        isotropic.fourier.probes = 1;
        timed(std::move(isotropic), width, height, truth, "sampler fourier 1-probe", "planes", texture);
    }
    // The normal-map scene: standard normal mapping and super bump mapping against the surface read at
    // level 0 and averaged over the pixel.
    if (!options.samplerTextures.empty()) {
        render::SceneOptions sceneOptions;
        sceneOptions.bump = render::Bump::Standard, sceneOptions.sampler = render::Sampler::Bilinear;
        const render::Frame truth = truthOf(render::buildScene("normal-map", sceneOptions), width, height);
        for (const auto& [bump, sampler] : {std::pair{render::Bump::Standard, render::Sampler::Trilinear},
                                            std::pair{render::Bump::Standard, render::Sampler::Anisotropic16},
                                            std::pair{render::Bump::Super, render::Sampler::Trilinear}}) {
            sceneOptions.bump = bump, sceneOptions.sampler = sampler;
            timed(render::buildScene("normal-map", sceneOptions), width, height, truth,
                  std::string("bump ") + render::bumpName(bump) +
                      (sampler == render::Sampler::Anisotropic16 ? " aniso16" : ""),
                  "normal-map", "dimples");
        }
    }
    return rows;
}

}  // namespace dejag::bench

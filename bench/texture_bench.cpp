#include "bench/texture_bench.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>

#include "base/error.h"
#include "base/timer.h"
#include "bench/bench.h"
#include "bench/taa_bench.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "data/spectrum.h"
#include "infer/filter.h"
#include "render/renderer.h"

namespace dejag::bench {
namespace {

// A scene of the comparison with its sampler or bump mode.
render::Scene caseScene(const std::string& name, render::Sampler sampler, render::Bump bump) {
    render::SceneOptions options;
    options.sampler = sampler, options.bump = bump;
    if (name == "normal-map") return render::buildScene("normal-map", options);
    options.texture = name;
    return render::buildScene("planes", options);
}

Image linearImage(const std::vector<float>& rgb, int width, int height) {
    Image image(width, height, {"R", "G", "B"});
    image.pixels = rgb;
    return image;
}

std::vector<float> toLinear(const std::vector<float>& srgb) {
    std::vector<float> out(srgb.size());
    for (size_t i = 0; i < srgb.size(); ++i) out[i] = srgbToLinear(std::clamp(srgb[i], 0.0f, 1.0f));
    return out;
}

}  // namespace

void markPareto(std::vector<nlohmann::json>& rows) {
    for (nlohmann::json& row : rows) {
        bool beaten = false;
        for (const nlohmann::json& other : rows)
            if (&other != &row && other["case"] == row["case"] &&
                other["ms"].get<double>() < row["ms"].get<double>() &&
                other["psnr"].get<double>() > row["psnr"].get<double>())
                beaten = true;
        row["pareto"] = !beaten;
    }
}

std::vector<nlohmann::json> benchTexture(const TextureBenchOptions& options) {
    std::vector<nlohmann::json> rows;
    const auto context = render::createOsMesaContext();
    const int W = options.width, H = options.height;
    for (const std::string& name : options.cases) {
        const bool shading = name == "normal-map";
        // The truth: the texture's texels (or the normal map's level 0) averaged over the pixel.
        const render::Scene truthScene = caseScene(
            name, shading ? render::Sampler::Bilinear : render::Sampler::Point, render::Bump::Standard);
        render::Renderer truthRenderer(*context, truthScene, W, H);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.truthSamples;
        const std::vector<float> truth =
            frameChannels(truthRenderer.renderTruth(0, truthOptions), 0, 3, false);
        const Image truthImage = linearImage(truth, W, H);
        const auto score = [&](const std::string& method, const char* family,
                               const std::vector<float>& linear, double ms) {
            const AliasingScore s = aliasingScore(linearImage(linear, W, H), truthImage);
            rows.push_back({{"case", name},
                            {"method", method},
                            {"family", family},
                            {"width", W},
                            {"height", H},
                            {"ms", ms},
                            {"aliasing", s.aliasing},
                            {"aliasing_db", s.aliasingDb()},
                            {"detail_kept", s.detailKept},
                            {"psnr", floatPsnr(linear, truth)}});
            if (!options.quiet)
                std::fprintf(stderr, "  %-12s %-30s %8.1f ms  aliasing %6.1f dB  detail %.3f  PSNR %.2f dB\n",
                             name.c_str(), method.c_str(), ms, s.aliasingDb(), s.detailKept,
                             rows.back()["psnr"].get<double>());
        };
        // A frame's render time: the median of three after a warm-up.
        const auto timedRender = [](render::Renderer& renderer, const render::FrameRequest& request,
                                    render::Frame& out) {
            out = renderer.render(request);
            std::vector<double> times;
            for (int i = 0; i < 3; ++i) {
                const Stopwatch clock;
                out = renderer.render(request);
                times.push_back(clock.elapsedMs());
            }
            return median(times);
        };

        // At the source.
        struct Source {
            std::string method;
            render::Sampler sampler;
            render::Bump bump;
        };
        std::vector<Source> sources;
        if (shading) {
            sources = {{"bump standard", render::Sampler::Trilinear, render::Bump::Standard},
                       {"bump standard aniso16", render::Sampler::Anisotropic16, render::Bump::Standard},
                       {"bump super", render::Sampler::Trilinear, render::Bump::Super}};
        } else {
            for (const render::Sampler s :
                 {render::Sampler::Point, render::Sampler::Bilinear, render::Sampler::Trilinear,
                  render::Sampler::Anisotropic16, render::Sampler::Fourier})
                sources.push_back(
                    {std::string("sampler ") + render::samplerName(s), s, render::Bump::Standard});
        }
        double baseRenderMs = 0;
        std::vector<float> baseSrgb;
        for (const Source& source : sources) {
            const render::Scene scene = caseScene(name, source.sampler, source.bump);
            render::Renderer renderer(*context, scene, W, H);
            render::Frame frame;
            const double ms = timedRender(renderer, {}, frame);
            score(source.method, "source", frameChannels(frame, 0, 3, false), ms);
            if (source.sampler == render::Sampler::Trilinear && source.bump == render::Bump::Standard)
                baseRenderMs = ms, baseSrgb = frameChannels(frame, 0, 3, true);
        }

        // After rendering, on the default frame (every buffer, for the networks that read them).
        const render::Scene baseScene = caseScene(name, render::Sampler::Trilinear, render::Bump::Standard);
        render::Renderer baseRenderer(*context, baseScene, W, H);
        render::FrameRequest allBuffers;
        allBuffers.buffers = render::BufferSet::all();
        const render::Frame baseFrame = baseRenderer.render(allBuffers);
        const FrameBuffers buffers(baseFrame, float(baseScene.far), {});
        std::vector<std::pair<std::string, std::unique_ptr<infer::Filter>>> singles;
        singles.emplace_back("fxaa", infer::makeFilter("fxaa", {}));
        singles.emplace_back("smaa", infer::makeFilter("smaa", {}));
        for (const std::string& model : options.models)
            singles.emplace_back(std::filesystem::path(model).stem().string(),
                                 infer::makeFilter("cnn", {{"model", model}}));
        std::vector<float> out(baseSrgb.size());
        for (auto& [method, filter] : singles) {
            std::vector<double> times;
            for (int i = 0; i < 4; ++i) {
                filter->apply(buffers.frame, out.data());
                if (i > 0) times.push_back(filter->figures().ms);
            }
            score(method, "post-process", toLinear(out), baseRenderMs + median(times));
        }

        // Over time: a still view's jittered frames, the default ones and point-sampled ones.
        for (const bool point : {false, true}) {
            const render::Scene scene = caseScene(
                name, point ? render::Sampler::Point : render::Sampler::Trilinear, render::Bump::Standard);
            render::Renderer renderer(*context, scene, W, H);
            std::vector<std::pair<std::string, std::unique_ptr<infer::Filter>>> taas;
            taas.emplace_back("u-taa", infer::makeFilter("taa", {}));
            taas.emplace_back("t-taa", infer::makeFilter("taa-sobel", {}));
            taas.emplace_back("taa-hq", infer::makeFilter("taa-hq", {}));
            if (!options.temporalModel.empty())
                taas.emplace_back("dejag-temporal",
                                  infer::makeFilter("cnn-temporal", {{"model", options.temporalModel}}));
            std::vector<std::vector<double>> filterTimes(taas.size());
            std::vector<double> renderTimes;
            std::vector<std::vector<float>> outputs(taas.size(), std::vector<float>(baseSrgb.size()));
            for (int i = 0; i < options.frames; ++i) {
                const render::FrameRequest request = jitteredFrame(0, i, options.jitterSpread);
                const Stopwatch clock;
                const render::Frame frame = renderer.render(request);
                renderTimes.push_back(clock.elapsedMs());
                const FrameBuffers jittered(frame, float(scene.far), request.jitter);
                for (size_t k = 0; k < taas.size(); ++k) {
                    taas[k].second->apply(jittered.frame, outputs[k].data());
                    filterTimes[k].push_back(taas[k].second->figures().ms);
                }
            }
            for (size_t k = 0; k < taas.size(); ++k)
                score(taas[k].first + (point ? " (point frames)" : ""), "temporal", toLinear(outputs[k]),
                      median(renderTimes) + median(filterTimes[k]));
        }
    }
    markPareto(rows);
    return rows;
}

}  // namespace dejag::bench

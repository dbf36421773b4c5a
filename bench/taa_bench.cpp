#include "bench/taa_bench.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include "base/progress.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "data/metrics.h"
#include "infer/filter.h"
#include "render/halton.h"
#include "render/renderer.h"

namespace dejag::bench {

namespace {

// An 8-bit sRGB image (the thesis measured on 8-bit render targets).
Image eightBit(const std::vector<float>& rgb, int width, int height) {
    Image image(width, height, {"R", "G", "B"}, PixelType::UInt8);
    for (size_t i = 0; i < rgb.size(); ++i)
        image.pixels[i] = std::round(std::clamp(rgb[i], 0.0f, 1.0f) * 255.0f) / 255.0f;
    return image;
}

nlohmann::json metricsJson(const ImageMetrics& m) {
    return {{"mse", m.mse}, {"rmsd", m.rmse}, {"psnr", m.psnr}, {"snr", m.snr}, {"ssim", m.ssim}};
}

// U-TAA and T-TAA as specified, and both without their final sharpen (which costs several dB on
// frames dense in edges).
struct Taas {
    std::unique_ptr<infer::Filter> filters[4] = {infer::makeFilter("taa", {}),
                                                 infer::makeFilter("taa-sobel", {}),
                                                 infer::makeFilter("taa", {{"sharpen", "false"}}),
                                                 infer::makeFilter("taa-sobel", {{"sharpen", "false"}})};
    std::vector<float> outputs[4];
};
const char* const kTaaNames[4] = {"u-taa", "t-taa", "u-taa unsharpened", "t-taa unsharpened"};

// Runs every TAA on one rendered frame with every buffer.
void runTaas(Taas& taas, const render::Frame& f, float far) {
    const std::vector<float> colour = frameChannels(f, 0, 3, true), albedo = frameChannels(f, 3, 3, true);
    const std::vector<float> depth = frameChannels(f, 6, 1, false, 1.0f / far),
                             motion = frameChannels(f, 7, 2, false);
    const std::vector<float> ids = frameChannels(f, 9, 1, false),
                             previousDepth = frameChannels(f, 10, 1, false, 1.0f / far);
    infer::Frame frame;
    frame.width = f.width, frame.height = f.height;
    frame.colour = colour.data(), frame.albedo = albedo.data(), frame.depth = depth.data();
    frame.motion = motion.data(), frame.ids = ids.data(), frame.previousDepth = previousDepth.data();
    for (int k = 0; k < 4; ++k) {
        taas.outputs[k].resize(colour.size());
        taas.filters[k]->apply(frame, taas.outputs[k].data());
    }
}

render::FrameRequest jittered(double time, int index) {
    render::FrameRequest r;
    r.time = time, r.previousTime = std::max(0.0, time - 1);
    r.jitter = render::jitterPixels(unsigned(index % 16), 1.7);
    r.previousJitter = render::jitterPixels(unsigned((index + 15) % 16), 1.7);
    r.buffers = render::BufferSet::all();
    return r;
}

}  // namespace

std::vector<nlohmann::json> benchTaa(const TaaBenchOptions& options) {
    std::vector<nlohmann::json> rows;
    const auto context = render::createOsMesaContext();
    struct StaticScene {
        const char* label;
        const char* scene;
        bool tilted;
    };
    const StaticScene scenes[] = {{"pipe", "pipe", false},
                                  {"pipe tilted", "pipe", true},
                                  {"blinds", "blinds", false},
                                  {"arched window", "arched-window", false},
                                  {"atrium", "atrium", false},
                                  {"flowers", "flowers", false},
                                  {"hard edges", "hard-edges", false},
                                  {"hairball", "hairball", false},
                                  {"hairball lit", "hairball-lit", false}};
    Progress progress("bench taa", int64_t(std::size(scenes)) + (options.ghosting ? 3 : 0), options.quiet);
    const int W = options.width, H = options.height;
    for (const StaticScene& s : scenes) {
        render::SceneOptions sceneOptions;
        sceneOptions.tiltedCamera = s.tilted;
        const render::Scene scene = render::buildScene(s.scene, sceneOptions);
        render::Renderer renderer(*context, scene, W, H);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.truthSamples, truthOptions.adaptive = true;
        const Image truth = eightBit(frameChannels(renderer.renderTruth(0, truthOptions), 0, 3, true), W, H);
        render::FrameRequest still;
        still.buffers = render::BufferSet::parse("color");
        const std::vector<float> noAa = frameChannels(renderer.render(still), 0, 3, true);
        std::vector<float> fxaaOut(noAa.size());
        infer::Frame stillFrame;
        stillFrame.width = W, stillFrame.height = H, stillFrame.colour = noAa.data();
        infer::makeFilter("fxaa", {})->apply(stillFrame, fxaaOut.data());
        Taas taas;
        for (int i = 0; i < options.historyFrames; ++i)
            runTaas(taas, renderer.render(jittered(0, i)), float(scene.far));
        const std::pair<const char*, const std::vector<float>*> methods[] = {
            {"no aa", &noAa},
            {"fxaa", &fxaaOut},
            {kTaaNames[0], &taas.outputs[0]},
            {kTaaNames[1], &taas.outputs[1]},
            {kTaaNames[2], &taas.outputs[2]},
            {kTaaNames[3], &taas.outputs[3]}};
        for (const auto& [method, pixels] : methods) {
            MetricOptions metricOptions;
            metricOptions.wantSsimMap = !options.ssimMapFolder.empty();
            const ImageMetrics m = compareImages(truth, eightBit(*pixels, W, H), metricOptions);
            nlohmann::json row = {
                {"test", "static"}, {"scene", s.label}, {"method", method}, {"width", W}, {"height", H}};
            row.update(metricsJson(m));
            if (metricOptions.wantSsimMap) {
                std::filesystem::create_directories(options.ssimMapFolder);
                std::string name = std::string(s.label) + "_" + method + "_ssim.png";
                std::replace(name.begin(), name.end(), ' ', '-');
                writeSsimMapPng((std::filesystem::path(options.ssimMapFolder) / name).string(), m.ssimMap, W,
                                H);
                row["ssim_map"] = name;
            }
            rows.push_back(row);
        }
        progress.advance(1, s.label);
    }
    if (options.ghosting) {
        const int GW = options.ghostWidth, GH = options.ghostHeight;
        for (const char* name : {"corridor", "hairball-rotating", "hairball-lit-rotating"}) {
            const render::Scene scene = render::buildScene(name);
            render::Renderer renderer(*context, scene, GW, GH);
            Taas taas;
            std::vector<double> psnr[4], ssim[4];
            render::TruthOptions truthOptions;
            truthOptions.samples = options.ghostTruthSamples, truthOptions.adaptive = true;
            for (int t = 0; t < options.ghostFrames; ++t) {
                runTaas(taas, renderer.render(jittered(t, t)), float(scene.far));
                const Image truth =
                    eightBit(frameChannels(renderer.renderTruth(t, truthOptions), 0, 3, true), GW, GH);
                for (int k = 0; k < 4; ++k) {
                    const ImageMetrics m = compareImages(truth, eightBit(taas.outputs[k], GW, GH));
                    psnr[k].push_back(m.psnr), ssim[k].push_back(m.ssim);
                }
            }
            auto summary = [](const std::vector<double>& v) {
                double sum = 0;
                for (double x : v) sum += x;
                return nlohmann::json{{"best", *std::max_element(v.begin(), v.end())},
                                      {"worst", *std::min_element(v.begin(), v.end())},
                                      {"mean", sum / double(v.size())}};
            };
            for (int k = 0; k < 4; ++k)
                rows.push_back({{"test", "ghosting"},
                                {"scene", name},
                                {"method", kTaaNames[k]},
                                {"frames", options.ghostFrames},
                                {"width", GW},
                                {"height", GH},
                                {"psnr", summary(psnr[k])},
                                {"ssim", summary(ssim[k])}});
            progress.advance(1, name);
        }
    }
    return rows;
}

}  // namespace dejag::bench

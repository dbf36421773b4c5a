#include "bench/demo.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>

#include "base/error.h"
#include "base/progress.h"
#include "base/timer.h"
#include "bench/quality.h"
#include "data/evaluation.h"
#include "data/frame_image.h"
#include "infer/filter.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace dejag::bench {

namespace fs = std::filesystem;
using nlohmann::json;

std::vector<std::string> defaultDemoScenes() {
    return {"atrium", "hard-edges", "flowers", "pipe", "text-wall", "planes"};
}

std::vector<json> runDemo(const DemoOptions& options) {
    const int W = options.width, H = options.height;
    if (W < 32 || H < 32 || W > 4096 || H > 4096) throw Error("demo size must be 32..4096 on each side");
    if (options.repeat < 1) throw Error("--repeat must be >= 1");
    const std::vector<std::string> sceneNames = options.scenes.empty() ? defaultDemoScenes() : options.scenes;
    const auto& catalogue = render::sceneCatalogue();
    for (const std::string& name : sceneNames)
        if (std::none_of(catalogue.begin(), catalogue.end(),
                         [&](const render::SceneInfo& i) { return i.name == name; }))
            throw Error("unknown scene '" + name + "' (dejag render --list)");
    // Every model is loaded and checked before anything is rendered or written.
    StillMethods::Options methodOptions;
    methodOptions.models = options.models;
    StillMethods methods(methodOptions);
    const std::vector<std::string>& tests = data::defaultTestFamilies();

    const auto context = render::createOsMesaContext();
    Progress progress("demo", int64_t(sceneNames.size()), options.quiet);
    std::vector<QualityCase> cases;
    for (const std::string& sceneName : sceneNames) {
        const render::Scene scene = render::buildScene(sceneName, {});
        render::Renderer renderer(*context, scene, W, H);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.truthSamples, truthOptions.adaptive = true;
        QualityCase c;
        c.name = sceneName;
        for (const auto& info : catalogue)
            if (info.name == sceneName)
                c.heldOut = std::find(tests.begin(), tests.end(), info.family) != tests.end();
        c.item.id = sceneName;
        c.item.truth = Image(W, H, {"R", "G", "B"}, PixelType::Float);
        c.item.truth.pixels = frameChannels(renderer.renderTruth(0, truthOptions), 0, 3, true);
        render::FrameRequest still;
        still.buffers = render::BufferSet::parse("color,depth,id");
        const render::Frame stillFrame = renderer.render(still);
        c.item.input = Image(W, H, {"R", "G", "B"}, PixelType::Float);
        c.item.input.pixels = frameChannels(stillFrame, 0, 3, true);
        const Image buffers = imageFromFrame(render::Frame(stillFrame));
        data::computeRegionMasks(c.item, buffers);
        c.ids = frameChannels(stillFrame, buffers.findChannel("id.ID"), 1, false);
        c.depth = frameChannels(stillFrame, buffers.findChannel("depth.Z"), 1, false);
        methods.run(c, options.repeat);

        // TAA: `historyFrames` Halton-jittered frames of the still camera, the last one scored; time =
        // median per frame after the first two.
        // As docs/taa.md has them (with their sharpen), and T-TAA without its sharpen (docs/infer.md: the
        // sharpen costs several dB on edge-dense frames).
        // And taa-hq (docs/taa-hq.md), the TAA that converges.
        constexpr int kTaas = 4;
        const std::unique_ptr<infer::Filter> taas[kTaas] = {
            infer::makeFilter("taa", {}), infer::makeFilter("taa-sobel", {}),
            infer::makeFilter("taa-sobel", {{"sharpen", "false"}}), infer::makeFilter("taa-hq", {})};
        std::vector<float> outputs[kTaas];
        std::vector<double> times[kTaas];
        for (int i = 0; i < options.historyFrames; ++i) {
            render::FrameRequest r;
            r.time = 0, r.previousTime = 0;
            r.jitter = render::jitterPixels(unsigned(i % 16), 1.7);
            r.previousJitter = render::jitterPixels(unsigned((i + 15) % 16), 1.7);
            r.buffers = render::BufferSet::all();
            const render::Frame f = renderer.render(r);
            const float far = float(scene.far);
            const std::vector<float> colour = frameChannels(f, 0, 3, true),
                                     albedo = frameChannels(f, 3, 3, true);
            const std::vector<float> depth = frameChannels(f, 6, 1, false, 1.0f / far),
                                     motion = frameChannels(f, 7, 2, false);
            const std::vector<float> ids = frameChannels(f, 9, 1, false),
                                     previousDepth = frameChannels(f, 10, 1, false, 1.0f / far);
            infer::Frame frame;
            frame.width = W, frame.height = H;
            frame.colour = colour.data(), frame.albedo = albedo.data(), frame.depth = depth.data();
            frame.motion = motion.data(), frame.ids = ids.data(), frame.previousDepth = previousDepth.data();
            frame.hasJitter = true;  // the image's shift, +y down
            frame.jitter[0] = float(r.jitter.x), frame.jitter[1] = float(-r.jitter.y);
            for (int k = 0; k < kTaas; ++k) {
                outputs[k].resize(colour.size());
                taas[k]->apply(frame, outputs[k].data());
                if (i >= 2) times[k].push_back(taas[k]->figures().ms);
            }
        }
        const char* names[kTaas] = {"U-TAA", "T-TAA", "T-TAA unsharpened", "taa-hq"};
        for (int k = 0; k < kTaas; ++k) {
            MethodResult r;
            r.name = names[k];
            r.ms = times[k].empty() ? 0.0 : median(times[k]);
            r.output = Image(W, H, {"R", "G", "B"}, PixelType::Float);
            r.output.pixels = outputs[k];
            r.note = std::to_string(options.historyFrames) + " jittered frames";
            c.methods.insert(c.methods.begin() + 2 + k, std::move(r));  // after no AA and FXAA
        }
        scoreCase(c);
        cases.push_back(std::move(c));
        progress.advance(1, sceneName);
    }
    progress.finish();
    ReportOptions report;
    report.out = options.out;
    report.title = "dejag demo: anti-aliasing methods against the supersampled truth";
    report.intro =
        std::to_string(W) + "×" + std::to_string(H) +
        " frames; truth: " + std::to_string(options.truthSamples) +
        " Halton samples per pixel (adaptive). No AA, FXAA and the networks filter one unjittered frame; "
        "U-TAA and T-TAA (docs/taa.md, with their sharpen; and T-TAA without it) and taa-hq (docs/taa-hq.md) "
        "the last of " +
        std::to_string(options.historyFrames) +
        " jittered frames. Scores on sRGB values in [0, 1]; edge = within 1 px of a geometric edge, "
        "texture = detailed pixels 3 px or more from one.";
    report.notes = methods.notes();
    for (const std::string& n : report.notes) std::fprintf(stderr, "demo: %s\n", n.c_str());
    return writeQualityReport(report, cases);
}

}  // namespace dejag::bench

#include "bench/demo.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>

#include "base/error.h"
#include "base/progress.h"
#include "base/timer.h"
#include "bench/quality.h"
#include "bench/taa_bench.h"
#include "data/evaluation.h"
#include "data/frame_image.h"
#include "data/metrics.h"
#include "data/plot.h"
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

namespace {

// The report's "Moving sequence" section: the temporal methods on a camera panning 1 px a frame, every
// frame against the truth of its own pose. Returns the section's HTML and one row per method.
std::string movingSection(const render::GlContext& context, const DemoOptions& options,
                          std::vector<json>& rows) {
    const int W = options.width, H = options.height, frames = options.movingFrames;
    const int skip = std::min(8, frames / 2);
    render::Scene scene = render::buildScene(options.movingScene, {});
    moveCamera(scene, 1.0, false, H);
    render::Renderer renderer(context, scene, W, H);
    render::TruthOptions truthOptions;
    truthOptions.samples = options.truthSamples, truthOptions.adaptive = true;
    const std::vector<std::pair<std::string, std::unique_ptr<infer::Filter>>> methods = [&] {
        std::vector<std::pair<std::string, std::unique_ptr<infer::Filter>>> m;
        m.emplace_back("no AA", infer::makeFilter("none", {}));
        m.emplace_back("FXAA", infer::makeFilter("fxaa", {}));
        m.emplace_back("taa-hq", infer::makeFilter("taa-hq", {}));
        m.emplace_back("dejag-temporal",
                       infer::makeFilter("cnn-temporal", {{"model", options.temporalModel}}));
        return m;
    }();
    const size_t count = methods.size();
    std::vector<double> psnr(count, 0.0), ssim(count, 0.0);
    std::vector<FlickerMeter> flicker(count);
    const int shown[3] = {skip, (skip + frames - 1) / 2, frames - 1};
    std::vector<std::vector<Image>> crops(count + 1);  // the truth, then each method
    Window window;
    std::vector<float> output(size_t(W) * size_t(H) * 3);
    for (int t = 0; t < frames; ++t) {
        const render::FrameRequest request = jitteredFrame(t, t, options.movingJitterSpread);
        const FrameBuffers buffers(renderer.render(request), float(scene.far), request.jitter);
        Image truth(W, H, {"R", "G", "B"}, PixelType::Float);
        if (t >= skip) truth.pixels = frameChannels(renderer.renderTruth(t, truthOptions), 0, 3, true);
        const bool show = std::find(std::begin(shown), std::end(shown), t) != std::end(shown);
        for (size_t k = 0; k < count; ++k) {
            methods[k].second->apply(buffers.frame, output.data());
            if (t < skip) continue;
            Image out(W, H, {"R", "G", "B"}, PixelType::Float);
            out.pixels = output;
            const ImageMetrics m = compareImages(truth, out);
            psnr[k] += m.psnr / (frames - skip), ssim[k] += m.ssim / (frames - skip);
            flicker[k].add(out.pixels, truth.pixels);
            if (t == skip && k == 0) window = worstWindow(out, truth, std::min(W, 120), std::min(H, 68));
            if (show) {
                if (k == 0) crops[0].push_back(zoomedCrop(truth, window, 2));
                crops[k + 1].push_back(zoomedCrop(out, window, 2));
            }
        }
    }
    const fs::path out(options.out);
    fs::create_directories(out);
    std::vector<std::string> rowLabels = {"truth"}, columnLabels;
    for (const auto& [name, filter] : methods) rowLabels.push_back(name);
    for (int t : shown) columnLabels.push_back("frame " + std::to_string(t));
    writeMosaicPng((out / "moving.png").string(), crops, rowLabels, columnLabels);
    std::ostringstream html;
    html << "<h2>Moving sequence</h2>\n<p>" << options.movingScene << ", " << frames
         << " jittered frames (Halton, spread " << options.movingJitterSpread
         << " px) of a camera panning 1 px a frame, each frame against the " << options.truthSamples
         << "-sample truth of its own pose; scores over frames " << skip << "–" << frames - 1
         << " (the histories fill first). Flicker: the mean |(X<sub>t</sub> − X<sub>t−1</sub>) − "
            "(R<sub>t</sub> − R<sub>t−1</sub>)| (docs/metrics.md).</p>\n<table><tr><th>method</th><th>PSNR "
            "(dB)</th><th>SSIM</th><th>flicker</th></tr>\n";
    char line[256];
    for (size_t k = 0; k < count; ++k) {
        std::snprintf(line, sizeof(line), "<tr><td>%s</td><td>%.2f</td><td>%.4f</td><td>%.5f</td></tr>\n",
                      methods[k].first.c_str(), psnr[k], ssim[k], flicker[k].value());
        html << line;
        rows.push_back({{"test", "moving"},
                        {"scene", options.movingScene},
                        {"method", methods[k].first},
                        {"psnr", psnr[k]},
                        {"ssim", ssim[k]},
                        {"flicker", flicker[k].value()},
                        {"frames", frames},
                        {"scored_from", skip}});
    }
    html << "</table>\n<p><img src=\"moving.png\" style=\"max-width:100%\"></p>\n";
    return html.str();
}

}  // namespace

std::vector<json> runDemo(const DemoOptions& options, std::vector<json>* moving) {
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
            const render::FrameRequest r = jitteredFrame(0, i, 1.7);
            const FrameBuffers jittered(renderer.render(r), float(scene.far), r.jitter);
            for (int k = 0; k < kTaas; ++k) {
                outputs[k].resize(jittered.colour.size());
                taas[k]->apply(jittered.frame, outputs[k].data());
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
    std::vector<json> movingRows;
    if (options.temporalModel.empty() || !fs::exists(options.temporalModel))
        report.notes.push_back("no temporal model (" + options.temporalModel +
                               "): the moving sequence is skipped");
    else
        report.extraHtml = movingSection(*context, options, movingRows);
    if (moving) *moving = movingRows;
    for (const std::string& n : report.notes) std::fprintf(stderr, "demo: %s\n", n.c_str());
    return writeQualityReport(report, cases);
}

}  // namespace dejag::bench

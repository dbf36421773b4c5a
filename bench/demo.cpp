#include "bench/demo.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>
#include <sstream>

#include "base/error.h"
#include "base/files.h"
#include "base/progress.h"
#include "base/timer.h"
#include "data/evaluation.h"
#include "data/frame_image.h"
#include "data/metrics.h"
#include "data/plot.h"
#include "infer/cnn.h"
#include "infer/fxaa.h"
#include "infer/taa.h"
#include "nn/model.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace dejag::bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int kCropZoom = 4;  // report crops are zoomed this much (the mosaic half as much)

// Scored as float in [0, 1] (data range 1, like the model cards); written as 8-bit PNGs.
Image rgbImage(std::vector<float> pixels, int width, int height) {
    Image image(width, height, {"R", "G", "B"}, PixelType::Float);
    image.pixels = std::move(pixels);
    return image;
}

void writePng(const fs::path& path, Image image) {
    image.storage = PixelType::UInt8;
    writeImage(path.string(), image);
}

// The window (of the crop's size) where the unfiltered frame is furthest from the truth: where the
// methods differ most.
struct Window {
    int x = 0, y = 0, width = 0, height = 0;
};
Window worstWindow(const Image& input, const Image& truth, int width, int height) {
    const int W = input.width, H = input.height;
    width = std::min(width, W), height = std::min(height, H);
    std::vector<double> integral(size_t(W + 1) * size_t(H + 1), 0.0);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            double e = 0;
            for (int c = 0; c < 3; ++c) e += std::abs(input.at(x, y, c) - truth.at(x, y, c));
            integral[size_t(y + 1) * size_t(W + 1) + size_t(x + 1)] =
                e + integral[size_t(y) * size_t(W + 1) + size_t(x + 1)] +
                integral[size_t(y + 1) * size_t(W + 1) + size_t(x)] -
                integral[size_t(y) * size_t(W + 1) + size_t(x)];
        }
    auto sum = [&](int x, int y) {
        auto at = [&](int i, int j) { return integral[size_t(j) * size_t(W + 1) + size_t(i)]; };
        return at(x + width, y + height) - at(x, y + height) - at(x + width, y) + at(x, y);
    };
    Window best{0, 0, width, height};
    double bestSum = -1;
    for (int y = 0; y + height <= H; y += 4)
        for (int x = 0; x + width <= W; x += 4)
            if (sum(x, y) > bestSum) bestSum = sum(x, y), best.x = x, best.y = y;
    return best;
}

// A crop of an RGB image, zoomed by pixel replication.
Image zoomedCrop(const Image& image, const Window& w, int zoom) {
    Image out(w.width * zoom, w.height * zoom, {"R", "G", "B"}, PixelType::Float);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x)
            for (int c = 0; c < 3; ++c) out.at(x, y, c) = image.at(w.x + x / zoom, w.y + y / zoom, c);
    return out;
}

struct MethodResult {
    std::string name;
    Image output;
    double ms = 0;
    data::ImageScore score;
    std::vector<float> ssimMap;
    std::string note;  // "gated: 42 % of tiles"
};

std::string slug(std::string text) {
    for (char& c : text)
        if (!std::isalnum(static_cast<unsigned char>(c))) c = '-';
    return text;
}

std::string htmlEscape(const std::string& text) {
    std::string out;
    for (char c : text) {
        if (c == '<')
            out += "&lt;";
        else if (c == '>')
            out += "&gt;";
        else if (c == '&')
            out += "&amp;";
        else
            out += c;
    }
    return out;
}

}  // namespace

std::vector<std::string> defaultDemoScenes() {
    return {"atrium", "hard-edges", "flowers", "pipe", "text-wall", "planes"};
}

std::vector<json> runDemo(const DemoOptions& options) {
    const int W = options.width, H = options.height;
    if (W < 32 || H < 32 || W > 4096 || H > 4096) throw Error("demo size must be 32..4096 on each side");
    const std::vector<std::string> sceneNames = options.scenes.empty() ? defaultDemoScenes() : options.scenes;
    const std::vector<std::string>& tests = data::defaultTestFamilies();
    for (const std::string& name : sceneNames) {
        const auto& catalogue = render::sceneCatalogue();
        if (std::none_of(catalogue.begin(), catalogue.end(),
                         [&](const render::SceneInfo& i) { return i.name == name; }))
            throw Error("unknown scene '" + name + "' (dejag render --list)");
    }
    // Load every model first: a bad model file fails before anything is rendered.
    struct LoadedModel {
        std::string name, path;
        int channels = 3;
    };
    std::vector<LoadedModel> models;
    std::vector<std::string> notes;
    for (const std::string& path : options.models) {
        if (!fs::exists(path)) {
            notes.push_back("model " + path + " not found: skipped (make models trains it)");
            continue;
        }
        models.push_back({fs::path(path).stem().string(), path, nn::loadModel(path).inputChannels()});
    }
    fs::create_directories(fs::path(options.out) / "images");
    const auto context = render::createOsMesaContext();
    Progress progress("demo", int64_t(sceneNames.size()), options.quiet);
    std::vector<json> rows;
    std::vector<std::string> methodOrder;
    std::vector<std::vector<Image>> mosaicRows;
    std::vector<std::string> mosaicLabels, mosaicColumns;
    std::ostringstream sections;
    for (const std::string& sceneName : sceneNames) {
        const render::Scene scene = render::buildScene(sceneName, {});
        render::Renderer renderer(*context, scene, W, H);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.truthSamples, truthOptions.adaptive = true;
        data::EvaluationItem item;
        item.id = sceneName;
        item.truth = rgbImage(frameChannels(renderer.renderTruth(0, truthOptions), 0, 3, true), W, H);
        render::FrameRequest still;
        still.buffers = render::BufferSet::parse("color,depth,id");
        const render::Frame stillFrame = renderer.render(still);
        item.input = rgbImage(frameChannels(stillFrame, 0, 3, true), W, H);
        const Image buffers = imageFromFrame(stillFrame);
        data::computeRegionMasks(item, buffers);
        const std::vector<float> ids = frameChannels(stillFrame, buffers.findChannel("id.ID"), 1, false);
        const std::vector<float> depth = frameChannels(stillFrame, buffers.findChannel("depth.Z"), 1, false);

        std::vector<MethodResult> results;
        auto timeSingle = [&](const std::string& name, const std::function<void(std::vector<float>&)>& run) {
            MethodResult r;
            r.name = name;
            std::vector<float> out(item.input.pixels.size());
            run(out);  // warm-up: plans, buffers
            r.ms = medianMilliseconds(options.repeat, [&] { run(out); });
            r.output = rgbImage(std::move(out), W, H);
            results.push_back(std::move(r));
        };
        timeSingle("no AA", [&](std::vector<float>& out) { out = item.input.pixels; });
        infer::Fxaa fxaa;
        timeSingle("FXAA", [&](std::vector<float>& out) {
            fxaa.apply(item.input.pixels.data(), out.data(), W, H, 3);
        });
        // TAA: 16 jittered frames of a still camera, the last one scored; time = median per frame.
        {
            infer::TaaOptions u, t;
            t.improved = true;
            infer::Taa taas[2] = {infer::Taa(u), infer::Taa(t)};
            std::vector<float> outputs[2];
            std::vector<double> times[2];
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
                const std::vector<float> d = frameChannels(f, 6, 1, false, 1.0f / far),
                                         motion = frameChannels(f, 7, 2, false);
                const std::vector<float> id = frameChannels(f, 9, 1, false),
                                         previousDepth = frameChannels(f, 10, 1, false, 1.0f / far);
                infer::TaaFrame frame;
                frame.width = W, frame.height = H;
                frame.colour = colour.data(), frame.albedo = albedo.data(), frame.depth = d.data();
                frame.motion = motion.data(), frame.ids = id.data(),
                frame.previousDepth = previousDepth.data();
                for (int k = 0; k < 2; ++k) {
                    outputs[k].resize(colour.size());
                    const auto start = std::chrono::steady_clock::now();
                    taas[k].apply(frame, outputs[k].data());
                    if (i >= 2)
                        times[k].push_back(std::chrono::duration<double, std::milli>(
                                               std::chrono::steady_clock::now() - start)
                                               .count());
                }
            }
            const char* names[2] = {"U-TAA", "T-TAA"};
            for (int k = 0; k < 2; ++k) {
                MethodResult r;
                r.name = names[k];
                r.ms = times[k].empty() ? 0.0 : median(times[k]);
                r.output = rgbImage(outputs[k], W, H);
                r.note = std::to_string(options.historyFrames) + " jittered frames";
                results.push_back(std::move(r));
            }
        }
        for (const LoadedModel& m : models) {
            for (bool gate : {true, false}) {
                if (!gate && m.channels == 1) continue;  // the grey replica: gated only
                infer::CnnOptions cnnOptions;
                cnnOptions.gate = gate;
                infer::CnnFilter filter(nn::loadModel(m.path), cnnOptions);
                infer::CnnBuffers gbuffers{depth.data(), ids.data()};
                timeSingle(m.name + (gate ? "" : " (ungated)"), [&](std::vector<float>& out) {
                    filter.apply(item.input.pixels.data(), out.data(), W, H, 3, gbuffers);
                });
                char note[64];
                std::snprintf(note, sizeof note, "%s%.0f %% of tiles", gate ? "gated: " : "",
                              100.0 * filter.processedFraction());
                results.back().note = note;
            }
        }

        // Scores, SSIM maps, images.
        const Window window = worstWindow(item.input, item.truth, W / 6, H / 6);
        std::vector<Image> mosaicRow{zoomedCrop(item.truth, window, 2)};
        if (mosaicColumns.empty()) mosaicColumns.push_back("truth (64 spp)");
        const bool heldOut = std::any_of(tests.begin(), tests.end(), [&](const std::string& f) {
            for (const auto& info : data::datasetFamilies())
                if (info.name == f)
                    for (const std::string& s : info.scenes)
                        if (s == sceneName) return true;
            return false;
        });
        const std::string base = slug(sceneName);
        writePng(fs::path(options.out) / "images" / (base + "_truth.png"), item.truth);
        writePng(fs::path(options.out) / "images" / (base + "_truth_crop.png"),
                 zoomedCrop(item.truth, window, kCropZoom));
        sections << "<h2>" << htmlEscape(sceneName)
                 << (heldOut ? " <small>(held-out family: never trained on)</small>" : "")
                 << "</h2>\n<div class=row>\n<figure><img src=\"images/" << base
                 << "_truth_crop.png\"><figcaption>truth, " << options.truthSamples
                 << " samples</figcaption></figure>\n";
        for (MethodResult& r : results) {
            r.score = data::scoreImage(item, r.output);
            MetricOptions metricOptions;
            metricOptions.dataRange = 1.0, metricOptions.wantSsimMap = true;
            r.ssimMap = compareImages(item.truth, r.output, metricOptions).ssimMap;
            const std::string file = base + "_" + slug(r.name);
            writePng(fs::path(options.out) / "images" / (file + ".png"), r.output);
            writePng(fs::path(options.out) / "images" / (file + "_crop.png"),
                     zoomedCrop(r.output, window, kCropZoom));
            writeSsimMapPng((fs::path(options.out) / "images" / (file + "_ssim.png")).string(), r.ssimMap, W,
                            H);
            mosaicRow.push_back(zoomedCrop(r.output, window, 2));
            if (mosaicColumns.size() < results.size() + 1) mosaicColumns.push_back(r.name);
            json row = {{"scene", sceneName}, {"held_out", heldOut}, {"method", r.name}, {"ms", r.ms},
                        {"width", W},         {"height", H},         {"note", r.note}};
            for (int k = 0; k < int(data::Region::Count); ++k) {
                const std::string region = data::regionName(data::Region(k));
                row["psnr_" + region] =
                    r.score.region[k].scored ? json(r.score.region[k].psnr) : json(nullptr);
                row["ssim_" + region] =
                    r.score.region[k].scored ? json(r.score.region[k].ssim) : json(nullptr);
            }
            rows.push_back(row);
            if (std::find(methodOrder.begin(), methodOrder.end(), r.name) == methodOrder.end())
                methodOrder.push_back(r.name);
            char caption[256];
            std::snprintf(caption, sizeof caption, "%s<br>%.2f dB · SSIM %.4f · %.1f ms%s%s",
                          htmlEscape(r.name).c_str(), r.score.region[0].psnr, r.score.region[0].ssim, r.ms,
                          r.note.empty() ? "" : "<br>", htmlEscape(r.note).c_str());
            sections << "<figure><a href=\"images/" << file << ".png\"><img src=\"images/" << file
                     << "_crop.png\"></a><figcaption>" << caption << "</figcaption>"
                     << "<a href=\"images/" << file << "_ssim.png\"><img class=map src=\"images/" << file
                     << "_ssim.png\"></a></figure>\n";
        }
        sections << "</div>\n";
        mosaicRows.push_back(std::move(mosaicRow));
        mosaicLabels.push_back(sceneName);
        progress.advance(1, sceneName);
    }
    progress.finish();

    // Means per method over scenes.
    std::vector<json> means;
    for (const std::string& method : methodOrder) {
        json mean = {{"scene", "mean"}, {"method", method}};
        std::vector<double> ms;
        for (const char* key :
             {"psnr_whole", "ssim_whole", "psnr_edge", "ssim_edge", "psnr_texture", "ssim_texture"}) {
            double sum = 0;
            int n = 0;
            for (const json& r : rows)
                if (r["method"] == method && !r[key].is_null()) sum += r[key].get<double>(), ++n;
            mean[key] = n ? json(sum / n) : json(nullptr);
        }
        for (const json& r : rows)
            if (r["method"] == method) ms.push_back(r["ms"].get<double>());
        mean["ms"] = median(ms);
        means.push_back(mean);
    }
    rows.insert(rows.end(), means.begin(), means.end());

    // Files: CSV, JSON, the Pareto plot, the mosaic, the report.
    const fs::path out(options.out);
    {
        std::ostringstream csv;
        csv << "scene,method,ms,psnr_whole,ssim_whole,psnr_edge,ssim_edge,psnr_texture,ssim_texture\n";
        for (const json& r : rows) {
            csv << r["scene"].get<std::string>() << ',' << r["method"].get<std::string>() << ','
                << r["ms"].get<double>();
            for (const char* key :
                 {"psnr_whole", "ssim_whole", "psnr_edge", "ssim_edge", "psnr_texture", "ssim_texture"})
                csv << ',' << (r[key].is_null() ? std::string() : std::to_string(r[key].get<double>()));
            csv << '\n';
        }
        writeTextFileAtomically((out / "results.csv").string(), csv.str());
        writeTextFileAtomically((out / "results.json").string(), json(rows).dump(2) + "\n");
    }
    {
        Plot pareto;
        pareto.title =
            "run time against error (" + std::to_string(W) + "x" + std::to_string(H) + ", mean over scenes)";
        pareto.xLabel = "ms per frame (median, log scale)";
        pareto.yLabel = "PSNR (dB)";
        pareto.logX = true;
        PlotSeries points;
        points.lines = false, points.markers = true, points.labels = true;
        for (const json& m : means) {
            points.x.push_back(std::max(m["ms"].get<double>(), 0.01));
            points.y.push_back(m["psnr_whole"].is_null() ? NAN : m["psnr_whole"].get<double>());
            points.pointLabels.push_back(m["method"]);
        }
        pareto.series.push_back(points);
        writePlotPng((out / "pareto.png").string(), pareto);
    }
    writeMosaicPng((out / "mosaic.png").string(), mosaicRows, mosaicLabels, mosaicColumns);
    {
        std::ostringstream html;
        html << "<!doctype html>\n<html><head><meta charset=utf-8><title>dejag demo</title>\n<style>"
                "body{font-family:sans-serif;margin:24px;color:#222}table{border-collapse:collapse}"
                "td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}th{background:#f3f3f3}"
                "td:first-child{text-align:left}.row{display:flex;flex-wrap:wrap;gap:8px}"
                "figure{margin:0;font-size:12px}img{image-rendering:pixelated;display:block}"
                "img.map{width:240px;margin-top:4px}</style></head><body>\n";
        html << "<h1>dejag: anti-aliasing methods against the supersampled truth</h1>\n<p>" << W << "×" << H
             << " frames, truth: " << options.truthSamples
             << " Halton samples per pixel (adaptive). Scores on sRGB values; edge = pixels within 1 px of a "
                "geometric edge, texture = detailed pixels away from edges. Crops are the region where the "
                "unfiltered frame is worst, zoomed "
             << kCropZoom << "× (click for the full frame); below each, the SSIM map (yellow = 1).</p>\n";
        for (const std::string& n : notes) html << "<p><b>Note:</b> " << htmlEscape(n) << "</p>\n";
        html
            << "<h2>Mean over scenes</h2>\n<table><tr><th>method</th><th>PSNR (dB)</th><th>SSIM</th><th>edge "
               "PSNR</th><th>texture PSNR</th><th>ms per frame</th></tr>\n";
        for (const json& m : means) {
            auto cell = [&](const char* key, const char* format) {
                char text[32];
                if (m[key].is_null()) return std::string("–");
                std::snprintf(text, sizeof text, format, m[key].get<double>());
                return std::string(text);
            };
            html << "<tr><td>" << htmlEscape(m["method"]) << "</td><td>" << cell("psnr_whole", "%.2f")
                 << "</td><td>" << cell("ssim_whole", "%.4f") << "</td><td>" << cell("psnr_edge", "%.2f")
                 << "</td><td>" << cell("psnr_texture", "%.2f") << "</td><td>" << cell("ms", "%.2f")
                 << "</td></tr>\n";
        }
        html << "</table>\n<p><img src=\"pareto.png\" width=720></p>\n" << sections.str();
        html << "<h2>Mosaic</h2><p><img src=\"mosaic.png\" style=\"max-width:100%\"></p>\n</body></html>\n";
        writeTextFileAtomically((out / "report.html").string(), html.str());
    }
    for (const std::string& n : notes) std::fprintf(stderr, "demo: %s\n", n.c_str());
    return rows;
}

}  // namespace dejag::bench

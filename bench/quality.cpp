#include "bench/quality.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <map>
#include <sstream>

#include "base/error.h"
#include "base/files.h"
#include "base/progress.h"
#include "base/simd.h"
#include "base/timer.h"
#include "data/dataset.h"
#include "data/frame_image.h"
#include "data/metrics.h"
#include "data/plot.h"
#include "infer/filter.h"
#include "nn/model.h"
#include "render/renderer.h"
#include "render/scene.h"

namespace dejag::bench {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int kCropZoom = 4;  // report crops are zoomed this much (the mosaic half as much)

Image rgbImage(std::vector<float> pixels, int width, int height) {
    Image image(width, height, {"R", "G", "B"}, PixelType::Float);
    image.pixels = std::move(pixels);
    return image;
}

void writePng(const fs::path& path, Image image) {
    image.storage = PixelType::UInt8;
    writeImage(path.string(), image);
}

}  // namespace

Window worstWindow(const Image& input, const Image& truth, int width, int height) {
    const int W = input.width, H = input.height;
    width = std::clamp(width, 1, W), height = std::clamp(height, 1, H);
    std::vector<double> integral(size_t(W + 1) * size_t(H + 1), 0.0);
    auto at = [&](int i, int j) -> double& { return integral[size_t(j) * size_t(W + 1) + size_t(i)]; };
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            double e = 0;
            for (int c = 0; c < 3; ++c) e += std::abs(input.at(x, y, c) - truth.at(x, y, c));
            at(x + 1, y + 1) = e + at(x + 1, y) + at(x, y + 1) - at(x, y);
        }
    Window best{0, 0, width, height};
    double bestSum = -1;
    for (int y = 0; y + height <= H; y += 2)
        for (int x = 0; x + width <= W; x += 2) {
            const double s = at(x + width, y + height) - at(x, y + height) - at(x + width, y) + at(x, y);
            if (s > bestSum) bestSum = s, best.x = x, best.y = y;
        }
    return best;
}

Image zoomedCrop(const Image& image, const Window& w, int zoom) {
    Image out(w.width * zoom, w.height * zoom, {"R", "G", "B"}, PixelType::Float);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x)
            for (int c = 0; c < 3; ++c) out.at(x, y, c) = image.at(w.x + x / zoom, w.y + y / zoom, c);
    return out;
}

namespace {

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

const char* const kKeys[] = {"psnr_whole", "ssim_whole",   "psnr_edge",
                             "ssim_edge",  "psnr_texture", "ssim_texture"};

constexpr float kDifferenceGain = 8.0f;  // difference crops show |method - truth| times this

// SSIM on a scale that separates good methods: t = -log10(1 - SSIM) / 3, so 0.9, 0.99 and 0.999 lie a
// third of the bar apart (a linear scale puts every method above 0.98 in its top fiftieth).
float ssimScale(float ssim) {
    if (!std::isfinite(ssim)) return 0.0f;
    const float gap = std::max(1.0f - ssim, 1e-3f);
    return std::clamp(-std::log10(gap) / 3.0f, 0.0f, 1.0f);
}

// A zoomed crop of a scalar map through the colour map.
Image zoomedMapCrop(const std::vector<float>& map, int width, const Window& w, int zoom,
                    float (*scale)(float)) {
    Image out(w.width * zoom, w.height * zoom, {"R", "G", "B"}, PixelType::Float);
    for (int y = 0; y < out.height; ++y)
        for (int x = 0; x < out.width; ++x) {
            const Rgb c =
                viridis(scale(map[size_t(w.y + y / zoom) * size_t(width) + size_t(w.x + x / zoom)]));
            out.at(x, y, 0) = c.r, out.at(x, y, 1) = c.g, out.at(x, y, 2) = c.b;
        }
    return out;
}

float differenceScale(float d) {
    return std::clamp(d * kDifferenceGain, 0.0f, 1.0f);
}

// The mean |a - b| over R, G, B of each pixel.
std::vector<float> differenceMap(const Image& a, const Image& b) {
    std::vector<float> map(a.pixelCount());
    for (size_t p = 0; p < map.size(); ++p) {
        float sum = 0;
        for (size_t c = 0; c < 3; ++c) sum += std::abs(a.pixels[p * 3 + c] - b.pixels[p * 3 + c]);
        map[p] = sum / 3.0f;
    }
    return map;
}

// The full frame with the crop's window outlined (2 px, red, just outside the window where it fits).
Image markedFrame(Image frame, const Window& w) {
    for (int y = w.y - 2; y < w.y + w.height + 2; ++y)
        for (int x = w.x - 2; x < w.x + w.width + 2; ++x) {
            if (x < 0 || y < 0 || x >= frame.width || y >= frame.height) continue;
            if (x >= w.x && x < w.x + w.width && y >= w.y && y < w.y + w.height) continue;
            frame.at(x, y, 0) = 1.0f, frame.at(x, y, 1) = 0.15f, frame.at(x, y, 2) = 0.15f;
        }
    return frame;
}

// The colour bar of a scale, as a CSS gradient with ticks: (value shown, position 0..1).
std::string colourBar(const std::string& title, const std::vector<std::pair<std::string, float>>& ticks) {
    std::ostringstream bar;
    bar << "<div class=bar><span>" << title
        << "</span><div class=grad style=\"background:linear-gradient(to right";
    for (int i = 0; i <= 8; ++i) {
        const Rgb c = viridis(float(i) / 8.0f);
        char stop[64];
        std::snprintf(stop, sizeof stop, ",rgb(%d,%d,%d) %d%%", int(c.r * 255 + 0.5f), int(c.g * 255 + 0.5f),
                      int(c.b * 255 + 0.5f), i * 100 / 8);
        bar << stop;
    }
    bar << ")\">";
    for (const auto& [label, at] : ticks)
        bar << "<i style=\"left:" << int(at * 100 + 0.5f) << "%\">" << label << "</i>";
    bar << "</div></div>\n";
    return bar.str();
}

// The flip and swipe viewer: a method's crop over another's (the truth by default). Swipe moves the
// boundary; flip shows one, then the other, whole. Opening the report with #flip=CASE&a=METHOD&b=METHOD
// selects them, shows that case's viewer alone on the page and flips once (a scripted click: what the
// headless-browser test does); #view=CASE shows the viewer alone without a click (a link to one
// comparison).
const char* const kViewerScript = R"(<script>
(function () {
  var hash = {};
  location.hash.replace(/^#/, '').split('&').forEach(function (kv) {
    var p = kv.split('='); if (p[0]) hash[decodeURIComponent(p[0])] = decodeURIComponent(p[1] || '');
  });
  document.querySelectorAll('.cmp').forEach(function (c, index) {
    var a = c.querySelector('.sel-a'), b = c.querySelector('.sel-b'), top = c.querySelector('.im-a'),
        under = c.querySelector('.im-b'), swipe = c.querySelector('.swipe'), flip = c.querySelector('.flip'),
        shown = c.querySelector('.shown'), mode = 'swipe', showA = true;
    function pick(select, name) {
      for (var i = 0; i < select.options.length; ++i) if (select.options[i].text === name) select.selectedIndex = i;
    }
    function update() {
      top.src = a.value; under.src = b.value;
      var cut = mode === 'flip' ? (showA ? 0 : 100) : 100 - swipe.value;
      top.style.clipPath = 'inset(0 ' + cut + '% 0 0)';
      shown.textContent = mode === 'flip' ? (showA ? a.options[a.selectedIndex].text : b.options[b.selectedIndex].text)
                                          : a.options[a.selectedIndex].text + ' | ' + b.options[b.selectedIndex].text;
    }
    a.onchange = b.onchange = update;
    swipe.oninput = function () { mode = 'swipe'; update(); };
    flip.onclick = function () { if (mode === 'flip') showA = !showA; else { mode = 'flip'; showA = false; } update(); };
    if (hash.a) pick(a, hash.a); else if (a.options.length > 1) a.selectedIndex = 1;
    if (hash.b) pick(b, hash.b);
    update();
    var focus = hash.flip !== undefined ? hash.flip : hash.view;
    if (focus !== undefined && Number(focus) === index) {
      document.body.classList.add('focus');
      c.classList.add('focused');
    }
    if (hash.flip !== undefined && Number(hash.flip) === index) flip.click();
  });
})();
</script>
)";

}  // namespace

// ---- Single-frame methods -----------------------------------------------------------------------------

struct StillMethods::Impl {
    // Every row is a filter made by name through the one face (infer/filter.h).
    struct Method {
        std::string name;
        std::unique_ptr<infer::Filter> filter;
        bool gated = false;  // a network with its gate on (the note says how much it ran on)
    };
    std::vector<Method> methods;
    std::vector<std::string> notes;

    void add(std::string name, const std::string& chain, const infer::FilterParameters& parameters,
             bool gated = false) {
        methods.push_back({std::move(name), infer::makeFilter(chain, parameters), gated});
    }

    void apply(Method& m, const Image& in, const float* depth, const float* ids, std::vector<float>& out,
               std::string& note) {
        out.resize(in.pixels.size());
        infer::Frame frame;
        frame.width = in.width, frame.height = in.height, frame.channels = 3;
        frame.colour = in.pixels.data(), frame.depth = depth, frame.ids = ids;
        m.filter->apply(frame, out.data());
        const infer::FilterFigures& f = m.filter->figures();
        if (m.filter->stages().empty() && m.filter->name() != "cnn") return;  // no AA, FXAA: no note
        double passed = 0;
        for (const auto& [key, value] : f.extra)
            if (key == "passed_through_fraction") passed = value;
        char text[64];
        if (m.gated && passed > 0)  // a kernel-predicting network
            std::snprintf(text, sizeof text, "gated: %.0f %% of tiles, %.0f %% of their pixels passed",
                          100.0 * f.processedFraction, 100.0 * passed);
        else if (m.gated)
            std::snprintf(text, sizeof text, "gated: %.0f %% of tiles", 100.0 * f.processedFraction);
        else
            std::snprintf(text, sizeof text, "%.0f %% of tiles", 100.0 * f.processedFraction);
        note = text;
    }
};

StillMethods::StillMethods(const Options& options) : impl_(std::make_unique<Impl>()) {
    Impl& impl = *impl_;
    impl.add("no AA", "none", {});
    for (int preset : options.fxaaPresets)
        impl.add(options.fxaaPresets.size() == 1 ? "FXAA" : "FXAA " + std::to_string(preset), "fxaa",
                 {{"preset", std::to_string(preset)}});
    impl.add("SMAA", "smaa", {});
    for (const std::string& path : options.models) {
        if (!fs::exists(path)) {
            impl.notes.push_back("model " + path + " not found: skipped (make models trains it)");
            continue;
        }
        // Named by the file's stem; two models of the same stem (e.g. a model against its new version)
        // are named by their folder too, so their rows stay apart.
        std::string name = fs::path(path).stem().string();
        for (const std::string& other : options.models)
            if (other != path && fs::path(other).stem() == fs::path(path).stem())
                name = (fs::path(path).parent_path().filename() / fs::path(path).stem()).string();
        const bool rgb = nn::loadModel(path).inputChannels() != 1;  // RGB, or RGB and a guide
        for (int variant = 0; variant < 5; ++variant) {
            const bool gate = variant != 1 && variant != 4, chain = variant == 2, bf16 = variant >= 3;
            if (!gate && (!rgb || !options.ungated)) continue;
            if (chain && !options.chains) continue;
            if (bf16 && (!rgb || !options.bf16 || !bf16Available())) continue;
            impl.add(
                chain ? "FXAA > " + name : name + (bf16 ? " bf16" : "") + (gate ? "" : " (ungated)"),
                chain ? "fxaa,cnn" : "cnn",
                {{"model", path}, {"gate", gate ? "auto" : "off"}, {"precision", bf16 ? "bf16" : "fp32"}},
                gate);
        }
    }
}

StillMethods::~StillMethods() = default;

const std::vector<std::string>& StillMethods::notes() const {
    return impl_->notes;
}

std::vector<std::string> StillMethods::names() const {
    std::vector<std::string> names;
    for (const auto& m : impl_->methods) names.push_back(m.name);
    return names;
}

void StillMethods::run(QualityCase& c, int repeat) {
    const float* depth = c.depth.empty() ? nullptr : c.depth.data();
    const float* ids = c.ids.empty() ? nullptr : c.ids.data();
    for (Impl::Method& m : impl_->methods) {
        MethodResult r;
        r.name = m.name;
        std::vector<float> out;
        impl_->apply(m, c.item.input, depth, ids, out, r.note);  // warm-up: plans, buffers
        r.ms = medianMilliseconds(repeat, [&] { impl_->apply(m, c.item.input, depth, ids, out, r.note); });
        r.output = rgbImage(std::move(out), c.item.input.width, c.item.input.height);
        c.methods.push_back(std::move(r));
    }
}

std::vector<double> StillMethods::time(const Image& frame, const float* depth, const float* ids, int repeat) {
    std::vector<double> ms;
    std::vector<float> out;
    std::string note;
    for (Impl::Method& m : impl_->methods) {
        impl_->apply(m, frame, depth, ids, out, note);
        ms.push_back(medianMilliseconds(repeat, [&] { impl_->apply(m, frame, depth, ids, out, note); }));
    }
    return ms;
}

void scoreCase(QualityCase& c) {
    for (MethodResult& r : c.methods) r.score = data::scoreImage(c.item, r.output);
}

// ---- The report ---------------------------------------------------------------------------------------

std::vector<json> writeQualityReport(const ReportOptions& options, const std::vector<QualityCase>& cases) {
    const fs::path out(options.out);
    fs::create_directories(out / "images");
    std::vector<json> rows;
    std::vector<std::string> methodOrder;
    std::vector<std::vector<Image>> mosaicRows;
    std::vector<std::string> mosaicLabels, mosaicColumns{"truth"};
    std::ostringstream sections;
    for (const QualityCase& c : cases) {
        for (const MethodResult& r : c.methods) {
            json row = {{"scene", c.name}, {"held_out", c.heldOut},       {"method", r.name},
                        {"ms", r.ms},      {"width", c.item.input.width}, {"height", c.item.input.height},
                        {"note", r.note}};
            for (int k = 0; k < int(data::Region::Count); ++k) {
                const std::string region = data::regionName(data::Region(k));
                const data::RegionScore& s = r.score.region[k];
                row["psnr_" + region] = s.scored ? json(std::min(s.psnr, 100.0)) : json(nullptr);
                row["ssim_" + region] = s.scored ? json(s.ssim) : json(nullptr);
            }
            rows.push_back(row);
            if (std::find(methodOrder.begin(), methodOrder.end(), r.name) == methodOrder.end())
                methodOrder.push_back(r.name);
        }
        if (!c.inReport) continue;
        const int W = c.item.input.width, H = c.item.input.height;
        const Window window =
            worstWindow(c.item.input, c.item.truth, std::max(16, W / 6), std::max(12, H / 6));
        const std::string base = slug(c.name);
        writePng(out / "images" / (base + "_truth.png"), c.item.truth);
        writePng(out / "images" / (base + "_truth_crop.png"), zoomedCrop(c.item.truth, window, kCropZoom));
        writePng(out / "images" / (base + "_where.png"), markedFrame(c.item.truth, window));
        std::vector<Image> mosaicRow{zoomedCrop(c.item.truth, window, 2)};
        sections << "<h2>" << htmlEscape(c.name)
                 << (c.heldOut ? " <small>(held-out family: never trained on)</small>" : "") << "</h2>\n";
        // The viewer: any method over any other, the truth beneath by default.
        std::string choices = "<option value=\"images/" + base + "_truth_crop.png\">truth</option>";
        for (const MethodResult& r : c.methods)
            choices += "<option value=\"images/" + base + "_" + slug(r.name) + "_crop.png\">" +
                       htmlEscape(r.name) + "</option>";
        const std::string firstCrop = "images/" + base + "_" +
                                      (c.methods.empty() ? std::string("truth") : slug(c.methods[0].name)) +
                                      "_crop.png";
        sections
            << "<div class=cmp><div class=controls><select class=sel-a>" << choices
            << "</select> over <select class=sel-b>" << choices
            << "</select> <input class=swipe type=range min=0 max=100 value=50 title=swipe> <button "
               "class=flip>flip</button> <span class=shown></span></div><div class=stage><img class=im-b "
               "src=\"images/"
            << base << "_truth_crop.png\"><img class=im-a src=\"" << firstCrop
            << "\"></div></div>\n<div class=row>\n<figure><a href=\"images/" << base
            << "_truth.png\"><img src=\"images/" << base
            << "_truth_crop.png\"></a><figcaption>truth</figcaption><a href=\"images/" << base
            << "_truth.png\"><img class=where src=\"images/" << base
            << "_where.png\" title=\"the crop on the full frame\"></a></figure>\n";
        for (const MethodResult& r : c.methods) {
            MetricOptions metricOptions;
            metricOptions.dataRange = 1.0, metricOptions.wantSsimMap = true;
            const std::vector<float> map = compareImages(c.item.truth, r.output, metricOptions).ssimMap;
            const std::string file = base + "_" + slug(r.name);
            writePng(out / "images" / (file + ".png"), r.output);
            writePng(out / "images" / (file + "_crop.png"), zoomedCrop(r.output, window, kCropZoom));
            writeSsimMapPng((out / "images" / (file + "_ssim.png")).string(), map, W, H);
            writePng(out / "images" / (file + "_ssim_crop.png"),
                     zoomedMapCrop(map, W, window, kCropZoom, ssimScale));
            writePng(
                out / "images" / (file + "_diff_crop.png"),
                zoomedMapCrop(differenceMap(r.output, c.item.truth), W, window, kCropZoom, differenceScale));
            mosaicRow.push_back(zoomedCrop(r.output, window, 2));
            if (mosaicColumns.size() < c.methods.size() + 1) mosaicColumns.push_back(r.name);
            char caption[320];
            std::snprintf(caption, sizeof caption, "%s<br>%.2f dB · SSIM %.4f · %.2f ms%s%s",
                          htmlEscape(r.name).c_str(), std::min(r.score.region[0].psnr, 100.0),
                          r.score.region[0].ssim, r.ms, r.note.empty() ? "" : "<br>",
                          htmlEscape(r.note).c_str());
            sections
                << "<figure><a href=\"images/" << file << ".png\"><img src=\"images/" << file
                << "_crop.png\"></a><figcaption>" << caption << "</figcaption><a href=\"images/" << file
                << "_ssim.png\"><img src=\"images/" << file
                << "_ssim_crop.png\" title=\"SSIM (click: the whole frame's map)\"></a><img src=\"images/"
                << file << "_diff_crop.png\" title=\"difference to the truth\"></figure>\n";
        }
        sections << "</div>\n";
        if (mosaicRows.empty() || mosaicRows[0].size() == mosaicRow.size()) {
            mosaicRows.push_back(std::move(mosaicRow));
            mosaicLabels.push_back(c.name);
        }
    }

    // Means per method over cases (PSNR capped at 100 dB per image: identical images are infinite).
    std::vector<json> means;
    for (const std::string& method : methodOrder) {
        json mean = {{"scene", "mean"}, {"method", method}};
        std::vector<double> ms;
        for (const char* key : kKeys) {
            double sum = 0;
            int n = 0;
            for (const json& r : rows)
                if (r["method"] == method && !r[key].is_null()) sum += r[key].get<double>(), ++n;
            mean[key] = n ? json(sum / n) : json(nullptr);
        }
        for (const json& r : rows)
            if (r["method"] == method) ms.push_back(r["ms"].get<double>());
        mean["ms"] = median(ms);
        mean["cases"] = ms.size();
        for (const auto& [name, value] : options.fullHdMs)
            if (name == method) mean["ms_1080p"] = value;
        if (auto it = options.fullHdSceneMs.find(method); it != options.fullHdSceneMs.end())
            for (size_t i = 0; i < it->second.size() && i < options.fullHdScenes.size(); ++i)
                mean["ms_1080p_scenes"][options.fullHdScenes[i]] = it->second[i];
        means.push_back(mean);
    }
    rows.insert(rows.end(), means.begin(), means.end());

    {
        std::ostringstream csv;
        csv << "scene,method,ms,ms_1080p,psnr_whole,ssim_whole,psnr_edge,ssim_edge,psnr_texture,ssim_"
               "texture\n";
        for (const json& r : rows) {
            csv << r["scene"].get<std::string>() << ',' << r["method"].get<std::string>() << ','
                << r["ms"].get<double>() << ','
                << (r.contains("ms_1080p") ? std::to_string(r["ms_1080p"].get<double>()) : "");
            for (const char* key : kKeys)
                csv << ',' << (r[key].is_null() ? std::string() : std::to_string(r[key].get<double>()));
            csv << '\n';
        }
        writeTextFileAtomically((out / "results.csv").string(), csv.str());
        writeTextFileAtomically((out / "results.json").string(), json(rows).dump(2) + "\n");
    }
    const bool useFullHd = !options.fullHdMs.empty();
    {
        Plot pareto;
        pareto.title = "run time against error (mean PSNR over the frames)";
        pareto.xLabel =
            useFullHd ? "ms per 1920x1080 frame (median, log scale)" : "ms per frame (median, log scale)";
        pareto.yLabel = "PSNR (dB)";
        pareto.logX = true;
        pareto.legendOutside = true, pareto.width = 1100;
        // One series per method: its own colour, named in the legend (and beside its marker).
        for (const json& m : means) {
            PlotSeries point;
            point.name = m["method"].get<std::string>();
            point.lines = false, point.markers = true, point.labels = true;
            const double ms =
                useFullHd && m.contains("ms_1080p") ? m["ms_1080p"].get<double>() : m["ms"].get<double>();
            point.x.push_back(std::max(ms, 0.01));
            point.y.push_back(m["psnr_whole"].is_null() ? NAN : m["psnr_whole"].get<double>());
            point.pointLabels.push_back(point.name);
            pareto.series.push_back(point);
        }
        writePlotPng((out / "pareto.png").string(), pareto);
    }
    if (!mosaicRows.empty())
        writeMosaicPng((out / "mosaic.png").string(), mosaicRows, mosaicLabels, mosaicColumns);
    {
        std::ostringstream html;
        html
            << "<!doctype html>\n<html><head><meta charset=utf-8><title>" << htmlEscape(options.title)
            << "</"
               "title>\n<style>body{font-family:sans-serif;margin:24px;color:#222}table{border-collapse:"
               "collapse}"
               "td,th{border:1px solid #ccc;padding:4px 8px;text-align:right}th{background:#f3f3f3}"
               "td:first-child{text-align:left}.row{display:flex;flex-wrap:wrap;gap:8px}"
               "figure{margin:0;font-size:12px}img{image-rendering:pixelated;display:block}"
               "img.map{width:240px;margin-top:4px}img.where{width:240px;margin-top:4px}"
               ".cmp{margin:8px 0}.stage{position:relative;display:inline-block}.stage img{display:block}"
               "body.focus>*{display:none}body.focus>.cmp.focused{display:block}.stage "
               "img{width:480px}.stage "
               ".im-a{position:absolute;left:0;top:0}.controls{margin-bottom:4px;font-size:13px}"
               ".bar{display:inline-block;margin:4px 24px 12px 0;font-size:12px}.bar .grad{position:relative;"
               "width:320px;height:14px;margin-top:2px}.bar i{position:absolute;top:16px;font-style:normal;"
               "transform:translateX(-50%);white-space:nowrap}</style></head><body>\n";
        html << "<h1>" << htmlEscape(options.title) << "</h1>\n<p>" << options.intro << "</p>\n";
        for (const std::string& n : options.notes) html << "<p><b>Note:</b> " << htmlEscape(n) << "</p>\n";
        html
            << "<h2>Mean over frames</h2>\n<table><tr><th>method</th><th>PSNR (dB)</th><th>SSIM</th><th>edge "
               "PSNR</th><th>edge SSIM</th><th>texture PSNR</th><th>texture SSIM</th><th>ms per frame</th>"
            << (useFullHd ? "<th>ms at 1920×1080</th>" : "") << "</tr>\n";
        for (const json& m : means) {
            auto cell = [&](const char* key, const char* format) {
                if (!m.contains(key) || m[key].is_null()) return std::string("–");
                char text[32];
                std::snprintf(text, sizeof text, format, m[key].get<double>());
                return std::string(text);
            };
            html << "<tr><td>" << htmlEscape(m["method"]) << "</td><td>" << cell("psnr_whole", "%.2f")
                 << "</td><td>" << cell("ssim_whole", "%.4f") << "</td><td>" << cell("psnr_edge", "%.2f")
                 << "</td><td>" << cell("ssim_edge", "%.4f") << "</td><td>" << cell("psnr_texture", "%.2f")
                 << "</td><td>" << cell("ssim_texture", "%.4f") << "</td><td>" << cell("ms", "%.2f")
                 << "</td>" << (useFullHd ? "<td>" + cell("ms_1080p", "%.1f") + "</td>" : "") << "</tr>\n";
        }
        html << "</table>\n<p><img src=\"pareto.png\" width=880></p>\n"
             << "<p>Crops: where the unfiltered frame is furthest from the truth, zoomed " << kCropZoom
             << "× (click for the full frame; the red box under the truth shows where the crop lies). Above "
                "each "
                "scene, a viewer: pick a method and what lies beneath it, then swipe the boundary or flip "
                "between the two. Under each method, its SSIM map and its difference to the truth (× "
             << int(kDifferenceGain) << "), cropped like the crops, on these scales:</p>\n"
             << colourBar("SSIM", {{"0", 0.0f}, {"0.9", 1.0f / 3}, {"0.99", 2.0f / 3}, {"≥ 0.999", 1.0f}})
             << colourBar("|method − truth| (mean of R, G, B)",
                          {{"0", 0.0f}, {"1/32", 0.25f}, {"1/16", 0.5f}, {"≥ 1/8", 1.0f}})
             << sections.str() << options.extraHtml;
        if (!mosaicRows.empty())
            html << "<h2>Mosaic</h2><p><img src=\"mosaic.png\" style=\"max-width:100%\"></p>\n";
        html << kViewerScript << "</body></html>\n";
        writeTextFileAtomically((out / "report.html").string(), html.str());
    }
    return rows;
}

void printQualityRows(const std::vector<json>& rows, bool asJson, bool meansOnly) {
    if (asJson) {
        for (const json& r : rows) std::printf("%s\n", r.dump().c_str());
        return;
    }
    const bool fullHd =
        std::any_of(rows.begin(), rows.end(), [](const json& r) { return r.contains("ms_1080p"); });
    std::printf("%-14s %-26s %9s %8s %9s %9s %9s%s  %s\n", "scene", "method", "PSNR dB", "SSIM", "edge dB",
                "texture", "ms", fullHd ? "  ms 1080p" : "", "");
    for (const json& r : rows) {
        if (meansOnly && r["scene"] != "mean") continue;
        auto number = [&](const char* key, const char* format) {
            if (!r.contains(key) || r[key].is_null()) return std::string("-");
            char text[32];
            std::snprintf(text, sizeof text, format, r[key].get<double>());
            return std::string(text);
        };
        std::printf(
            "%-14s %-26s %9s %8s %9s %9s %9s%s  %s\n", r["scene"].get<std::string>().c_str(),
            r["method"].get<std::string>().c_str(), number("psnr_whole", "%.2f").c_str(),
            number("ssim_whole", "%.4f").c_str(), number("psnr_edge", "%.2f").c_str(),
            number("psnr_texture", "%.2f").c_str(), number("ms", "%.2f").c_str(),
            fullHd ? ("  " + std::string(9 - std::min<size_t>(9, number("ms_1080p", "%.1f").size()), ' ') +
                      number("ms_1080p", "%.1f"))
                         .c_str()
                   : "",
            r.value("note", "").c_str());
    }
}

// ---- dejag bench quality ------------------------------------------------------------------------------

std::vector<json> benchQuality(const QualityBenchOptions& options) {
    if (options.data.empty() && options.pairs.empty())
        throw Error("give a dataset folder (--data) and/or --pairs");
    if (options.repeat < 1) throw Error("--repeat must be >= 1");
    StillMethods::Options methodOptions;
    methodOptions.models = options.models;
    methodOptions.fxaaPresets = {12, 23, 39};
    methodOptions.chains = true;
    StillMethods methods(methodOptions);
    std::vector<QualityCase> cases;
    if (!options.data.empty()) {
        for (data::EvaluationItem& item :
             data::loadEvaluationItems(options.data, data::Split::Test, options.limit)) {
            QualityCase c;
            c.name = item.family + "/" + item.id;
            c.heldOut = true;
            c.item = std::move(item);
            cases.push_back(std::move(c));
        }
    }
    if (!options.pairs.empty()) {
        if (!fs::is_directory(options.pairs)) throw Error("--pairs '" + options.pairs + "' is not a folder");
        std::vector<fs::path> inputs;
        for (const auto& entry : fs::directory_iterator(options.pairs)) {
            const std::string stem = entry.path().stem().string();
            if (stem.size() > 6 && stem.compare(stem.size() - 6, 6, "_input") == 0)
                inputs.push_back(entry.path());
        }
        std::sort(inputs.begin(), inputs.end());
        if (inputs.empty()) throw Error("--pairs '" + options.pairs + "' holds no NAME_input.* image");
        for (const fs::path& input : inputs) {
            const std::string stem = input.stem().string(), name = stem.substr(0, stem.size() - 6);
            fs::path truth;
            for (const auto& entry : fs::directory_iterator(options.pairs))
                if (entry.path().stem().string() == name + "_truth") truth = entry.path();
            if (truth.empty()) throw Error("pair '" + name + "' has no " + name + "_truth image");
            QualityCase c;
            c.name = name;
            c.item.id = name;
            Image in = readImage(input.string()), tr = readImage(truth.string());
            auto toSrgb = [](Image image, const std::string& what) {
                if (image.findChannel("R") != 0 || image.findChannel("G") != 1 || image.findChannel("B") != 2)
                    throw Error("'" + what + "' has no R, G, B channels first");
                const bool linear = image.storage == PixelType::Half || image.storage == PixelType::Float;
                Image out(image.width, image.height, {"R", "G", "B"}, PixelType::Float);
                for (size_t p = 0; p < image.pixelCount(); ++p)
                    for (size_t k = 0; k < 3; ++k) {
                        const float v = image.pixels[p * size_t(image.channels()) + k];
                        out.pixels[p * 3 + k] =
                            std::clamp(linear ? linearToSrgb(std::max(v, 0.0f)) : v, 0.0f, 1.0f);
                    }
                return out;
            };
            c.item.input = toSrgb(std::move(in), input.string());
            c.item.truth = toSrgb(std::move(tr), truth.string());
            if (c.item.input.width != c.item.truth.width || c.item.input.height != c.item.truth.height)
                throw Error("pair '" + name + "': input and truth differ in size");
            // No buffers: scored on whole images only.
            for (int r = 0; r < int(data::Region::Count); ++r) {
                c.item.masks[r] = Image(c.item.input.width, c.item.input.height, {"Y"}, PixelType::Float);
                c.item.hasRegion[r] = r == int(data::Region::Whole);
            }
            cases.push_back(std::move(c));
        }
    }
    Progress progress("bench quality", int64_t(cases.size()), options.quiet);
    for (size_t i = 0; i < cases.size(); ++i) {
        methods.run(cases[i], options.repeat);
        scoreCase(cases[i]);
        // Only a spread of cases keeps its images (crops for the report); the rest keep their scores.
        cases[i].inReport =
            options.reportItems > 0 && (i * size_t(options.reportItems)) / cases.size() !=
                                           ((i + 1) * size_t(options.reportItems)) / cases.size();
        if (!cases[i].inReport)
            for (MethodResult& r : cases[i].methods) r.output = Image();
        progress.advance(1);
    }
    progress.finish();
    ReportOptions report;
    report.out = options.out;
    report.title = "dejag bench quality: run time against error";
    report.intro =
        "Every single-frame method on the test split (families never trained on)" +
        std::string(options.pairs.empty() ? "" : " and the given pairs") +
        ", against the 128-sample truth. Scores on sRGB values in [0, 1]; edge = within 1 px of a "
        "geometric edge, texture = detailed pixels 3 px or more from one. TAA needs sequences: see "
        "dejag demo and dejag bench taa.";
    report.notes = methods.notes();
    if (options.fullHd) {
        // The test families' scenes rendered at 1920x1080 with their buffers (the size the targets are set
        // at); a method's figure is the median over the scenes of its median time on each.
        const auto context = render::createOsMesaContext();
        for (const std::string& family : data::defaultTestFamilies())
            for (const data::FamilyInfo& f : data::datasetFamilies())
                if (f.name == family)
                    report.fullHdScenes.insert(report.fullHdScenes.end(), f.scenes.begin(), f.scenes.end());
        const std::vector<std::string> names = methods.names();
        for (const std::string& name : report.fullHdScenes) {
            const render::Scene scene = render::buildScene(name);
            render::Renderer renderer(*context, scene, 1920, 1080);
            render::FrameRequest request;
            request.buffers = render::BufferSet::parse("color,depth,id");
            const render::Frame frame = renderer.render(request);
            const Image rgb = rgbImage(frameChannels(frame, 0, 3, true), 1920, 1080);
            const Image buffers = imageFromFrame(render::Frame(frame));
            const std::vector<float> depth = frameChannels(frame, buffers.findChannel("depth.Z"), 1, false);
            const std::vector<float> ids = frameChannels(frame, buffers.findChannel("id.ID"), 1, false);
            const std::vector<double> ms = methods.time(rgb, depth.data(), ids.data(), options.repeat);
            for (size_t i = 0; i < names.size(); ++i) report.fullHdSceneMs[names[i]].push_back(ms[i]);
        }
        for (const std::string& name : names)
            report.fullHdMs.emplace_back(name, median(report.fullHdSceneMs[name]));
        std::string scenes;
        for (const std::string& name : report.fullHdScenes) scenes += (scenes.empty() ? "" : ", ") + name;
        report.notes.push_back("ms at 1920x1080: the median over the test scenes (" + scenes +
                               ") rendered at that size; results.json has each scene's figure");
    }
    for (const std::string& n : report.notes) std::fprintf(stderr, "bench quality: %s\n", n.c_str());
    return writeQualityReport(report, cases);
}

}  // namespace dejag::bench

#include "bench/filter_bench.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>

#include "base/peak.h"
#include "base/random.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "bench/bench.h"
#include "data/frame_image.h"
#include "infer/cnn.h"
#include "infer/filter.h"
#include "nn/model.h"
#include "render/renderer.h"

namespace dejag::bench {

namespace {

// Bytes each method must move per pixel at the least (every input read once, every output written
// once, float32): FXAA reads RGB and writes and reads back its luma plane; U-TAA reads colour, depth,
// motion and the RGB history and writes the history and the output; T-TAA also reads albedo, IDs, the
// previous depth and its Sobel history and writes that.
constexpr double kFxaaBytesPerPixel = 12 + 4 + 4;
// SMAA (out of place) reads RGB and writes RGB, writes and reads back its luma plane and its edge bytes
// (the blending weights, 16 bytes for each pixel with an edge, are not counted).
constexpr double kSmaaBytesPerPixel = 12 + 12 + 4 + 4 + 1 + 1;
constexpr double kUTaaBytesPerPixel = 12 + 4 + 8 + 12 + 12 + 12;
constexpr double kTTaaBytesPerPixel = kUTaaBytesPerPixel + 12 + 4 + 4 + 4 + 4;
// taa-hq (docs/taa-hq.md) reads colour, motion, depth, the previous depth and its history (RGB and the
// signed accumulated weight, 16 bytes) and writes the history and the output.
constexpr double kTaaHqBytesPerPixel = 12 + 8 + 4 + 4 + 16 + 16 + 12;

// Memory bandwidth in GB/s with `threads` threads (median of 5): a[i] = b[i] + s * c[i] over 3 x 64 MB,
// counted as 3 x 64 MB moved (as STREAM counts its triad).
double measureBandwidth(int threads) {
    static std::vector<float> a(size_t(16) << 20, 1.0f), b(a.size(), 2.0f), c(a.size(), 3.0f);
    setThreadCount(threads);
    const double ms = medianMilliseconds(5, [&] {
        parallelFor(0, int64_t(a.size()), 1 << 16, [&](int64_t first, int64_t last) {
            for (int64_t i = first; i < last; ++i) a[size_t(i)] = b[size_t(i)] + 0.5f * c[size_t(i)];
        });
    });
    return 3.0 * double(a.size()) * sizeof(float) / (ms * 1e6);
}

}  // namespace

std::vector<nlohmann::json> benchFilters(const FilterBenchOptions& options) {
    std::map<int, double> bandwidth;  // GB/s per thread count, measured in this run
    for (const int threads : options.threads) bandwidth[threads] = measureBandwidth(threads);
    const double pixels = double(options.width) * double(options.height);
    auto floorMs = [&](double bytesPerPixel, int threads) {
        return pixels * bytesPerPixel / (bandwidth[threads] * 1e6);
    };
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
        const auto fxaa = infer::makeFilter("fxaa", {{"preset", std::to_string(preset)}});
        infer::Frame inPlace;
        inPlace.width = options.width, inPlace.height = options.height, inPlace.colour = out.data();
        for (const int threads : options.threads) {
            setThreadCount(threads);
            // In place, as a frame pipeline runs it; the frame is restored (untimed) before each run.
            std::vector<double> times;
            for (int i = 0; i <= options.repeat; ++i) {
                std::copy(frame.begin(), frame.end(), out.begin());
                const Stopwatch clock;
                fxaa->apply(inPlace, out.data());
                if (i > 0) times.push_back(clock.elapsedMs());  // the first run is the warm-up
            }
            const double ms = median(times);
            rows.push_back({{"name", "fxaa preset " + std::to_string(preset)},
                            {"threads", threads},
                            {"width", options.width},
                            {"height", options.height},
                            {"ms", ms},
                            {"target_ms", 2.0},
                            {"processed_fraction", fxaa->figures().processedFraction},
                            {"floor_ms", floorMs(kFxaaBytesPerPixel, threads)},
                            {"psnr_before", floatPsnr(frame, truth)},
                            {"psnr_after", floatPsnr(out, truth)}});
        }
    }
    for (const char* preset : {"low", "medium", "high", "ultra"}) {
        const auto smaa = infer::makeFilter("smaa", {{"preset", preset}});
        infer::Frame in;
        in.width = options.width, in.height = options.height, in.colour = frame.data();
        for (const int threads : options.threads) {
            setThreadCount(threads);
            const double ms = medianMilliseconds(options.repeat, [&] { smaa->apply(in, out.data()); });
            rows.push_back({{"name", std::string("smaa ") + preset},
                            {"threads", threads},
                            {"width", options.width},
                            {"height", options.height},
                            {"ms", ms},
                            {"target_ms", 0.0},
                            {"processed_fraction", smaa->figures().processedFraction},
                            {"floor_ms", floorMs(kSmaaBytesPerPixel, threads)},
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
    infer::Frame frameBuffers;
    frameBuffers.width = options.width, frameBuffers.height = options.height;
    frameBuffers.colour = colour.data(), frameBuffers.albedo = albedo.data(),
    frameBuffers.depth = depth.data();
    frameBuffers.motion = motion.data(), frameBuffers.ids = ids.data(),
    frameBuffers.previousDepth = previousDepth.data();
    // Motion: the render's (a still camera: zero), a smooth zoom (what a moving camera gives: the history
    // read takes the kernel's windowed path) and random per-pixel motion (its gather path, a worst case).
    std::vector<float> zoom(motion.size()), random(motion.size());
    uint64_t state = 1;
    for (int y = 0; y < options.height; ++y)
        for (int x = 0; x < options.width; ++x) {
            const size_t i = 2 * (size_t(y) * size_t(options.width) + size_t(x));
            zoom[i] = 0.004f * float(x - options.width / 2),
            zoom[i + 1] = 0.004f * float(y - options.height / 2);
            for (int k = 0; k < 2; ++k)
                random[i + size_t(k)] = float(unitInterval(state = splitMix64(state), -2, 2));
        }
    const std::pair<const char*, const float*> motions[] = {
        {"", motion.data()}, {" zoom", zoom.data()}, {" random motion", random.data()}};
    struct TaaCase {
        const char *method, *name;
        double target, bytesPerPixel;
    };
    const TaaCase taas[] = {{"taa", "u-taa", 3.0, kUTaaBytesPerPixel},
                            {"taa-sobel", "t-taa", 5.0, kTTaaBytesPerPixel},
                            {"taa-hq", "taa-hq", 5.0, kTaaHqBytesPerPixel}};
    frameBuffers.hasJitter = true, frameBuffers.jitter[0] = 0.3f, frameBuffers.jitter[1] = -0.2f;
    for (const TaaCase& c : taas) {
        for (const auto& [label, field] : motions) {
            const auto taa = infer::makeFilter(c.method, {});
            frameBuffers.motion = field;
            for (const int threads : options.threads) {
                setThreadCount(threads);
                const double ms =
                    medianMilliseconds(options.repeat, [&] { taa->apply(frameBuffers, out.data()); });
                rows.push_back({{"name", std::string(c.name) + label},
                                {"threads", threads},
                                {"width", options.width},
                                {"height", options.height},
                                {"ms", ms},
                                {"target_ms", c.target},
                                {"processed_fraction", 1.0},
                                {"floor_ms", floorMs(c.bytesPerPixel, threads)}});
            }
        }
    }
    // The temporal network on the frame with every buffer under the zoom's motion, its history carried
    // over the timed runs; its floor is its multiply-adds at the FMA peak measured here.
    if (!options.temporalModel.empty()) {
        const nn::Model model = nn::loadModel(options.temporalModel);
        const double macsPerPixel =
            double(model.macs({1, model.inputChannels(), options.height, options.width})) / pixels;
        frameBuffers.motion = zoom.data();
        std::vector<std::pair<std::string, double>> precisions = {{"fp32", 33.0}};
        if (bf16Available()) precisions.push_back({"bf16", 16.7});
        for (const auto& [precision, target] : precisions)
            for (const int threads : options.threads) {
                setThreadCount(threads);
                const FmaPeak peak = measureFmaPeak();
                const auto network = infer::makeFilter(
                    "cnn-temporal", {{"model", options.temporalModel}, {"precision", precision}});
                const double ms =
                    medianMilliseconds(options.repeat, [&] { network->apply(frameBuffers, out.data()); });
                rows.push_back({{"name", "dejag-temporal " + precision + " zoom"},
                                {"threads", threads},
                                {"width", options.width},
                                {"height", options.height},
                                {"ms", ms},
                                {"target_ms", target},
                                {"processed_fraction", 1.0},
                                {"macs_per_pixel", macsPerPixel},
                                {"peak_gmacs", peak.gmacsTotal},
                                {"floor_ms", pixels * macsPerPixel / (peak.gmacsTotal * 1e6)}});
            }
    }
    // The single-frame networks on the colour frame; floor: multiply-adds at the FMA peak measured here.
    for (const std::string& path : options.frameModels) {
        const nn::Model model = nn::loadModel(path);
        const std::string name = std::filesystem::path(path).stem().string();
        const double macsPerPixel =
            double(model.macs({1, model.inputChannels(), options.height, options.width})) / pixels;
        const std::string guideMethod = model.architecture().value("guide_method", "");
        std::vector<float> guide;
        if (!guideMethod.empty()) {
            guide.resize(colour.size());
            infer::Frame plain;
            plain.width = options.width, plain.height = options.height, plain.colour = colour.data();
            infer::makeFilter(guideMethod, {})->apply(plain, guide.data());
        }
        std::vector<std::pair<std::string, double>> precisions = {{"fp32", 33.0}};
        if (bf16Available()) precisions.push_back({"bf16", 16.7});
        infer::Frame plain;
        plain.width = options.width, plain.height = options.height, plain.colour = colour.data();
        for (const auto& [precision, target] : precisions)
            for (const bool gate : {true, false})
                for (const bool alone : {false, true}) {
                    if (alone && guide.empty()) continue;
                    for (const int threads : options.threads) {
                        setThreadCount(threads);
                        const FmaPeak peak = measureFmaPeak();
                        double ms = 0;
                        if (alone) {  // the network with its guide given: what the guide method adds, apart
                            infer::CnnOptions cnnOptions;
                            cnnOptions.gate = gate, cnnOptions.precision = infer::cnnPrecision(precision);
                            infer::CnnFilter network(nn::loadModel(path), cnnOptions);
                            ms = medianMilliseconds(options.repeat, [&] {
                                network.apply(colour.data(), out.data(), options.width, options.height, 3,
                                              {nullptr, nullptr, guide.data()});
                            });
                        } else {
                            const auto network = infer::makeFilter(
                                "cnn",
                                {{"model", path}, {"precision", precision}, {"gate", gate ? "auto" : "off"}});
                            ms = medianMilliseconds(options.repeat,
                                                    [&] { network->apply(plain, out.data()); });
                        }
                        rows.push_back({{"name", name + " " + precision + (gate ? "" : " ungated") +
                                                     (alone ? " (" + guideMethod + " given)" : "")},
                                        {"threads", threads},
                                        {"width", options.width},
                                        {"height", options.height},
                                        {"ms", ms},
                                        {"target_ms", gate ? target : 60.0},
                                        {"processed_fraction", 1.0},
                                        {"macs_per_pixel", macsPerPixel},
                                        {"peak_gmacs", peak.gmacsTotal},
                                        {"floor_ms", pixels * macsPerPixel / (peak.gmacsTotal * 1e6)},
                                        {"psnr_before", floatPsnr(colour, truth)},
                                        {"psnr_after", floatPsnr(out, truth)}});
                    }
                }
    }
    setThreadCount(0);
    return rows;
}

}  // namespace dejag::bench

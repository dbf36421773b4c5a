#include "bench/taa_bench.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <memory>

#include "base/error.h"
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

// The temporal methods: U-TAA and T-TAA as specified and without their final sharpen (which costs several
// dB on frames dense in edges), taa-hq, and when its model is given the temporal network.
struct Taas {
    Taas(const TaaBenchOptions& options) {
        auto thesis = [&](const char* name, const char* method, bool sharpen) {
            add(name, infer::makeFilter(method, {{"sharpen", sharpen ? "true" : "false"},
                                                 {"unjitter", options.unjitter ? "true" : "false"}}));
        };
        thesis("u-taa", "taa", true), thesis("t-taa", "taa-sobel", true);
        thesis("u-taa unsharpened", "taa", false), thesis("t-taa unsharpened", "taa-sobel", false);
        add("taa-hq", infer::makeFilter("taa-hq", options.taaHq));
        if (!options.temporalModel.empty()) {
            infer::FilterParameters parameters = options.temporal;
            parameters.setAssignment("model=" + options.temporalModel);
            add("dejag-temporal", infer::makeFilter("cnn-temporal", parameters));
        }
        outputs.resize(filters.size());
    }
    void add(const char* name, std::unique_ptr<infer::Filter> filter) {
        names.push_back(name), filters.push_back(std::move(filter));
    }
    std::vector<std::string> names;
    std::vector<std::unique_ptr<infer::Filter>> filters;
    std::vector<std::vector<float>> outputs;
};

// The single-frame methods, each on the frame no AA shows: FXAA, and when its model is given the
// single-frame network.
struct Singles {
    explicit Singles(const TaaBenchOptions& options) {
        names.push_back("fxaa"), filters.push_back(infer::makeFilter("fxaa", {}));
        names.push_back("smaa"), filters.push_back(infer::makeFilter("smaa", {}));
        if (!options.fastModel.empty())
            names.push_back("dejag-fast"),
                filters.push_back(infer::makeFilter("cnn", {{"model", options.fastModel}}));
        outputs.resize(filters.size());
    }
    void run(const std::vector<float>& colour, int width, int height) {
        infer::Frame frame;
        frame.width = width, frame.height = height, frame.colour = colour.data();
        for (size_t k = 0; k < filters.size(); ++k) {
            outputs[k].resize(colour.size());
            filters[k]->apply(frame, outputs[k].data());
        }
    }
    std::vector<std::string> names;
    std::vector<std::unique_ptr<infer::Filter>> filters;
    std::vector<std::vector<float>> outputs;
};

// The frame's jitter as the filters take it: the image's shift in pixels, +y down.
std::array<float, 2> imageShift(const render::Vec2& jitter) {
    return {float(jitter.x), float(-jitter.y)};
}

// Runs every TAA on one rendered frame with every buffer.
void runTaas(Taas& taas, const render::Frame& f, float far, const render::Vec2& jitter) {
    const FrameBuffers buffers(f, far, jitter);
    for (size_t k = 0; k < taas.filters.size(); ++k) {
        taas.outputs[k].resize(buffers.colour.size());
        taas.filters[k]->apply(buffers.frame, taas.outputs[k].data());
    }
}

// The oracle of a static view: per pixel, the mean in linear light of the samples that fell inside it
// over the frames (every sample of a frame is shifted by its jitter, so one per frame: for spreads up to
// a pixel, the mean of the jittered frames).
struct Oracle {
    int width = 0, height = 0, frames = 0;
    std::vector<double> sum;
    void add(const render::Frame& f, const render::Vec2& jitter) {
        const std::vector<float> linear = frameChannels(f, 0, 3, false);
        width = f.width, height = f.height;
        sum.resize(linear.size(), 0.0);
        const std::array<float, 2> j = imageShift(jitter);
        const int sx = -int(std::floor(-j[0] + 0.5f)), sy = -int(std::floor(-j[1] + 0.5f));
        for (int y = 0; y < height; ++y)
            for (int x = 0; x < width; ++x) {
                const int qx = std::clamp(x + sx, 0, width - 1), qy = std::clamp(y + sy, 0, height - 1);
                for (int c = 0; c < 3; ++c)
                    sum[(size_t(y) * size_t(width) + size_t(x)) * 3 + size_t(c)] +=
                        linear[(size_t(qy) * size_t(width) + size_t(qx)) * 3 + size_t(c)];
            }
        ++frames;
    }
    std::vector<float> srgb() const {
        std::vector<float> out(sum.size());
        for (size_t i = 0; i < sum.size(); ++i)
            out[i] = std::clamp(linearToSrgb(float(sum[i] / std::max(frames, 1))), 0.0f, 1.0f);
        return out;
    }
};

// The thesis' reference (its accumulation buffer): `samples` 8-bit renders of the pose, sample i shifted
// by Halton point i with spread 1 (a box), averaged as the displayed values they are — the sRGB-encoded
// colour, with no step through linear light.
Image displayTruth(render::Renderer& renderer, int samples, double time) {
    std::vector<double> sum;
    int W = 0, H = 0;
    for (int i = 0; i < samples; ++i) {
        render::FrameRequest r;
        r.time = r.previousTime = time;
        r.jitter = render::jitterPixels(unsigned(i), 1.0);
        r.buffers = render::BufferSet::parse("color");
        const render::Frame f = renderer.render(r);
        W = f.width, H = f.height;
        const std::vector<float> c = frameChannels(f, 0, 3, true);
        sum.resize(c.size(), 0.0);
        for (size_t k = 0; k < c.size(); ++k)
            sum[k] += std::round(std::clamp(c[k], 0.0f, 1.0f) * 255.0f) / 255.0;
    }
    std::vector<float> mean(sum.size());
    for (size_t k = 0; k < sum.size(); ++k) mean[k] = float(sum[k] / samples);
    return eightBit(mean, W, H);
}

// Every method over `frames` jittered frames of a scene (time 0, 1, ...), each frame against the truth of
// its own pose (32 samples by default, options.ghostTruthSamples); the first `skip` frames are run but not
// scored. One row per method: mean, best and worst PSNR and SSIM, and the flicker.
void runSequence(const render::GlContext& context, const render::Scene& scene, int frames, int skip,
                 const TaaBenchOptions& options, const nlohmann::json& labels,
                 std::vector<nlohmann::json>& rows) {
    const int W = options.ghostWidth, H = options.ghostHeight;
    render::Renderer renderer(context, scene, W, H);
    Taas taas(options);
    Singles singles(options);
    // Every TAA, then no AA and the single-frame methods.
    std::vector<std::string> names = taas.names;
    names.push_back("no aa");
    names.insert(names.end(), singles.names.begin(), singles.names.end());
    const size_t methods = names.size(), taaCount = taas.filters.size();
    std::vector<std::vector<double>> psnr(methods), ssim(methods);
    std::vector<FlickerMeter> flicker(methods);
    render::TruthOptions truthOptions;
    truthOptions.samples = options.ghostTruthSamples, truthOptions.adaptive = true;
    for (int t = 0; t < frames; ++t) {
        const render::FrameRequest request = jitteredFrame(t, t, options.jitterSpread);
        const render::Frame rendered = renderer.render(request);
        runTaas(taas, rendered, float(scene.far), request.jitter);
        if (t < skip) continue;
        const std::vector<float> noAa = frameChannels(rendered, 0, 3, true);
        singles.run(noAa, W, H);
        const Image truth =
            options.displayTruth
                ? displayTruth(renderer, options.ghostTruthSamples, t)
                : eightBit(frameChannels(renderer.renderTruth(t, truthOptions), 0, 3, true), W, H);
        for (size_t k = 0; k < methods; ++k) {
            const Image out = eightBit(k < taaCount    ? taas.outputs[k]
                                       : k == taaCount ? noAa
                                                       : singles.outputs[k - taaCount - 1],
                                       W, H);
            const ImageMetrics m = compareImages(truth, out);
            psnr[k].push_back(m.psnr), ssim[k].push_back(m.ssim);
            flicker[k].add(out.pixels, truth.pixels);
        }
    }
    auto summary = [](const std::vector<double>& v) {
        double sum = 0;
        for (double x : v) sum += x;
        return nlohmann::json{{"best", *std::max_element(v.begin(), v.end())},
                              {"worst", *std::min_element(v.begin(), v.end())},
                              {"mean", sum / double(v.size())}};
    };
    for (size_t k = 0; k < methods; ++k) {
        nlohmann::json row = labels;
        row.update({{"method", names[k]},
                    {"flicker", flicker[k].value()},
                    {"frames", frames},
                    {"scored_from", skip},
                    {"width", W},
                    {"height", H},
                    {"psnr", summary(psnr[k])},
                    {"ssim", summary(ssim[k])}});
        rows.push_back(row);
    }
}

// The moving protocol's camera motions: pans and an orbit, speeds in pixels per frame.
struct Motion {
    const char* label;
    double speed;
    bool orbit;
};
constexpr Motion kMotions[] = {
    {"pan 0.25 px", 0.25, false}, {"pan 2 px", 2.0, false}, {"orbit 1 px", 1.0, true}};

}  // namespace

FrameBuffers::FrameBuffers(const render::Frame& f, float far, const render::Vec2& jitter)
    : colour(frameChannels(f, 0, 3, true)),
      albedo(frameChannels(f, 3, 3, true)),
      depth(frameChannels(f, 6, 1, false, 1.0f / far)),
      motion(frameChannels(f, 7, 2, false)),
      ids(frameChannels(f, 9, 1, false)),
      previousDepth(frameChannels(f, 10, 1, false, 1.0f / far)) {
    frame.width = f.width, frame.height = f.height;
    frame.colour = colour.data(), frame.albedo = albedo.data(), frame.depth = depth.data();
    frame.motion = motion.data(), frame.ids = ids.data(), frame.previousDepth = previousDepth.data();
    frame.hasJitter = true;
    const std::array<float, 2> shift = imageShift(jitter);
    frame.jitter[0] = shift[0], frame.jitter[1] = shift[1];
}

void moveCamera(render::Scene& scene, double speed, bool orbit, int height) {
    const render::CameraPose start = scene.cameraAt(0);
    const double distance = render::length(start.target - start.eye);
    const double pixel = 2 * distance * std::tan(start.fovY / 2) / height;
    const render::Vec3 forward = render::normalize(start.target - start.eye);
    const render::Vec3 right = render::normalize(render::cross(forward, start.up));
    scene.camera = [start, speed, orbit, pixel, distance, forward, right](double t) {
        render::CameraPose pose = start;
        const double travel = speed * pixel * t;
        if (!orbit) {
            pose.eye = start.eye + right * travel, pose.target = start.target + right * travel;
        } else {  // around the target, in the plane of the view's right and forward vectors
            const double angle = travel / distance;
            pose.eye = start.target + (-forward * std::cos(angle) + right * std::sin(angle)) * distance;
        }
        return pose;
    };
}

render::FrameRequest jitteredFrame(double time, int index, double spread) {
    render::FrameRequest r;
    r.time = time, r.previousTime = std::max(0.0, time - 1);
    r.jitter = render::jitterPixels(unsigned(index % 16), spread);
    r.previousJitter = render::jitterPixels(unsigned((index + 15) % 16), spread);
    r.buffers = render::BufferSet::all();
    return r;
}

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
    auto wanted = [&](const std::string& label, const std::string& scene) {
        return options.scenes.empty() ||
               std::any_of(options.scenes.begin(), options.scenes.end(),
                           [&](const std::string& name) { return name == label || name == scene; });
    };
    const char* ghostScenes[] = {"corridor", "hairball-rotating", "hairball-lit-rotating"};
    const std::vector<std::string>& movingScenes = options.movingScenes;
    int64_t steps = 0;
    for (const StaticScene& s : scenes) steps += wanted(s.label, s.scene);
    for (const char* name : ghostScenes) steps += options.ghosting && wanted(name, name);
    for (const std::string& name : movingScenes)
        steps += options.moving && wanted(name, name) ? int64_t(std::size(kMotions)) : 0;
    if (steps == 0) throw Error("bench taa: no scene of the protocols is named in --scenes");
    Progress progress("bench taa", steps, options.quiet);
    const int W = options.width, H = options.height;
    for (const StaticScene& s : scenes) {
        if (!wanted(s.label, s.scene)) continue;
        render::SceneOptions sceneOptions;
        sceneOptions.tiltedCamera = s.tilted;
        const render::Scene scene = render::buildScene(s.scene, sceneOptions);
        render::Renderer renderer(*context, scene, W, H);
        render::TruthOptions truthOptions;
        truthOptions.samples = options.truthSamples, truthOptions.adaptive = true;
        const Image truth =
            options.displayTruth
                ? displayTruth(renderer, options.truthSamples, 0)
                : eightBit(frameChannels(renderer.renderTruth(0, truthOptions), 0, 3, true), W, H);
        render::FrameRequest still;
        still.buffers = render::BufferSet::parse("color");
        const std::vector<float> noAa = frameChannels(renderer.render(still), 0, 3, true);
        Singles singles(options);
        singles.run(noAa, W, H);
        Taas taas(options);
        Oracle oracle;
        for (int i = 0; i < options.historyFrames; ++i) {
            const render::FrameRequest request = jitteredFrame(0, i, options.jitterSpread);
            const render::Frame frame = renderer.render(request);
            runTaas(taas, frame, float(scene.far), request.jitter);
            if (i >= options.historyFrames - 16) oracle.add(frame, request.jitter);
        }
        const std::vector<float> oracleOut = oracle.srgb();
        std::vector<std::pair<std::string, const std::vector<float>*>> methods = {{"no aa", &noAa}};
        for (size_t k = 0; k < singles.filters.size(); ++k)
            methods.push_back({singles.names[k], &singles.outputs[k]});
        for (size_t k = 0; k < taas.filters.size(); ++k) methods.push_back({taas.names[k], &taas.outputs[k]});
        methods.push_back({"oracle", &oracleOut});
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
        for (const char* name : ghostScenes) {
            if (!wanted(name, name)) continue;
            const render::Scene scene = render::buildScene(name);
            runSequence(*context, scene, options.ghostFrames, 0, options,
                        {{"test", "ghosting"}, {"scene", name}}, rows);
            progress.advance(1, name);
        }
    }
    if (options.moving) {
        // A still scene seen by a moving camera: pans across the view and an orbit around its target, at
        // the speeds given in pixels per frame (at the target's distance).
        for (const std::string& name : movingScenes)
            for (const Motion& motion : kMotions) {
                if (!wanted(name, name)) continue;
                render::Scene scene = render::buildScene(name);
                moveCamera(scene, motion.speed, motion.orbit, options.ghostHeight);
                runSequence(*context, scene, options.movingFrames, options.movingSkip, options,
                            {{"test", "moving"}, {"scene", name}, {"motion", motion.label}}, rows);
                progress.advance(1, std::string(name) + " " + motion.label);
            }
    }
    for (nlohmann::json& row : rows) row["jitter_spread"] = options.jitterSpread;  // (what a card quotes)
    return rows;
}

}  // namespace dejag::bench

// dejag filter: anti-aliasing post-processes on images (FXAA now; TAA and the CNN come next).
#include <cstdio>
#include <nlohmann/json.hpp>
#include <optional>

#include <filesystem>
#include <fstream>
#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/progress.h"
#include "base/timer.h"
#include "data/image.h"
#include "infer/cnn.h"
#include "infer/fxaa.h"
#include "infer/taa.h"
#include "nn/model.h"

namespace dejag::cli {
namespace {

struct FilterArguments {
    std::string method, input, output;
    std::string model = "models/dejag-fast.safetensors", gate = "auto";
    int tile = 256;
    int preset = 39;
    bool greenLuma = false, json = false, noSharpen = false;
    RuntimeOptions runtime;
};

// The channels of one buffer of a rendered frame, in order (throws naming the file if absent).
std::vector<float> channelsOf(const Image& image, const std::vector<std::string>& names,
                              const std::string& path, bool encode = false) {
    std::vector<int> index;
    for (const std::string& n : names) {
        const int c = image.findChannel(n);
        if (c < 0)
            throw Error("'" + path + "' has no channel " + n +
                        " (render it with --buffers color,albedo,depth,motion,id,prevdepth)");
        index.push_back(c);
    }
    std::vector<float> out(image.pixelCount() * names.size());
    for (size_t p = 0; p < image.pixelCount(); ++p)
        for (size_t k = 0; k < names.size(); ++k) {
            float v = image.pixels[p * size_t(image.channels()) + size_t(index[k])];
            if (encode) v = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
            out[p * names.size() + k] = v;
        }
    return out;
}

// TAA over a sequence written by dejag render: INPUT is its folder, OUTPUT a folder of sRGB PNGs.
void runTaa(const FilterArguments& args) {
    namespace fs = std::filesystem;
    if (!fs::is_directory(args.input))
        throw Error("TAA filters a sequence: '" + args.input + "' must be a folder written by dejag render");
    std::vector<std::string> frames;
    for (const auto& entry : fs::directory_iterator(args.input)) {
        const std::string name = entry.path().filename().string();
        if (name.rfind("frame_", 0) == 0 && entry.path().extension() == ".exr")
            frames.push_back(entry.path().string());
    }
    std::sort(frames.begin(), frames.end());
    if (frames.empty()) throw Error("'" + args.input + "' holds no frame_NNNN.exr");
    double far = 200.0;
    if (std::ifstream sidecar(fs::path(args.input) / "render.json"); sidecar) {
        const nlohmann::json j = nlohmann::json::parse(sidecar, nullptr, false);
        if (j.is_object() && j.contains("depth_far")) far = j["depth_far"].get<double>();
    }
    std::error_code ec;
    fs::create_directories(args.output, ec);
    if (ec || !fs::is_directory(args.output))
        throw Error("cannot write to the output folder '" + args.output + "'");
    infer::TaaOptions options;
    options.improved = args.method == "taa-sobel";
    options.sharpen = !args.noSharpen;
    infer::Taa taa(options);
    Progress progress("filter " + args.method, int64_t(frames.size()), args.json);
    std::vector<float> out;
    nlohmann::json timings = nlohmann::json::array();
    for (const std::string& path : frames) {
        const Image frame = readImage(path);
        const std::vector<float> colour = channelsOf(frame, {"R", "G", "B"}, path, true);
        std::vector<float> depth = channelsOf(frame, {"depth.Z"}, path);
        const std::vector<float> motion = channelsOf(frame, {"motion.X", "motion.Y"}, path);
        for (float& d : depth) d = float(d / far);
        std::vector<float> albedo, ids, previousDepth;
        infer::TaaFrame f;
        f.width = frame.width, f.height = frame.height;
        f.colour = colour.data(), f.depth = depth.data(), f.motion = motion.data();
        if (options.improved) {
            albedo = channelsOf(frame, {"albedo.R", "albedo.G", "albedo.B"}, path, true);
            ids = channelsOf(frame, {"id.ID"}, path);
            previousDepth = channelsOf(frame, {"prevdepth.Z"}, path);
            for (float& d : previousDepth) d = float(d / far);
            f.albedo = albedo.data(), f.ids = ids.data(), f.previousDepth = previousDepth.data();
        }
        out.resize(colour.size());
        const Stopwatch clock;
        taa.apply(f, out.data());
        const double ms = clock.elapsedMs();
        Image result(frame.width, frame.height, {"R", "G", "B"}, PixelType::UInt8);
        result.pixels = out;
        const std::string name = fs::path(path).stem().string() + ".png";
        writeImage((fs::path(args.output) / name).string(), result);
        timings.push_back({{"frame", name}, {"ms", ms}});
        progress.advance(1);
    }
    if (args.json)
        std::printf("%s\n", nlohmann::json{{"method", args.method}, {"frames", timings}}.dump().c_str());
}

void runFilter(const FilterArguments& args) {
    applyRuntimeOptions(args.runtime);
    if (args.method == "taa" || args.method == "taa-sobel") return runTaa(args);
    if (args.method != "fxaa" && args.method != "cnn")
        throw Error("--method '" + args.method + "' is not one of fxaa, cnn, taa, taa-sobel");
    // Both filters are built (and the model loaded and checked) before the input is read.
    std::optional<infer::Fxaa> fxaa;
    std::optional<infer::CnnFilter> cnn;
    if (args.method == "fxaa") {
        infer::FxaaOptions options;
        options.preset = args.preset;
        options.greenAsLuma = args.greenLuma;
        fxaa.emplace(options);
    } else {
        infer::CnnOptions options;
        options.tileSize = args.tile;
        if (args.gate == "off") {
            options.gate = false;
        } else if (args.gate != "auto") {
            try {
                size_t used = 0;
                options.gateThreshold = std::stof(args.gate, &used);
                if (used != args.gate.size()) throw std::invalid_argument(args.gate);
            } catch (const std::exception&) {
                throw Error("--gate '" + args.gate + "' is not off, auto or a luma threshold in [0, 1]");
            }
            if (!(options.gateThreshold >= 0 && options.gateThreshold <= 1))
                throw Error("--gate '" + args.gate + "' is not off, auto or a luma threshold in [0, 1]");
        }
        cnn.emplace(nn::loadModel(args.model), options);
    }
    Image image = readImage(args.input);
    if (image.findChannel("R") != 0 || image.findChannel("G") != 1 || image.findChannel("B") != 2)
        throw Error("'" + args.input + "' has no R, G, B channels first (" + image.describe() + ")");
    if (auto bad = findNonFinite(image))
        throw Error("'" + args.input + "' has a non-finite value at pixel (" + std::to_string(bad->x) + ", " +
                    std::to_string(bad->y) + ")");
    // FXAA works on display-referred colour: half and float files hold linear light, so they are encoded
    // to sRGB for the filter and decoded back; 8- and 16-bit files are sRGB-encoded already.
    const bool linear = image.storage == PixelType::Half || image.storage == PixelType::Float;
    if (linear) {
        for (size_t p = 0; p < image.pixelCount(); ++p)
            for (int c = 0; c < 3; ++c) {
                float& v = image.pixels[p * size_t(image.channels()) + size_t(c)];
                v = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
            }
    }
    Image out = image;
    const Stopwatch clock;
    if (fxaa)
        fxaa->apply(image.pixels.data(), out.pixels.data(), image.width, image.height, image.channels());
    else
        cnn->apply(image.pixels.data(), out.pixels.data(), image.width, image.height, image.channels());
    const double ms = clock.elapsedMs();
    if (linear)
        for (size_t p = 0; p < out.pixelCount(); ++p)
            for (int c = 0; c < 3; ++c) {
                float& v = out.pixels[p * size_t(out.channels()) + size_t(c)];
                v = srgbToLinear(v);
            }
    writeImage(args.output, out);
    if (args.json) {
        nlohmann::json j = {{"method", args.method}, {"input", args.input},    {"output", args.output},
                            {"width", image.width},  {"height", image.height}, {"ms", ms}};
        if (fxaa) {
            j["preset"] = args.preset;
            j["processed_fraction"] = fxaa->processedFraction();
        } else {
            j["model"] = args.model;
            j["gate"] = args.gate;
            j["tiles"] = cnn->tileCount();
            j["tiles_processed"] = cnn->tilesProcessed();
            j["processed_fraction"] = cnn->processedFraction();
        }
        std::printf("%s\n", j.dump().c_str());
    }
}

}  // namespace

void registerFilterCommand(CLI::App& app) {
    auto args = std::make_shared<FilterArguments>();
    CLI::App* command = app.add_subcommand(
        "filter", "anti-alias an image (FXAA 3.11, the CNN) or a rendered sequence (TAA: U-TAA, T-TAA)");
    command->add_option("--method", args->method, "fxaa | cnn | taa | taa-sobel")->required();
    command->add_option("--model", args->model, "CNN: model file")->capture_default_str();
    command->add_option("--gate", args->gate, "CNN: off | auto | T (run tiles whose luma steps exceed T)")
        ->capture_default_str();
    command->add_option("--tile", args->tile, "CNN: tile side in pixels")->capture_default_str();
    command->add_option("--preset", args->preset, "FXAA quality preset: 12, 23 or 39")->capture_default_str();
    command->add_flag("--green-luma", args->greenLuma, "FXAA: use green as luma");
    command->add_flag("--no-sharpen", args->noSharpen, "TAA: skip the final sharpen (see docs/infer.md)");
    command->add_option("input", args->input, "input image (PNG, JPEG, TIFF, EXR)")->required();
    command->add_option("output", args->output, "output image (bit depth and extra channels kept)")
        ->required();
    command->add_flag("--json", args->json, "print timing as JSON");
    addRuntimeOptions(command, args->runtime);
    command->footer(
        "CNN: a trained model (models/*.safetensors, see models/*.md) run in tiles with a receptive-field "
        "halo,\n"
        "only on tiles with a luma step above the gate (auto = 0.04); skipped tiles pass through unchanged.\n"
        "FXAA and the CNN run on sRGB-encoded colour: 8/16-bit inputs as they are, half/float (linear) "
        "inputs encoded\n"
        "for the filter and decoded back. Constants: subpix 0.75, edge threshold 0.166, minimum 0.0833.\n"
        "TAA (taa = the baseline U-TAA, taa-sobel = T-TAA of spec/taa.md): INPUT is a folder written by\n"
        "dejag render --jitter halton16 --buffers color,albedo,depth,motion,id,prevdepth; OUTPUT a folder\n"
        "of sRGB PNGs, one per frame. History starts with the first frame.");
    command->callback([args] { runFilter(*args); });
}

}  // namespace dejag::cli

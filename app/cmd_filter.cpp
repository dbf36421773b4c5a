// dejag filter: anti-aliasing post-processes on images and sequences — FXAA 3.11, the CNN, U-TAA and
// T-TAA — alone or chained (--chain taa,cnn).
#include <algorithm>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/files.h"
#include "base/progress.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "data/image.h"
#include "infer/cnn.h"
#include "infer/fxaa.h"
#include "infer/taa.h"
#include "nn/model.h"

namespace dejag::cli {
namespace {

namespace fs = std::filesystem;

struct FilterArguments {
    std::string method, chain, input, output;
    std::string model = "models/dejag-fast.safetensors", gate = "auto", precision = "auto";
    int tile = 2048;
    int preset = 39;
    bool greenLuma = false, json = false, noSharpen = false, quiet = false;
    bool motionBlur = false;
    float motionBlurScale = 1.0f;
    std::string cuts;  // TAA: frame numbers that start a new shot
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
    parallelFor(0, int64_t(image.pixelCount()), 1 << 14, [&](int64_t first, int64_t last) {
        for (size_t p = size_t(first); p < size_t(last); ++p)
            for (size_t k = 0; k < names.size(); ++k) {
                float v = image.pixels[p * size_t(image.channels()) + size_t(index[k])];
                if (encode) v = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
                out[p * names.size() + k] = v;
            }
    });
    return out;
}

// R, G, B (the first three channels) of linear-light pixels encoded to sRGB in [0, 1] for the filters,
// or decoded back; on the thread pool (each value on its own: the same result for any thread count).
void encodeColour(Image& image) {
    const size_t C = size_t(image.channels());
    parallelFor(0, int64_t(image.pixelCount()), 1 << 14, [&](int64_t first, int64_t last) {
        for (size_t p = size_t(first); p < size_t(last); ++p)
            for (size_t c = 0; c < 3; ++c) {
                float& v = image.pixels[p * C + c];
                v = std::clamp(linearToSrgb(std::max(v, 0.0f)), 0.0f, 1.0f);
            }
    });
}
void decodeColour(Image& image) {
    const size_t C = size_t(image.channels());
    parallelFor(0, int64_t(image.pixelCount()), 1 << 14, [&](int64_t first, int64_t last) {
        for (size_t p = size_t(first); p < size_t(last); ++p)
            for (size_t c = 0; c < 3; ++c) image.pixels[p * C + c] = srgbToLinear(image.pixels[p * C + c]);
    });
}

// One image filter of a chain: works in place on an sRGB-encoded frame (R G B first, other channels
// left alone). TAA is not one: it needs the rendered buffers and runs first.
struct ImageStage {
    std::string name;
    std::optional<infer::Fxaa> fxaa;
    std::optional<infer::CnnFilter> cnn;
    std::vector<float> scratch;
    double lastFraction = 0;
    void apply(std::vector<float>& frame, int width, int height, int channels,
               const infer::CnnBuffers& buffers) {
        scratch.resize(frame.size());
        if (fxaa) {
            fxaa->apply(frame.data(), scratch.data(), width, height, channels);
            lastFraction = fxaa->processedFraction();
        } else {
            cnn->apply(frame.data(), scratch.data(), width, height, channels, buffers);
            lastFraction = cnn->processedFraction();
        }
        frame.swap(scratch);
    }
};

ImageStage makeStage(const std::string& method, const FilterArguments& args) {
    ImageStage stage;
    stage.name = method;
    if (method == "fxaa") {
        infer::FxaaOptions options;
        options.preset = args.preset;
        options.greenAsLuma = args.greenLuma;
        stage.fxaa.emplace(options);
    } else if (method == "cnn") {
        infer::CnnOptions options;
        options.tileSize = args.tile;
        options.precision = infer::cnnPrecision(args.precision);
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
        nn::Model model = nn::loadModel(args.model);
        try {
            stage.cnn.emplace(std::move(model), options);
        } catch (const Error& e) {
            throw Error("--model '" + args.model + "': " + e.what());
        }
    } else {
        throw Error("--method/--chain: '" + method + "' is not one of fxaa, cnn, taa, taa-sobel");
    }
    return stage;
}

bool isImageFile(const fs::path& path) {
    std::string ext = path.extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    return ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".tif" || ext == ".tiff" ||
           ext == ".exr";
}

// "frame_%04d.png" -> the path of frame i (isPattern has checked the pattern).
std::string formatPattern(const std::string& pattern, int index) {
    char text[4096];
    const int n = std::snprintf(text, sizeof text, pattern.c_str(), index);
    if (n < 0 || size_t(n) >= sizeof text)
        throw Error("'" + pattern + "': the file name it gives is too long");
    return text;
}
// True for a printf-style sequence pattern: one field %d, %Nd or %0Nd with N at most 2 digits.
bool isPattern(const std::string& path) {
    const size_t percent = path.find('%');
    if (percent == std::string::npos) return false;
    const std::string bad = "'" + path + "': a sequence pattern holds one integer field such as %04d";
    size_t i = percent + 1;
    if (i < path.size() && path[i] == '0') ++i;
    const size_t digits = i;
    while (i < path.size() && std::isdigit(static_cast<unsigned char>(path[i]))) ++i;
    if (i - digits > 2) throw Error(bad + " (a field at most 99 digits wide)");
    if (i >= path.size() || path[i] != 'd' || path.find('%', i) != std::string::npos) throw Error(bad);
    if (fs::path(path).parent_path().string().find('%') != std::string::npos)
        throw Error(bad + " in the file name, not in a folder");
    return true;
}

// The frame numbers of a pattern that exist, in order: the files of its folder whose names it gives.
std::vector<int> sequenceFrames(const std::string& pattern) {
    const fs::path folder =
        fs::path(pattern).parent_path().empty() ? fs::path(".") : fs::path(pattern).parent_path();
    const std::string name = fs::path(pattern).filename().string();
    const size_t percent = name.find('%'), field = name.find('d', percent);
    const std::string prefix = name.substr(0, percent), suffix = name.substr(field + 1);
    std::vector<int> frames;
    std::error_code ec;
    for (const auto& entry : fs::directory_iterator(folder, ec)) {
        const std::string file = entry.path().filename().string();
        if (file.size() <= prefix.size() + suffix.size() || file.compare(0, prefix.size(), prefix) != 0 ||
            file.compare(file.size() - suffix.size(), suffix.size(), suffix) != 0)
            continue;
        const std::string number = file.substr(prefix.size(), file.size() - prefix.size() - suffix.size());
        if (number.size() > 9 ||
            !std::all_of(number.begin(), number.end(), [](unsigned char c) { return std::isdigit(c); }))
            continue;
        const int index = std::stoi(number);
        if (formatPattern(name, index) == file) frames.push_back(index);
    }
    std::sort(frames.begin(), frames.end());
    return frames;
}

// The (input, output) pairs: one file, a folder of images, or a printf-style numbered sequence. Hidden
// files (dejag's temporary ".NAME.tmp-PID-N.EXT" among them) are not frames. A sequence with a gap in
// its numbering is refused: its later frames would otherwise be dropped without a word.
std::vector<std::pair<std::string, std::string>> framePairs(const std::string& input,
                                                            const std::string& output) {
    std::vector<std::pair<std::string, std::string>> pairs;
    if (isPattern(input)) {
        if (!isPattern(output))
            throw Error("input '" + input + "' is a sequence: OUTPUT must be a pattern too");
        const std::vector<int> frames = sequenceFrames(input);
        if (frames.empty()) throw Error("no frame matches '" + input + "'");
        for (size_t k = 1; k < frames.size(); ++k)
            if (frames[k] != frames[k - 1] + 1)
                throw Error("'" + input + "' has a gap: frame " + std::to_string(frames[k - 1] + 1) +
                            " is missing between " + formatPattern(input, frames[k - 1]) + " and " +
                            formatPattern(input, frames[k]) + " (filter each run of frames on its own)");
        for (int i : frames) pairs.emplace_back(formatPattern(input, i), formatPattern(output, i));
    } else if (fs::is_directory(input)) {
        std::vector<fs::path> files;
        for (const auto& entry : fs::directory_iterator(input))
            if (entry.is_regular_file() && isImageFile(entry.path()) &&
                entry.path().filename().string().front() != '.')
                files.push_back(entry.path());
        std::sort(files.begin(), files.end());
        if (files.empty()) throw Error("folder '" + input + "' holds no PNG, JPEG, TIFF or EXR image");
        if (fs::exists(output) && !fs::is_directory(output))
            throw Error("input '" + input + "' is a folder: OUTPUT '" + output + "' must be a folder too");
        for (const fs::path& f : files)
            pairs.emplace_back(f.string(), (fs::path(output) / f.filename()).string());
    } else {
        requireReadableFile(input);
        pairs.emplace_back(input, output);
    }
    return pairs;
}

// Refuses a frame the filters turned non-finite (a NaN can only come from a model whose weights the
// load-time check could not judge on every input): nothing is written for it.
void requireFiniteOutput(const Image& image, const std::string& in, const std::string& method) {
    const size_t C = size_t(image.channels()), count = image.pixels.size();
    std::atomic<size_t> first{count};
    parallelFor(0, int64_t(count), 1 << 16, [&](int64_t begin, int64_t end) {
        for (int64_t i = begin; i < end; ++i)
            if (!std::isfinite(image.pixels[size_t(i)])) {
                size_t seen = first.load();
                while (size_t(i) < seen && !first.compare_exchange_weak(seen, size_t(i))) {
                }
                return;
            }
    });
    const size_t i = first.load();
    if (i < count)
        throw Error(method + " turned '" + in + "' into a non-finite value at pixel (" +
                    std::to_string((i / C) % size_t(image.width)) + ", " +
                    std::to_string((i / C) / size_t(image.width)) + "); nothing written for it");
}

void makeParentFolder(const std::string& path) {
    const fs::path parent = fs::path(path).parent_path();
    if (parent.empty()) return;
    std::error_code ec;
    fs::create_directories(parent, ec);
    if (ec || !fs::is_directory(parent))
        throw Error("cannot write to the output folder '" + parent.string() + "'");
}

// Sequences decode their files one frame ahead and encode them one frame behind, on threads of their
// own, so the image codecs (zlib, partly parallel at best) overlap the filters. Errors still come in frame
// order: a frame that cannot be read stops the run once every frame before it is written, and files are
// written atomically, so a stop leaves no partial file. (A future of std::async waits for its task when
// destroyed, so an error thrown meanwhile still lets a started write finish.)
std::future<Image> readAhead(const std::string& path) {
    return std::async(std::launch::async, [path] { return readImage(path); });
}
std::future<void> writeBehind(const std::string& path, Image image) {
    return std::async(std::launch::async, [path, image = std::move(image)] { writeImage(path, image); });
}

// Image filters (FXAA, CNN, chains of them) over single images, folders and numbered sequences.
void runImageChain(const FilterArguments& args, std::vector<ImageStage>& stages) {
    const auto pairs = framePairs(args.input, args.output);
    Progress progress("filter", int64_t(pairs.size()), args.json || args.quiet || pairs.size() == 1);
    nlohmann::json frames = nlohmann::json::array();
    // (Frames read one ahead and written one behind: readAhead / writeBehind.)
    std::future<Image> nextImage = readAhead(pairs.front().first);
    std::future<void> lastWrite;
    for (size_t index = 0; index < pairs.size(); ++index) {
        const auto& [in, out] = pairs[index];
        Image image = nextImage.get();
        if (index + 1 < pairs.size()) nextImage = readAhead(pairs[index + 1].first);
        if (image.findChannel("R") != 0 || image.findChannel("G") != 1 || image.findChannel("B") != 2)
            throw Error("'" + in + "' has no R, G, B channels first (" + image.describe() + ")");
        if (auto bad = findNonFinite(image))
            throw Error("'" + in + "' has a non-finite value at pixel (" + std::to_string(bad->x) + ", " +
                        std::to_string(bad->y) + ")");
        // The filters work on display-referred colour: half and float files hold linear light, so they are
        // encoded to sRGB for the filters and decoded back; 8- and 16-bit files are sRGB-encoded already.
        const bool linear = image.storage == PixelType::Half || image.storage == PixelType::Float;
        if (linear) encodeColour(image);
        nlohmann::json stageTimes = nlohmann::json::array();
        const Stopwatch total;
        for (ImageStage& stage : stages) {
            const Stopwatch clock;
            stage.apply(image.pixels, image.width, image.height, image.channels(), {});
            stageTimes.push_back({{"method", stage.name},
                                  {"ms", clock.elapsedMs()},
                                  {"processed_fraction", stage.lastFraction}});
        }
        const double ms = total.elapsedMs();
        requireFiniteOutput(image, in, args.chain.empty() ? args.method : args.chain);
        if (linear) decodeColour(image);
        frames.push_back({{"input", in},
                          {"output", out},
                          {"width", image.width},
                          {"height", image.height},
                          {"ms", ms},
                          {"stages", stageTimes}});
        if (lastWrite.valid()) lastWrite.get();  // the previous frame's write error, if any, first
        makeParentFolder(out);
        lastWrite = writeBehind(out, std::move(image));
        progress.advance(1);
    }
    lastWrite.get();
    progress.finish();
    if (args.json) {
        if (frames.size() == 1) {
            nlohmann::json j = frames[0];
            j["method"] = args.chain.empty() ? args.method : args.chain;
            j["processed_fraction"] = j["stages"].back()["processed_fraction"];
            if (stages.back().cnn) {
                j["tiles"] = stages.back().cnn->tileCount();
                j["tiles_processed"] = stages.back().cnn->tilesProcessed();
                j["passed_through_fraction"] = stages.back().cnn->passedThroughFraction();
                j["model"] = args.model;
                j["gate"] = args.gate;
                j["precision"] = infer::precisionName(stages.back().cnn->options().precision);
            }
            if (stages.back().fxaa) j["preset"] = args.preset;
            std::printf("%s\n", j.dump().c_str());
        } else {
            std::printf("%s\n", nlohmann::json{{"method", args.chain.empty() ? args.method : args.chain},
                                               {"frames", frames}}
                                    .dump()
                                    .c_str());
        }
    }
}

// TAA over a sequence written by dejag render (INPUT its folder, OUTPUT a folder of sRGB PNGs), then any
// image filters of the chain on each TAA frame.
void runTaaChain(const FilterArguments& args, const std::string& taaMethod, std::vector<ImageStage>& stages) {
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
    std::set<long> cuts;
    for (const std::string& item : splitList(args.cuts)) {
        char* end = nullptr;
        const long n = std::strtol(item.c_str(), &end, 10);
        if (!end || *end != '\0' || n < 0)
            throw Error("--cuts '" + args.cuts + "' is not a list of frame numbers (e.g. 24,96)");
        cuts.insert(n);
    }
    std::error_code ec;
    fs::create_directories(args.output, ec);
    if (ec || !fs::is_directory(args.output))
        throw Error("cannot write to the output folder '" + args.output + "'");
    infer::TaaOptions options;
    options.improved = taaMethod == "taa-sobel";
    options.sharpen = !args.noSharpen;
    options.motionBlur = args.motionBlur, options.motionBlurScale = args.motionBlurScale;
    infer::Taa taa(options);
    // The history restarts at a cut: a frame listed in --cuts, or a gap in the numbering (the motion
    // vectors point into the previous frame number, which is not the frame before).
    auto frameNumber = [](const std::string& path) -> long {
        const std::string stem = fs::path(path).stem().string();  // frame_NNNN
        char* end = nullptr;
        const long n = std::strtol(stem.c_str() + 6, &end, 10);
        return end && *end == '\0' && end != stem.c_str() + 6 ? n : -1;
    };
    long previousNumber = -2;
    Progress progress("filter " + (args.chain.empty() ? args.method : args.chain), int64_t(frames.size()),
                      args.json || args.quiet);
    std::vector<float> out;
    nlohmann::json timings = nlohmann::json::array();
    std::future<Image> nextFrame = readAhead(frames.front());
    std::future<void> lastWrite;
    for (size_t index = 0; index < frames.size(); ++index) {
        const std::string& path = frames[index];
        const Image frame = nextFrame.get();
        if (index + 1 < frames.size()) nextFrame = readAhead(frames[index + 1]);
        const long number = frameNumber(path);
        const bool cut = path != frames.front() && (cuts.count(number) > 0 || number < 0 ||
                                                    previousNumber < 0 || number != previousNumber + 1);
        if (cut) taa.reset();
        previousNumber = number;
        const std::vector<float> colour = channelsOf(frame, {"R", "G", "B"}, path, true);
        std::vector<float> depth = channelsOf(frame, {"depth.Z"}, path);
        const std::vector<float> motion = channelsOf(frame, {"motion.X", "motion.Y"}, path);
        for (float& d : depth) d = float(d / far);
        std::vector<float> albedo, ids, previousDepth;
        infer::TaaFrame f;
        f.width = frame.width, f.height = frame.height;
        f.colour = colour.data(), f.depth = depth.data(), f.motion = motion.data();
        if (options.improved || !stages.empty()) {
            ids = channelsOf(frame, {"id.ID"}, path);
            f.ids = ids.data();
        }
        if (options.improved) {
            albedo = channelsOf(frame, {"albedo.R", "albedo.G", "albedo.B"}, path, true);
            previousDepth = channelsOf(frame, {"prevdepth.Z"}, path);
            for (float& d : previousDepth) d = float(d / far);
            f.albedo = albedo.data(), f.previousDepth = previousDepth.data();
        }
        out.resize(colour.size());
        const Stopwatch clock;
        taa.apply(f, out.data());
        nlohmann::json stageTimes =
            nlohmann::json::array({{{"method", taaMethod}, {"ms", clock.elapsedMs()}}});
        for (ImageStage& stage : stages) {
            const Stopwatch stageClock;
            stage.apply(out, frame.width, frame.height, 3, {depth.data(), ids.data()});
            stageTimes.push_back({{"method", stage.name},
                                  {"ms", stageClock.elapsedMs()},
                                  {"processed_fraction", stage.lastFraction}});
        }
        const double ms = clock.elapsedMs();
        Image result(frame.width, frame.height, {"R", "G", "B"}, PixelType::UInt8);
        result.pixels = out;
        const std::string name = fs::path(path).stem().string() + ".png";
        if (lastWrite.valid()) lastWrite.get();
        lastWrite = writeBehind((fs::path(args.output) / name).string(), std::move(result));
        timings.push_back({{"frame", name}, {"ms", ms}, {"stages", stageTimes}, {"history_reset", cut}});
        progress.advance(1);
    }
    lastWrite.get();
    progress.finish();
    if (args.json)
        std::printf("%s\n", nlohmann::json{{"method", args.chain.empty() ? args.method : args.chain},
                                           {"frames", timings}}
                                .dump()
                                .c_str());
}

void runFilter(const FilterArguments& args) {
    applyRuntimeOptions(args.runtime);
    if (args.method.empty() == args.chain.empty()) throw Error("give --method M or --chain M1,M2,...");
    std::vector<std::string> methods;
    if (!args.method.empty()) {
        methods.push_back(args.method);
    } else {
        methods = splitList(args.chain);
        if (methods.empty()) throw Error("--chain is empty");
        if (std::count(args.chain.begin(), args.chain.end(), ',') + 1 != std::ptrdiff_t(methods.size()))
            throw Error("--chain '" + args.chain + "' has an empty method (two commas, or one at an end)");
    }
    std::string taaMethod;
    std::vector<ImageStage> stages;  // built (models loaded and checked) before any input is read
    for (size_t i = 0; i < methods.size(); ++i) {
        if (methods[i] == "taa" || methods[i] == "taa-sobel") {
            if (i != 0) throw Error("--chain: TAA needs the rendered buffers, so it must come first");
            taaMethod = methods[i];
        } else {
            stages.push_back(makeStage(methods[i], args));
        }
    }
    if (!taaMethod.empty()) return runTaaChain(args, taaMethod, stages);
    runImageChain(args, stages);
}

}  // namespace

void registerFilterCommand(CLI::App& app) {
    auto args = std::make_shared<FilterArguments>();
    CLI::App* command = app.add_subcommand(
        "filter", "anti-alias images and sequences: FXAA 3.11, the CNN, U-TAA, T-TAA, alone or chained");
    command->add_option("--method", args->method, "fxaa | cnn | taa | taa-sobel");
    command->add_option("--chain", args->chain, "methods in order, e.g. taa,cnn or fxaa,cnn");
    command
        ->add_option(
            "--model", args->model,
            "CNN: model file (a models/... path missing here is taken from the dejag tree the binary is in)")
        ->capture_default_str();
    command
        ->add_option("--gate", args->gate,
                     "CNN: off | auto | T (run tiles whose luma steps exceed T; gated, a kernel-predicting "
                     "network also passes through runs of pixels it could move by at most 1/1024)")
        ->capture_default_str();
    command->add_option("--tile", args->tile, "CNN: tile side in pixels")
        ->check(CLI::Range(16, 4096))
        ->capture_default_str();
    command
        ->add_option("--precision", args->precision,
                     "CNN: fp32 | bf16 (AVX-512 BF16 CPUs: bf16 activations, float sums) | auto (bf16 where "
                     "the CPU has it)")
        ->capture_default_str();
    command->add_option("--preset", args->preset, "FXAA quality preset: 12, 23 or 39")->capture_default_str();
    command->add_flag("--green-luma", args->greenLuma, "FXAA: use green as luma");
    command->add_flag("--no-sharpen", args->noSharpen, "TAA: skip the final sharpen (see docs/infer.md)");
    command->add_flag("--motion-blur", args->motionBlur,
                      "TAA: blur the output along the motion vectors (docs/taa.md step 7; off by default)");
    command
        ->add_option("--motion-blur-scale", args->motionBlurScale,
                     "TAA: motion blur length, the frame rate over the target frame rate")
        ->check(CLI::Range(0.0f, 100.0f))
        ->capture_default_str();
    command->add_option(
        "--cuts", args->cuts,
        "TAA: frame numbers that start a new shot (history restarts; also at a gap in the numbering)");
    command->add_option("input", args->input, "image, folder of images, or sequence pattern (frame_%04d.png)")
        ->required();
    command
        ->add_option("output", args->output, "image, folder or pattern (bit depth and extra channels kept)")
        ->required();
    command->add_flag("--json", args->json, "print per-frame timing (and gating) as JSON");
    command->add_flag("--quiet", args->quiet, "no progress bar");
    addRuntimeOptions(command, args->runtime);
    command->footer(
        "INPUT/OUTPUT: single images (PNG, JPEG, TIFF, EXR), folders (every image, same names), or "
        "printf-style\n"
        "sequences (frame_%04d.png: every number that exists, in order; a gap is an error). Files are\n"
        "written atomically, and hidden files are not frames;\n"
        "a sequence reads one frame ahead and writes one behind while it filters (the ms of --json share "
        "the cores\n"
        "with that file I/O; dejag bench quality times the filters alone).\n"
        "FXAA and the CNN run on sRGB-encoded colour: 8/16-bit inputs as they are, half/float (linear) "
        "inputs\n"
        "encoded for the filter and decoded back; OUTPUT's format decides what it holds (EXR linear, PNG "
        "sRGB).\nFXAA constants: subpix 0.75, edge threshold 0.166, min "
        "0.0833.\n"
        "CNN: a trained model (models/*.safetensors, see models/*.md) run in tiles with a receptive-field "
        "halo,\n"
        "only on tiles with a luma step above the gate (auto = 0.04); skipped tiles pass through unchanged.\n"
        "TAA (taa = the baseline U-TAA, taa-sobel = T-TAA of docs/taa.md): INPUT is a folder written by\n"
        "dejag render --jitter halton16 --buffers color,albedo,depth,motion,id,prevdepth; OUTPUT a folder\n"
        "of sRGB PNGs, one per frame. History starts with the first frame and restarts at each --cuts frame "
        "and\n"
        "where the frame numbers skip. In a chain TAA comes first.");
    command->callback([args] {
        args->model = shippedModelPath(args->model);  // the shipped network from any directory
        runFilter(*args);
    });
}

}  // namespace dejag::cli

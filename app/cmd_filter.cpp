// dejag filter: anti-aliasing post-processes on images and sequences — FXAA 3.11, the CNN, U-TAA and
// T-TAA — alone or chained (--chain taa,cnn).
#include <algorithm>
#include <array>
#include <atomic>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <future>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <set>
#include <sstream>

#include "app/cli.h"
#include "app/commands.h"
#include "app/sequence.h"
#include "base/error.h"
#include "base/files.h"
#include "base/progress.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "data/image.h"
#include "data/video.h"
#include "infer/filter.h"
#include "nn/model.h"

namespace dejag::cli {
namespace {

namespace fs = std::filesystem;

struct FilterArguments {
    std::string method, chain, input, output, out;  // out: --out, the output as every command names it
    std::string model = "models/dejag-fast.safetensors", gate = "auto", precision = "auto";
    int tile = 2048;
    std::string preset = "39";
    bool greenLuma = false, json = false, noSharpen = false, quiet = false, listMethods = false;
    bool motionBlur = false, force = false;
    float motionBlurScale = 1.0f;
    std::string codec;  // video output: a FOURCC, "" for the extension's default (data/video.h)
    double fps = 0;     // video output from images: frames per second (0: 30)
    std::vector<std::string> settings;  // --set NAME=VALUE
    std::string channelPreset = "dejag";
    std::vector<std::string> channels;   // --channel BUFFER=NAMES
    double depthFar = 0;                 // 0: render.json's, else the first frame's largest finite depth
    std::string cuts;                    // temporal methods: frame numbers that start a new shot
    infer::FilterParameters parameters;  // the method flags the user gave, by parameter name
    RuntimeOptions runtime;
};

// One frame of a run: the file read, the file written, and its frame number (-1 if its name has none).
struct FramePair {
    std::string input, output;
    long number = -1;
};

// The frames of a run: one file, a folder of images, a folder written by dejag render (its frame_NNNN.exr
// only; into a folder they come out as frame_NNNN.png, as the render folder's previews), or a printf-style
// numbered sequence. OUTPUT may be a pattern for a folder too, numbered by the input's frame numbers.
// Hidden files (dejag's temporary ".NAME.tmp-PID-N.EXT" among them) are not frames. A pattern sequence
// with a gap in its numbering is refused: its later frames would otherwise be dropped without a word.
std::vector<FramePair> framePairs(const std::string& input, const std::string& output) {
    std::vector<FramePair> pairs;
    if (isPattern(input)) {
        if (!isPattern(output))
            throw Error("input '" + input + "' is a sequence: OUTPUT must be a pattern too");
        for (const SequenceFrame& f : listSequence(input))
            pairs.push_back({f.path, formatPattern(output, int(f.number)), f.number});
    } else if (fs::is_directory(input)) {
        const bool rendered = isRenderFolder(input);
        const std::vector<SequenceFrame> frames = listSequence(input);
        const bool pattern = isPattern(output);
        if (!pattern && fs::exists(output) && !fs::is_directory(output))
            throw Error("input '" + input + "' is a folder: OUTPUT '" + output +
                        "' must be a folder or a pattern (out/f_%04d.exr)");
        for (const SequenceFrame& f : frames) {
            std::string out;
            if (pattern) {
                if (f.number < 0)
                    throw Error("'" + f.path + "' has no frame number for the OUTPUT pattern '" + output +
                                "'");
                out = formatPattern(output, int(f.number));
            } else {
                const fs::path file(f.path);
                out =
                    (fs::path(output) / (rendered ? file.stem().string() + ".png" : file.filename().string()))
                        .string();
            }
            pairs.push_back({f.path, out, f.number});
        }
    } else {
        requireReadableFile(input);
        pairs.push_back({input, output, trailingNumber(input)});
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

// R, G, B (the first three channels: what frameFromImage encoded) decoded back to linear light; the
// other channels were never encoded. On the thread pool, each value on its own.
void decodeColour(Image& image) {
    const size_t C = size_t(image.channels());
    parallelFor(0, int64_t(image.pixelCount()), 1 << 14, [&](int64_t first, int64_t last) {
        for (size_t p = size_t(first); p < size_t(last); ++p)
            for (size_t c = 0; c < 3; ++c) image.pixels[p * C + c] = srgbToLinear(image.pixels[p * C + c]);
    });
}

// Where a sequence's render.json would be: in its folder, or beside its files.
fs::path renderSidecar(const std::string& input) {
    const fs::path folder = fs::is_directory(input) ? fs::path(input) : fs::path(input).parent_path();
    return (folder.empty() ? fs::path(".") : folder) / "render.json";
}

// The kind of values OUTPUT holds and how the filtered sRGB frame gets there: an EXR holds linear light
// (the colour decoded back), PNG and JPEG sRGB at 16 or 8 bits (TIFF keeps the input's type). Returns
// the storage to write; *decode says whether the colour is to be decoded to linear light first.
PixelType outputStorage(const std::string& out, PixelType input, bool* decode) {
    std::string ext = fs::path(out).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    const bool linearInput = holdsLinearLight(input);
    *decode = false;
    if (!linearInput) return input;  // sRGB values: writeImage converts for an EXR
    if (ext == ".png") return PixelType::UInt16;
    if (ext == ".jpg" || ext == ".jpeg") return PixelType::UInt8;
    *decode = true;
    return input;
}

// A video in: its frames decoded one ahead on a thread of their own, filtered in order, and written as a
// video (encoded one behind) or as images (OUTPUT a pattern or a folder: frame_NNNN.png, from 0).
void runVideoFilter(FilterArguments& args, const std::string& methods, infer::Filter& filter,
                    infer::FrameOptions frameOptions) {
    VideoReader reader(args.input);
    const VideoInfo info = reader.info();
    const bool videoOut = isVideoPath(args.output);
    const bool patternOut = !videoOut && isPattern(args.output);
    if (!videoOut && !patternOut && fs::exists(args.output) && !fs::is_directory(args.output))
        throw Error("input '" + args.input + "' is a video: OUTPUT '" + args.output +
                    "' must be a video, a folder or a pattern (out/f_%04d.png)");
    const auto framePath = [&](int64_t index) {
        return patternOut ? formatPattern(args.output, int(index))
                          : (fs::path(args.output) / formatPattern("frame_%04d.png", int(index))).string();
    };
    const std::string firstOutput = videoOut ? args.output : framePath(0);
    if (!args.force && fs::exists(firstOutput))
        throw Error("'" + firstOutput + "' exists; add --force to overwrite");
    frameOptions.keepExtraChannels = false;
    frameOptions.depthFar = 1.0;
    const double fps = args.fps > 0 ? args.fps : info.fps > 0 ? info.fps : 30.0;
    std::unique_ptr<VideoWriter> writer;
    if (videoOut) {
        makeParentFolder(args.output);
        writer = std::make_unique<VideoWriter>(args.output, info.width, info.height, fps, args.codec);
    } else if (!args.codec.empty()) {
        throw Error("--codec names a video codec, and OUTPUT '" + args.output + "' is images");
    }

    Progress progress("filter " + methods, std::max<int64_t>(info.frameCount, 1), args.json || args.quiet);
    const auto decode = [&reader](Image* into) { return reader.read(*into); };
    Image frames[2];
    std::future<bool> next = std::async(std::launch::async, decode, &frames[0]);
    std::future<void> lastWrite;
    std::vector<float> out;
    double msSum = 0;
    int64_t index = 0;
    for (;; ++index) {
        Image& image = frames[index % 2];
        if (!next.get()) break;
        // The next frame decodes into the other buffer, which the previous write has finished with.
        if (lastWrite.valid()) lastWrite.get();
        next = std::async(std::launch::async, decode, &frames[(index + 1) % 2]);
        const std::string label = args.input + " frame " + std::to_string(index);
        infer::FrameData data = infer::frameFromImage(image, frameOptions, label);
        out.resize(data.colour.size());
        filter.apply(data.frame(), out.data());
        msSum += filter.figures().ms;
        Image result(image.width, image.height, data.colourNames, PixelType::UInt8);
        result.pixels.swap(out);
        requireFiniteOutput(result, label, methods);
        if (writer) {
            lastWrite = std::async(std::launch::async,
                                   [&writer, result = std::move(result)] { writer->write(result); });
        } else {
            const std::string path = framePath(index);
            if (index == 0) makeParentFolder(path);
            lastWrite = writeBehind(path, std::move(result));
        }
        progress.advance(1);
    }
    if (lastWrite.valid()) lastWrite.get();
    if (index == 0) throw Error("'" + args.input + "' holds no frame FFmpeg can decode");
    if (writer) writer->close();
    progress.setTotal(index);
    progress.finish();
    if (!args.json) return;
    nlohmann::json summary = {
        {"input", args.input}, {"output", args.output},     {"method", methods},
        {"frames", index},     {"width", info.width},       {"height", info.height},
        {"fps", fps},          {"input_codec", info.codec}, {"ms_mean", msSum / double(index)}};
    if (writer) summary["codec"] = writer->codec();
    std::printf("%s\n", summary.dump().c_str());
}

// Every method, one face: frames from any sequence (colour and the buffers the methods use, channel
// names mapped), filtered in order, written as OUTPUT says.
void runFilter(FilterArguments& args, const std::string& methods) {
    // The filter is built (models loaded and checked, every parameter judged) before any input is read.
    args.parameters.setPathResolver(shippedModelPath);
    std::unique_ptr<infer::Filter> filter = infer::makeFilter(methods, args.parameters);
    const bool temporal = filter->temporal();
    std::set<long> cuts;
    for (const std::string& item : splitList(args.cuts)) {
        char* end = nullptr;
        const long n = std::strtol(item.c_str(), &end, 10);
        if (!end || *end != '\0' || n < 0)
            throw Error("--cuts '" + args.cuts + "' is not a list of frame numbers (e.g. 24,96)");
        cuts.insert(n);
    }
    if (!cuts.empty() && !temporal) throw Error("--cuts: " + methods + " keeps no history across frames");
    infer::FrameOptions frameOptions;
    frameOptions.channels = infer::ChannelMap::preset(args.channelPreset);
    for (const std::string& c : args.channels) frameOptions.channels.assign(c);
    frameOptions.required = filter->needs();
    frameOptions.wanted = filter->uses();
    if (isVideoPath(args.input)) {
        if (temporal)
            throw Error(methods +
                        " needs the depth and motion of each frame, which a video does not hold; "
                        "a video takes the single-frame methods");
        return runVideoFilter(args, methods, *filter, frameOptions);
    }
    // Images in, a video out: the frames go to one encoder instead of one file each.
    const bool videoOut = isVideoPath(args.output);
    if (!videoOut && !args.codec.empty())
        throw Error("--codec names a video codec, and OUTPUT '" + args.output + "' is not a video");
    if (videoOut && !args.force && fs::exists(args.output))
        throw Error("'" + args.output + "' exists; add --force to overwrite");
    std::vector<FramePair> pairs;
    if (!videoOut) {
        pairs = framePairs(args.input, args.output);
    } else if (isPattern(args.input) || fs::is_directory(args.input)) {
        for (const SequenceFrame& f : listSequence(args.input))
            pairs.push_back({f.path, args.output, f.number});
    } else {
        requireReadableFile(args.input);
        pairs.push_back({args.input, args.output, trailingNumber(args.input)});
    }
    if (pairs.empty()) throw Error("'" + args.input + "' holds no frames");
    std::unique_ptr<VideoWriter> video;
    // Nothing is overwritten unless asked: every output is checked before the first frame is read.
    if (!args.force && !videoOut) {
        int existing = 0;
        std::string first;
        std::error_code error;
        for (const FramePair& pair : pairs)
            if (fs::exists(pair.output, error) && existing++ == 0) first = pair.output;
        if (existing > 0)
            throw Error(
                "'" + first + "' exists" +
                (existing > 1 ? " (and " + std::to_string(existing - 1) + " more of the outputs)" : "") +
                "; add --force to overwrite");
    }
    // A method that reads buffers makes the frame its colour (and alpha); the others keep every channel,
    // unless the output is a PNG or JPEG, which holds the colour alone.
    std::string outputExtension = pairs.empty() ? "" : fs::path(pairs.front().output).extension().string();
    std::transform(outputExtension.begin(), outputExtension.end(), outputExtension.begin(),
                   [](unsigned char c) { return char(std::tolower(c)); });
    frameOptions.keepExtraChannels = filter->needs() == 0 && outputExtension != ".png" &&
                                     outputExtension != ".jpg" && outputExtension != ".jpeg";

    // The far plane depth is divided by: --depth-far, the render.json of a dejag render sequence, or the
    // largest finite depth of the first frame.
    nlohmann::json sidecar;
    if (std::ifstream in(renderSidecar(args.input)); in) sidecar = nlohmann::json::parse(in, nullptr, false);
    std::map<std::string, std::array<float, 2>> jitters;
    if (sidecar.is_object() && sidecar.contains("frames") && sidecar["frames"].is_array())
        for (const nlohmann::json& f : sidecar["frames"])
            if (f.is_object() && f.contains("file") && f["file"].is_string() && f.contains("jitter_pixels") &&
                f["jitter_pixels"].is_array() && f["jitter_pixels"].size() == 2 &&
                f["jitter_pixels"][0].is_number() && f["jitter_pixels"][1].is_number())
                jitters[f["file"].get<std::string>()] = {f["jitter_pixels"][0].get<float>(),
                                                         f["jitter_pixels"][1].get<float>()};
    // A sequence of a dataset (dejag data generate --sequence-length) lists its cuts beside its frames.
    if (temporal && sidecar.is_object() && sidecar.contains("cuts") && sidecar["cuts"].is_array())
        for (const nlohmann::json& cut : sidecar["cuts"])
            if (cut.is_number_integer() && cut.get<long>() >= 0) cuts.insert(cut.get<long>());
    const bool usesDepth = (filter->uses() & (infer::Buffer::Depth | infer::Buffer::PreviousDepth)) != 0;
    double far = args.depthFar;
    std::string farSource = "--depth-far";
    if (far <= 0 && sidecar.is_object()) {
        far = sidecar.contains("depth_far") && sidecar["depth_far"].is_number()
                  ? sidecar["depth_far"].get<double>()
                  : 200.0;
        farSource = "render.json";
    }

    Progress progress("filter " + methods, int64_t(pairs.size()),
                      args.json || args.quiet || pairs.size() == 1);
    nlohmann::json frames = nlohmann::json::array();
    // (Frames read one ahead and written one behind: readAhead / writeBehind.)
    std::future<Image> nextImage = readAhead(pairs.front().input);
    std::future<void> lastWrite;
    std::vector<float> out;
    long previousNumber = -2;
    for (size_t index = 0; index < pairs.size(); ++index) {
        const FramePair& pair = pairs[index];
        const Image image = nextImage.get();
        if (index + 1 < pairs.size()) nextImage = readAhead(pairs[index + 1].input);
        if (auto bad = findNonFinite(image))
            throw Error("'" + pair.input + "' has a non-finite value at pixel (" + std::to_string(bad->x) +
                        ", " + std::to_string(bad->y) + ")");
        if (far <= 0) {
            far = usesDepth ? infer::largestFiniteDepth(image, frameOptions.channels) : 1.0;
            if (!(far > 0)) far = 1.0;
            farSource = "the first frame's largest finite depth";
        }
        frameOptions.depthFar = far;
        // The methods work on display-referred colour: half and float files hold linear light, so their
        // colour is encoded to sRGB for the methods and decoded back where OUTPUT holds linear light.
        infer::FrameData data = infer::frameFromImage(image, frameOptions, pair.input);
        if (auto j = jitters.find(fs::path(pair.input).filename().string()); j != jitters.end())
            data.hasJitter = true, data.jitter[0] = j->second[0], data.jitter[1] = j->second[1];
        // The history restarts at a cut: a frame listed in --cuts, or a gap in the numbering (the motion
        // vectors point into the previous frame number, which is not the frame before).
        const long number = pair.number;
        const bool cut =
            temporal && index > 0 &&
            (cuts.count(number) > 0 || number < 0 || previousNumber < 0 || number != previousNumber + 1);
        if (cut) filter->reset();
        previousNumber = number;
        const infer::Frame frame = data.frame();
        out.resize(data.colour.size());
        filter->apply(frame, out.data());
        nlohmann::json stageTimes = nlohmann::json::array();
        std::vector<const infer::Filter*> stages = filter->stages();
        if (stages.empty()) stages.push_back(filter.get());
        for (const infer::Filter* stage : stages)
            stageTimes.push_back({{"method", stage->name()},
                                  {"ms", stage->figures().ms},
                                  {"processed_fraction", stage->figures().processedFraction}});
        Image result(image.width, image.height, data.colourNames, image.storage);
        result.pixels.swap(out);
        requireFiniteOutput(result, pair.input, methods);
        bool decode = false;
        result.storage = outputStorage(pair.output, image.storage, &decode);
        if (decode) decodeColour(result);
        nlohmann::json record = {{"input", pair.input},        {"output", pair.output},
                                 {"width", image.width},       {"height", image.height},
                                 {"ms", filter->figures().ms}, {"stages", stageTimes}};
        if (temporal) {
            record["frame"] = fs::path(pair.output).filename().string();
            record["history_reset"] = cut;
        }
        frames.push_back(record);
        if (lastWrite.valid()) lastWrite.get();  // the previous frame's write error, if any, first
        makeParentFolder(pair.output);
        if (videoOut) {
            if (!video)
                video = std::make_unique<VideoWriter>(args.output, result.width, result.height,
                                                      args.fps > 0 ? args.fps : 30.0, args.codec);
            lastWrite = std::async(std::launch::async,
                                   [&video, result = std::move(result)] { video->write(result); });
        } else {
            lastWrite = writeBehind(pair.output, std::move(result));
        }
        progress.advance(1);
    }
    lastWrite.get();
    if (video) video->close();
    progress.finish();
    if (!args.json) return;
    nlohmann::json summary;
    if (frames.size() == 1 && !temporal) {
        summary = frames[0];
        summary["processed_fraction"] = filter->figures().processedFraction;
        for (const auto& [name, value] : filter->figures().extra) summary[name] = value;
        for (const auto& [name, value] : filter->figures().settings) summary[name] = value;
    } else {
        summary["frames"] = frames;
    }
    summary["method"] = methods;
    if (usesDepth) summary["depth_far"] = {{"value", far}, {"from", farSource}};
    std::printf("%s\n", summary.dump().c_str());
}

// The method flags the user gave, as the parameters of infer/filter.h (the factory refuses any that
// no method of the chain reads).
struct MethodFlag {
    const char* flag;
    const char* parameter;
};
constexpr MethodFlag kMethodFlags[] = {
    {"--model", "model"},
    {"--gate", "gate"},
    {"--tile", "tile"},
    {"--precision", "precision"},
    {"--preset", "preset"},
    {"--green-luma", "green-luma"},
    {"--no-sharpen", "sharpen"},
    {"--motion-blur", "motion-blur"},
    {"--motion-blur-scale", "motion-blur-scale"},
};

void collectParameters(CLI::App& command, FilterArguments& args) {
    for (const MethodFlag& f : kMethodFlags) {
        if (command.get_option(f.flag)->count() == 0) continue;
        const std::string flag = f.flag;
        std::string value;
        if (flag == "--model")
            value = args.model;
        else if (flag == "--gate")
            value = args.gate;
        else if (flag == "--tile")
            value = std::to_string(args.tile);
        else if (flag == "--precision")
            value = args.precision;
        else if (flag == "--preset")
            value = args.preset;
        else if (flag == "--green-luma")
            value = "true";
        else if (flag == "--no-sharpen")
            value = "false";
        else if (flag == "--motion-blur")
            value = "true";
        else if (flag == "--motion-blur-scale")
            value = std::to_string(args.motionBlurScale);
        args.parameters.set(f.parameter, value, flag);
    }
    for (const std::string& s : args.settings) args.parameters.setAssignment(s);
}

void listMethods(bool json) {
    if (!json) {
        std::printf("%s", infer::describeMethods().c_str());
        return;
    }
    nlohmann::json list = nlohmann::json::array();
    for (const infer::MethodSpec& m : infer::filterMethods()) {
        nlohmann::json parameters = nlohmann::json::array();
        for (const infer::ParameterSpec& p : m.parameters)
            parameters.push_back({{"name", p.name}, {"default", p.defaultValue}, {"help", p.help}});
        list.push_back({{"name", m.name},
                        {"summary", m.summary},
                        {"temporal", m.temporal},
                        {"needs", infer::bufferList(m.needs)},
                        {"uses", infer::bufferList(m.optional)},
                        {"parameters", parameters}});
    }
    std::printf("%s\n", list.dump(2).c_str());
}

}  // namespace

void registerFilterCommand(CLI::App& app) {
    auto args = std::make_shared<FilterArguments>();
    CLI::App* command = app.add_subcommand(
        "filter", "anti-alias images and sequences: FXAA, SMAA, the networks, the TAAs, alone or chained");
    command->add_option(
        "--method", args->method,
        "none | fxaa | smaa | cnn | taa | taa-sobel | taa-hq | cnn-temporal (--list-methods)");
    command->add_option("--chain", args->chain,
                        "methods in order, each filtering the one before: taa,cnn or fxaa,cnn");
    command->add_flag("--list-methods", args->listMethods,
                      "print every method with its parameters, their defaults and the buffers it needs");
    command
        ->add_option("--set", args->settings,
                     "a method parameter NAME=VALUE (repeatable; --list-methods names them, e.g. subpix=0.5)")
        ->allow_extra_args(false);
    command
        ->add_option("--model", args->model,
                     "CNN: model file, or a shipped model's name (dejag-fast: models/dejag-fast.safetensors, "
                     "found in the dejag tree the binary is in)")
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
    command->add_option(
        "--preset", args->preset,
        "quality preset: FXAA 12, 23 or 39 (default 39); SMAA low, medium, high or ultra (default ultra)");
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
    command
        ->add_option("--channels", args->channelPreset,
                     "the channel names of the input files: dejag (dejag render's) | blender (a Blender "
                     "multilayer EXR of view layer ViewLayer)")
        ->capture_default_str();
    command
        ->add_option("--channel", args->channels,
                     "one buffer's channels, BUFFER=NAME[,NAME...] (repeatable): color=R,G,B, "
                     "albedo=..., depth=Z, motion=X,Y (a leading - negates), id=..., prevdepth=...")
        ->allow_extra_args(false);
    command
        ->add_option("--depth-far", args->depthFar,
                     "divide depth by this far plane (default: render.json's, else the first frame's largest "
                     "finite depth)")
        ->check(CLI::Range(1e-9, 1e30));
    command->add_option(
        "input", args->input,
        "image, video, folder of images, or sequence pattern (frame_%04d.exr); - reads one image from "
        "standard input");
    command->add_option(
        "output", args->output,
        "image, video, folder or pattern (out/f_%04d.exr); its extension decides what it holds; - writes "
        "the image to standard output in the input's format");
    command->add_option("--out", args->out, "the output, as the positional OUTPUT (one of the two)");
    command->add_option("--codec", args->codec,
                        "video OUTPUT: FOURCC of the codec (default by extension: .mkv FFV1 lossless, "
                        ".mp4/.mov avc1, .avi MJPG)");
    command
        ->add_option("--fps", args->fps,
                     "video OUTPUT from images: frames per second (default 30; a "
                     "video input keeps its own)")
        ->check(CLI::Range(0.001, 1000.0));
    command->add_flag("--json", args->json, "print per-frame timing (and gating) as JSON");
    command->add_flag("--quiet", args->quiet, "no progress bar");
    command->add_flag("--force", args->force,
                      "overwrite outputs that exist (without it, refused before any work)");
    addRuntimeOptions(command, args->runtime);
    command->footer(
        "INPUT/OUTPUT: single images (PNG, JPEG, TIFF, EXR), videos (.mp4 .mov .mkv .avi), folders (every\n"
        "image, same names), printf-style\n"
        "sequences (frame_%04d.exr: every number that exists, in order; a gap is an error), or a folder\n"
        "written by dejag render (its frame_NNNN.exr, its render.json for the far plane and the jitter).\n"
        "Files are written atomically, and hidden files are not frames; a sequence reads one frame ahead "
        "and\n"
        "writes one behind while it filters (the ms of --json share the cores with that file I/O).\n"
        "A video is filtered frame by frame by the single-frame methods (8-bit sRGB, no buffers), keeping\n"
        "its size and frame rate, into a video (--codec; .mkv is lossless FFV1) or images; a folder or\n"
        "sequence of images goes into a video at --fps. docs/video.md.\n"
        "Every method runs on sRGB-encoded colour: 8/16-bit inputs as they are, half/float (linear) inputs\n"
        "encoded for the methods; OUTPUT's format decides what it holds (EXR linear light, PNG 16-bit and\n"
        "JPEG 8-bit sRGB from a linear input; an integer input keeps its bit depth).\n"
        "Buffers: colour plus albedo, depth, motion, id and prevdepth, read from the channels --channels "
        "and\n"
        "--channel name (default dejag render's: albedo.R.., depth.Z, motion.X/Y, id.ID, prevdepth.Z); a\n"
        "method missing one names the channel it looked for. Depth is divided by the far plane.\n"
        "TAA (taa = U-TAA, taa-sobel = T-TAA of docs/taa.md) needs depth and motion (T-TAA albedo, id and\n"
        "prevdepth too); its history starts with the first frame and restarts at each --cuts frame and "
        "where\n"
        "the frame numbers skip. A method that reads buffers writes colour (and alpha) only.\n"
        "CNN: a trained model (models/*.safetensors, see models/*.md) run in tiles with a receptive-field\n"
        "halo, only on tiles with a luma step above the gate (auto = 0.04), an id change or a depth jump.\n"
        "Every parameter of every method: dejag filter --list-methods.");
    command->callback([args, command] {
        if (args->listMethods) return listMethods(args->json);
        applyRuntimeOptions(args->runtime);
        if (!args->out.empty()) {
            if (!args->output.empty()) throw Error("give OUTPUT or --out, not both");
            args->output = args->out;
        }
        if (args->input.empty() || args->output.empty())
            throw Error("give INPUT and OUTPUT (or --list-methods)");
        if (args->method.empty() == args->chain.empty()) throw Error("give --method M or --chain M1,M2,...");
        if (!args->chain.empty() && splitList(args->chain).empty()) throw Error("--chain is empty");
        if (!args->chain.empty() && std::count(args->chain.begin(), args->chain.end(), ',') + 1 !=
                                        std::ptrdiff_t(splitList(args->chain).size()))
            throw Error("--chain '" + args->chain + "' has an empty method (two commas, or one at an end)");
        collectParameters(*command, *args);
        // "-": the image comes from standard input or goes to standard output (in the input's format).
        StandardStreams streams;
        args->input = streams.input(args->input);
        if (args->output == "-") {
            if (args->json) throw Error("--json prints to standard output, which '-' takes for the image");
            std::string extension = fs::path(args->input).extension().string();
            std::transform(extension.begin(), extension.end(), extension.begin(),
                           [](unsigned char c) { return char(std::tolower(c)); });
            args->output = streams.output("-", extension);
        }
        runFilter(*args, args->method.empty() ? args->chain : args->method);
        streams.finish();
    });
}

}  // namespace dejag::cli

// dejag filter: anti-aliasing post-processes on images (FXAA now; TAA and the CNN come next).
#include <cstdio>
#include <nlohmann/json.hpp>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/timer.h"
#include "data/image.h"
#include "infer/fxaa.h"

namespace dejag::cli {
namespace {

struct FilterArguments {
    std::string method, input, output;
    int preset = 39;
    bool greenLuma = false, json = false;
    RuntimeOptions runtime;
};

void runFilter(const FilterArguments& args) {
    applyRuntimeOptions(args.runtime);
    if (args.method != "fxaa")
        throw Error("--method '" + args.method +
                    "' is not available yet (fxaa; taa, taa-sobel and cnn are planned)");
    infer::FxaaOptions options;
    options.preset = args.preset;
    options.greenAsLuma = args.greenLuma;
    infer::Fxaa fxaa(options);
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
    fxaa.apply(image.pixels.data(), out.pixels.data(), image.width, image.height, image.channels());
    const double ms = clock.elapsedMs();
    if (linear)
        for (size_t p = 0; p < out.pixelCount(); ++p)
            for (int c = 0; c < 3; ++c) {
                float& v = out.pixels[p * size_t(out.channels()) + size_t(c)];
                v = srgbToLinear(v);
            }
    writeImage(args.output, out);
    if (args.json)
        std::printf("%s\n", nlohmann::json{{"method", "fxaa"},
                                           {"preset", args.preset},
                                           {"input", args.input},
                                           {"output", args.output},
                                           {"width", image.width},
                                           {"height", image.height},
                                           {"ms", ms},
                                           {"processed_fraction", fxaa.processedFraction()}}
                                .dump()
                                .c_str());
}

}  // namespace

void registerFilterCommand(CLI::App& app) {
    auto args = std::make_shared<FilterArguments>();
    CLI::App* command =
        app.add_subcommand("filter", "anti-alias an image: FXAA 3.11 (TAA and the CNN are planned)");
    command->add_option("--method", args->method, "fxaa")->required();
    command->add_option("--preset", args->preset, "FXAA quality preset: 12, 23 or 39")->capture_default_str();
    command->add_flag("--green-luma", args->greenLuma, "FXAA: use green as luma");
    command->add_option("input", args->input, "input image (PNG, JPEG, TIFF, EXR)")->required();
    command->add_option("output", args->output, "output image (bit depth and extra channels kept)")
        ->required();
    command->add_flag("--json", args->json, "print timing as JSON");
    addRuntimeOptions(command, args->runtime);
    command->footer(
        "FXAA runs on sRGB-encoded colour: 8/16-bit inputs as they are, half/float (linear) inputs encoded\n"
        "for the filter and decoded back. Constants: subpix 0.75, edge threshold 0.166, minimum 0.0833.");
    command->callback([args] { runFilter(*args); });
}

}  // namespace dejag::cli

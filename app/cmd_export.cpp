// dejag export: a model in a format other software runs. --onnx: an ONNX file (opset 13) for any runtime
// with the standard operators (docs/onnx.md).
#include <cstdio>
#include <filesystem>
#include <memory>
#include <nlohmann/json.hpp>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/files.h"
#include "infer/glsl_filter.h"
#include "nn/glsl.h"
#include "nn/model.h"
#include "nn/onnx.h"

namespace dejag::cli {
namespace {

namespace fs = std::filesystem;

struct ExportArguments {
    std::string model, output, size;
    std::vector<std::string> settings;  // --set NAME=VALUE (a method's)
    bool onnx = false, glsl = false, force = false, json = false;
};

// --glsl: OUT is a folder of shaders, weights.bin and network.json (nn/glsl.h).
void runGlslExport(const ExportArguments& args) {
    if (!args.size.empty()) throw Error("--size is for --onnx; the GLSL passes take the size as uniforms");
    std::error_code error;
    if (fs::exists(args.output, error) && !fs::is_directory(args.output, error))
        throw Error("'" + args.output + "' is a file; --glsl writes a folder");
    if (fs::is_directory(args.output, error) && !fs::is_empty(args.output, error)) {
        if (!args.force) throw Error("'" + args.output + "' is not empty; add --force to replace its export");
        if (!fs::exists(fs::path(args.output) / "network.json"))
            throw Error("'" + args.output + "' holds no GLSL export (no network.json): not replaced");
        for (const auto& entry : fs::directory_iterator(args.output)) {
            const std::string name = entry.path().filename().string();
            if (entry.path().extension() == ".comp" || entry.path().extension() == ".bin" ||
                name == "network.json")
                fs::remove(entry.path());
        }
    }
    const fs::path folder = fs::path(args.output).parent_path();
    if (!folder.empty() && !fs::is_directory(folder))
        throw Error("cannot write '" + args.output + "': the folder '" + folder.string() +
                    "' does not exist");
    if (infer::findMethod(args.model)) {  // a method, not a network: its passes and what they bind
        infer::FilterParameters parameters;
        for (const std::string& assignment : args.settings) parameters.setAssignment(assignment);
        const infer::GlslMethodFiles files = infer::glslMethodFiles(args.model, parameters);
        std::error_code made;
        fs::create_directories(args.output, made);
        for (const auto& [name, source] : files.passes)
            writeTextFileAtomically((fs::path(args.output) / name).string(), source);
        for (const auto& [name, values] : files.tables)
            writeBytesAtomically((fs::path(args.output) / name).string(),
                                 std::string_view(reinterpret_cast<const char*>(values.data()),
                                                  values.size() * sizeof(float)));
        writeTextFileAtomically((fs::path(args.output) / "network.json").string(),
                                files.description.dump(2) + "\n");
        if (args.json) {
            std::printf("%s\n", nlohmann::json{{"method", args.model},
                                               {"output", args.output},
                                               {"format", "glsl"},
                                               {"passes", files.passes.size()},
                                               {"tables", files.tables.size()}}
                                    .dump()
                                    .c_str());
        } else {
            std::string names;
            for (const auto& [name, source] : files.passes) names += (names.empty() ? "" : ", ") + name;
            for (const auto& [name, values] : files.tables) names += ", " + name;
            std::printf("wrote %s/: %s (GLSL 430) and network.json\n", args.output.c_str(), names.c_str());
        }
        return;
    }
    if (!args.settings.empty()) throw Error("--set is for a method (fxaa, smaa, taa, taa-sobel, taa-hq)");
    const std::string path = shippedModelPath(args.model);
    const nn::Model model = nn::loadModel(path);
    const nn::GlslNetwork network = nn::exportGlsl(model);
    nn::writeGlslNetwork(args.output, network);
    if (args.json) {
        std::printf("%s\n", nlohmann::json{{"model", path},
                                           {"output", args.output},
                                           {"format", "glsl"},
                                           {"passes", network.passes.size()},
                                           {"weights", network.weights.size()},
                                           {"size_divisor", network.sizeDivisor},
                                           {"input_channels", model.inputChannels()},
                                           {"output_channels", model.outputChannels()}}
                                .dump()
                                .c_str());
        return;
    }
    std::printf(
        "wrote %s/: %zu GLSL 430 compute passes, weights.bin (%zu floats), network.json; input %d "
        "channels, planar float32, sides multiples of %d\n",
        args.output.c_str(), network.passes.size(), network.weights.size(), model.inputChannels(),
        network.sizeDivisor);
}

void runExport(const ExportArguments& args) {
    if (args.onnx == args.glsl) throw Error("name one format: --onnx or --glsl");
    if (args.glsl) return runGlslExport(args);
    if (!args.force && fs::exists(args.output))
        throw Error("'" + args.output + "' exists; add --force to overwrite");
    const fs::path folder = fs::path(args.output).parent_path();
    if (!folder.empty() && !fs::is_directory(folder))
        throw Error("cannot write '" + args.output + "': the folder '" + folder.string() +
                    "' does not exist");
    const std::string path = shippedModelPath(args.model);
    std::map<std::string, std::string> metadata;
    const nn::Model model = nn::loadModel(path, &metadata);
    nn::OnnxOptions options;
    if (!args.size.empty()) {
        const Size size = parseSize(args.size, "--size");
        options.width = size.width, options.height = size.height;
    }
    options.producerVersion = DEJAG_VERSION;
    for (const char* key : {"dejag.provenance", "dejag.guide_method", "dejag.input_method"})
        if (auto it = metadata.find(key); it != metadata.end()) options.metadata[key] = it->second;
    options.metadata["dejag.source"] = fs::path(path).filename().string();
    const std::string bytes = nn::exportOnnx(model, options);
    writeBytesAtomically(args.output, bytes);
    const std::string size = args.size.empty()
                                 ? std::string("HxW")
                                 : std::to_string(options.height) + "x" + std::to_string(options.width);
    if (args.json) {
        std::printf("%s\n", nlohmann::json{{"model", path},
                                           {"output", args.output},
                                           {"format", "onnx"},
                                           {"opset", 13},
                                           {"bytes", bytes.size()},
                                           {"input_channels", model.inputChannels()},
                                           {"output_channels", model.outputChannels()},
                                           {"size", args.size.empty() ? nlohmann::json("symbolic")
                                                                      : nlohmann::json(args.size)}}
                                .dump()
                                .c_str());
        return;
    }
    std::printf(
        "wrote %s (%zu bytes, ONNX opset 13): input 'input' 1x%dx%s, output 'output' 1x%dx%s (NCHW)\n",
        args.output.c_str(), bytes.size(), model.inputChannels(), size.c_str(), model.outputChannels(),
        size.c_str());
}

}  // namespace

void registerExportCommand(CLI::App& app) {
    auto args = std::make_shared<ExportArguments>();
    CLI::App* command =
        app.add_subcommand("export",
                           "write a model for other runtimes: ONNX (a training run's best model: "
                           "dejag train export)");
    command->add_flag("--onnx", args->onnx, "write ONNX (opset 13, standard operators only)");
    command->add_flag(
        "--glsl", args->glsl,
        "write GLSL 430 compute shaders, one per pass, with weights.bin and network.json into the "
        "folder OUT");
    command
        ->add_option("MODEL", args->model,
                     "model file, a shipped model's name (dejag-fast), or for --glsl a method (fxaa, smaa, "
                     "taa, taa-sobel, taa-hq)")
        ->required();
    command->add_option("OUT", args->output, "the file to write (model.onnx), or the folder (--glsl)")
        ->required();
    command->add_option("--size", args->size,
                        "fix the input to WIDTHxHEIGHT (default: symbolic height and width; some runtimes "
                        "need them fixed)");
    command->add_option(
        "--set", args->settings,
        "--glsl of a method: a parameter NAME=VALUE (repeatable; dejag filter --list-methods)");
    command->add_flag("--force", args->force, "overwrite OUT if it exists");
    command->add_flag("--json", args->json, "print what was written as JSON");
    command->footer(
        "The graph takes 'input' (1, C, H, W) and gives 'output', on the values the model sees in dejag:\n"
        "sRGB-encoded colour in [0, 1] (a guided model: the frame, then the guide method's result on it).\n"
        "The kernel filter is decomposed into Softmax, Pad (edge), Slice, Mul and Add. A U-Net needs H and\n"
        "W divisible by 2^depth (8 for the shipped ones). A recurrent model (dejag-temporal) reads its taps\n"
        "with GatherElements and computes one frame: its output becomes channels 3..9 of the next frame's\n"
        "input. docs/onnx.md.\n"
        "--glsl: one compute pass per node (a concatenation: one per input), every tensor a storage buffer "
        "of\n"
        "planar floats; network.json says what each pass binds and how to dispatch it; a recurrent model's\n"
        "passes compute one frame from the input its caller assembles (its history included). docs/glsl.md.");
    command->callback([args] { runExport(*args); });
}

}  // namespace dejag::cli

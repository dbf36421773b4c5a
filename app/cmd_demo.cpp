// dejag demo: every anti-aliasing method, including the shipped networks, on a set of rendered scenes;
// prints the table and writes an HTML report (what `make demo` runs).
#include <cstdio>
#include <sstream>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "bench/demo.h"
#include "bench/quality.h"

namespace dejag::cli {

void registerDemoCommand(CLI::App& app) {
    auto options = std::make_shared<bench::DemoOptions>();
    auto runtime = std::make_shared<RuntimeOptions>();
    auto size = std::make_shared<std::string>("640x360");
    auto scenes = std::make_shared<std::string>();
    auto models = std::make_shared<std::string>(bench::kShippedModels);
    auto json = std::make_shared<bool>(false);
    CLI::App* command = app.add_subcommand("demo",
                                           "render a scene set, run every method (FXAA, SMAA, the TAAs, the "
                                           "shipped networks), write an HTML report");
    command->add_option("--out", options->out, "report folder")->capture_default_str();
    command->add_option("--size", *size, "size of the frames, WIDTHxHEIGHT")->capture_default_str();
    command->add_option("--truth", options->truthSamples, "samples of the truth")->capture_default_str();
    command->add_option("--scenes", *scenes,
                        "comma-separated scenes (default: atrium,hard-edges,flowers,pipe,text-wall,planes)");
    command->add_option("--models", *models, "comma-separated model files")->capture_default_str();
    command->add_option("--repeat", options->repeat, "timing repeats")->capture_default_str();
    command
        ->add_option("--temporal-model", options->temporalModel,
                     "the temporal network of the moving sequence (missing: the sequence is skipped)")
        ->capture_default_str();
    command->add_option("--moving-scene", options->movingScene, "the moving sequence's scene")
        ->capture_default_str();
    command->add_option("--moving-frames", options->movingFrames, "frames of the moving sequence")
        ->check(CLI::Range(2, 10000))
        ->capture_default_str();
    command->add_flag("--json", *json, "print the rows as JSON lines instead of the table");
    command->add_flag("--quiet", options->quiet, "no progress bar");
    addRuntimeOptions(command, *runtime);
    command->footer(
        "Writes OUT/report.html (crops and SSIM maps side by side), OUT/mosaic.png, OUT/pareto.png (ms "
        "against\n"
        "PSNR), OUT/results.csv and OUT/results.json. Models not found are skipped with a note.");
    command->callback([=] {
        applyRuntimeOptions(*runtime);
        const Size s = parseSize(*size, "--size");
        options->width = s.width, options->height = s.height;
        options->scenes = splitList(*scenes);
        options->models = shippedModelPaths(splitList(*models));
        options->temporalModel = shippedModelPath(options->temporalModel);  // from any folder
        std::vector<nlohmann::json> moving;
        const std::vector<nlohmann::json> rows = bench::runDemo(*options, &moving);
        bench::printQualityRows(rows, *json, false);
        for (const nlohmann::json& row : moving) {
            if (*json) {
                std::printf("%s\n", row.dump().c_str());
                continue;
            }
            std::printf("moving %-10s %-16s PSNR %.2f dB  SSIM %.4f  flicker %.5f  (frames %d-%d)\n",
                        row["scene"].get<std::string>().c_str(), row["method"].get<std::string>().c_str(),
                        row["psnr"].get<double>(), row["ssim"].get<double>(), row["flicker"].get<double>(),
                        row["scored_from"].get<int>(), row["frames"].get<int>() - 1);
        }
        if (!*json) {
            std::printf("report: %s/report.html\n", options->out.c_str());
            std::printf(
                "live, in a window: dejag view --scene atrium --method cnn --compare fxaa (keys 1-8 switch "
                "methods; docs/view.md)\n");
        }
    });
}

}  // namespace dejag::cli

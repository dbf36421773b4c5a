// dejag data: dataset generation (resumable, parallel worker processes), verification and statistics.
#include <cstdio>
#include <sstream>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "data/dataset.h"
#include "data/patches.h"

namespace dejag::cli {
namespace {

struct GenerateArguments {
    std::string families = "all", testFamilies = "default", size = "256x256", out;
    int count = 0, truth = 128, workers = 2, sequenceLength = 1;
    double jitterSpread = 1.0;
    double closeUps = 0.0;
    std::string samplers = "point,bilinear,trilinear";
    uint64_t seed = 1;
    bool adaptive = false, listFamilies = false, json = false, quiet = false, jitterSpreadGiven = false;
    RuntimeOptions runtime;
    std::string killAt;  // testing: RANK:ITEMS
};

void runGenerate(const GenerateArguments& args) {
    applyRuntimeOptions(args.runtime);
    if (args.listFamilies) {
        const auto& tests = data::defaultTestFamilies();
        for (const data::FamilyInfo& f : data::datasetFamilies())
            std::printf("%-13s %-5s %s\n", f.name.c_str(),
                        std::find(tests.begin(), tests.end(), f.name) != tests.end() ? "test" : "",
                        f.description.c_str());
        return;
    }
    if (args.out.empty()) throw Error("--out is required");
    data::DatasetSpec spec;
    if (args.families == "all")
        for (const data::FamilyInfo& f : data::datasetFamilies()) spec.families.push_back(f.name);
    else
        spec.families = splitList(args.families);
    if (args.testFamilies == "default") {
        for (const std::string& f : data::defaultTestFamilies())
            if (std::find(spec.families.begin(), spec.families.end(), f) != spec.families.end())
                spec.testFamilies.push_back(f);
    } else if (args.testFamilies != "none") {
        spec.testFamilies = splitList(args.testFamilies);
    }
    spec.count = args.count;
    const Size size = parseSize(args.size, "--size");
    spec.width = size.width, spec.height = size.height;
    spec.truthSamples = args.truth;
    spec.adaptive = args.adaptive;
    spec.seed = args.seed;
    spec.sequenceLength = args.sequenceLength;
    spec.jitterSpread = args.jitterSpread;
    spec.closeUps = args.closeUps;
    spec.samplers = splitList(args.samplers);
    if (args.jitterSpreadGiven && !spec.sequences())
        throw Error("--jitter-spread jitters sequences only (give --sequence-length 2 or more)");
    data::GenerateOptions options;
    options.workers = args.workers;
    options.quiet = args.quiet || args.json;
    options.workerCommand = {"/proc/self/exe", "data", "worker"};
    if (!args.killAt.empty()) {
        const size_t colon = args.killAt.find(':');
        try {
            if (colon == std::string::npos) throw std::invalid_argument("no colon");
            options.killRank = std::stoi(args.killAt.substr(0, colon));
            options.killAfterItems = std::stoi(args.killAt.substr(colon + 1));
        } catch (const std::exception&) {
            throw Error("--kill-rank-at: '" + args.killAt + "' is not RANK:ITEMS");
        }
    }
    const data::GenerateResult result = data::generateDataset(spec, args.out, options);
    if (args.json) {
        std::printf("%s\n", nlohmann::json{{"folder", args.out},
                                           {"rendered", result.rendered},
                                           {"skipped", result.skipped},
                                           {"seconds", result.seconds},
                                           {"dataset", spec.toJson()}}
                                .dump()
                                .c_str());
    } else if (!args.quiet) {
        std::printf("%s: %d items rendered, %d already complete, %.1f s\n", args.out.c_str(), result.rendered,
                    result.skipped, result.seconds);
    }
}

}  // namespace

void registerDataCommand(CLI::App& app) {
    CLI::App* data =
        app.add_subcommand("data", "datasets: generate aliased/truth pairs, verify them, print statistics");
    data->require_subcommand(1);

    auto args = std::make_shared<GenerateArguments>();
    CLI::App* generate = data->add_subcommand(
        "generate",
        "render a dataset: aliased frames + buffers and their accumulated truth, with a manifest");
    generate->add_option("--families", args->families, "comma-separated families, or all (--list-families)")
        ->capture_default_str();
    generate
        ->add_option("--test-families", args->testFamilies,
                     "families held out for the test split: default (architecture, foliage), none, or a list")
        ->capture_default_str();
    generate->add_option("--count", args->count, "number of items");
    generate->add_option("--size", args->size, "size of every item, WIDTHxHEIGHT")->capture_default_str();
    generate->add_option("--truth", args->truth, "samples accumulated for the truth")->capture_default_str();
    generate->add_flag("--adaptive", args->adaptive, "adaptive truth (stop converged tiles early)");
    generate->add_option("--out", args->out, "dataset folder (created; re-running resumes it)");
    generate->add_option("--workers", args->workers, "worker processes, one OpenGL context each")
        ->capture_default_str();
    generate->add_option("--seed", args->seed, "dataset seed")->capture_default_str();
    generate
        ->add_option("--sequence-length", args->sequenceLength,
                     "frames per item: 2 or more makes sequences of a moving camera, jittered, each frame "
                     "with its own truth")
        ->capture_default_str();
    generate->add_option_function<double>(
        "--jitter-spread",
        [args](double spread) { args->jitterSpread = spread, args->jitterSpreadGiven = true; },
        "sequences: Halton jitter spread in pixels (1: within the pixel, the truth's box) [1]");
    generate
        ->add_option(
            "--close-ups", args->closeUps,
            "share of items framed as close-ups: the view narrowed 1.5-4.5x at a random point of it, "
            "as a crop of a full-HD frame sees it")
        ->capture_default_str();
    generate
        ->add_option("--samplers", args->samplers,
                     "texture samplers drawn per item for textured scenes: point, bilinear, trilinear, "
                     "fourier, aniso16 (a minute per truth)")
        ->capture_default_str();
    generate->add_flag("--list-families", args->listFamilies, "print the families and exit");
    generate
        ->add_option("--kill-rank-at", args->killAt,
                     "testing: RANK:ITEMS, the process of that rank kills itself (SIGKILL) once it has "
                     "recorded that many items")
        ->group("");
    generate->add_flag("--json", args->json, "print a JSON summary");
    generate->add_flag("--quiet", args->quiet, "no progress bar or summary");
    addRuntimeOptions(generate, args->runtime);
    generate->footer(
        "Writes DIR/dataset.json, DIR/manifest.jsonl (one JSON record per complete item: id, family, scene,\n"
        "seed, split, camera, sample counts, size, checksums) and DIR/items/FAMILY/ID_input.exr (R G B,\n"
        "albedo, depth, motion, id of the aliased frame) + ID_truth.exr. Test split: whole families held "
        "out;\n"
        "validation: a tenth of the other items by seed. Interrupted? Run the same command again.\n"
        "With --sequence-length K: DIR/items/FAMILY/ID/frame_NNNN.exr (+ prevdepth), truth_NNNN.exr and\n"
        "render.json (jitter, cuts, cameras), a folder dejag filter reads as a sequence (docs/data.md).\n"
        "Several processes (mpirun -np N dejag-mpi data generate ...): each renders every N-th missing "
        "item;\n"
        "the dataset equals one process's. docs/mpi.md.");
    generate->callback([args] { runGenerate(*args); });

    auto folder = std::make_shared<std::string>();
    auto json = std::make_shared<bool>(false);
    // The worker processes of `data generate` (internal; see data::GenerateOptions::workerCommand).
    auto workerFolder = std::make_shared<std::string>();
    auto workerItems = std::make_shared<std::string>();
    auto workerFd = std::make_shared<int>(-1);
    CLI::App* worker = data->add_subcommand("worker", "internal: one worker process of data generate");
    worker->group("");
    worker->add_option("--folder", *workerFolder)->required();
    worker->add_option("--items", *workerItems)->required();
    worker->add_option("--result-fd", *workerFd)->required();
    worker->callback([workerFolder, workerItems, workerFd] {
        std::vector<int> items;
        for (const std::string& item : splitList(*workerItems)) items.push_back(std::stoi(item));
        data::runDatasetWorker(*workerFolder, items, *workerFd);
    });

    CLI::App* verify =
        data->add_subcommand("verify", "check a dataset: checksums, missing or extra files, sizes");
    verify->add_option("folder", *folder, "dataset folder")->required();
    verify->add_flag("--json", *json, "print the report as JSON");
    verify->callback([folder, json] {
        const data::VerifyReport report = data::verifyDataset(*folder);
        if (*json)
            std::printf(
                "%s\n",
                nlohmann::json{{"items", report.items}, {"problems", report.problems}, {"ok", report.ok()}}
                    .dump()
                    .c_str());
        else
            for (const std::string& p : report.problems) std::printf("%s\n", p.c_str());
        if (!report.ok())
            throw Error(std::to_string(report.problems.size()) + " problem(s) in '" + *folder +
                        "': " + report.problems.front());
        if (!*json)
            std::printf("%s: %d items, all files present and intact\n", folder->c_str(), report.items);
    });

    auto statsFolder = std::make_shared<std::string>();
    auto statsJson = std::make_shared<bool>(false);
    auto statsSampler = std::make_shared<bool>(false);
    auto statsPatch = std::make_shared<int>(96);
    CLI::App* stats =
        data->add_subcommand("stats", "items per family and split, edge pixels, aliased-vs-truth PSNR");
    stats->add_option("folder", *statsFolder, "dataset folder")->required();
    stats->add_flag("--json", *statsJson, "print JSON");
    stats->add_flag(
        "--sampler", *statsSampler,
        "also measure the patch sampler's aliasing bias on the train split (loads it into memory)");
    stats->add_option("--patch", *statsPatch, "patch size for --sampler")->capture_default_str();
    stats->callback([statsFolder, statsJson, statsSampler, statsPatch] {
        nlohmann::json s = data::datasetStats(*statsFolder);
        if (*statsSampler) {
            // Fraction of aliasing-source pixels in sampled patches: the default bias vs uniform crops.
            data::PatchOptions options;
            options.patchSize = *statsPatch;
            double fractions[2] = {0, 0};
            for (int uniform = 0; uniform < 2; ++uniform) {
                if (uniform) options.uniformFraction = 1.0;
                data::PatchSampler sampler(*statsFolder, options);
                for (uint64_t i = 0; i < 50; ++i) fractions[uniform] += sampler.assemble(i).edgeFraction / 50;
            }
            s["patch_sampler"] = {{"patch", *statsPatch},
                                  {"uniform_fraction", data::PatchOptions().uniformFraction},
                                  {"aliasing_pixels_biased", fractions[0]},
                                  {"aliasing_pixels_uniform", fractions[1]}};
        }
        if (*statsJson) {
            std::printf("%s\n", s.dump().c_str());
            return;
        }
        std::printf("%-13s %6s %6s %6s %6s %7s   aliased PSNR dB: min / median / max\n", "family", "items",
                    "train", "val", "test", "edges");
        for (const auto& [family, f] : s["families"].items()) {
            const nlohmann::json& splits = f["splits"];
            auto count = [&](const char* split) { return splits.value(split, 0); };
            std::printf("%-13s %6d %6d %6d %6d %6.1f%%   %.2f / %.2f / %.2f\n", family.c_str(),
                        f["items"].get<int>(), count("train"), count("validation"), count("test"),
                        100 * f["edge_fraction"].get<double>(), f["aliased_psnr"]["min"].get<double>(),
                        f["aliased_psnr"]["median"].get<double>(), f["aliased_psnr"]["max"].get<double>());
        }
        std::printf("%d items; aliased PSNR median %.2f dB\n", s["items"].get<int>(),
                    s["aliased_psnr"]["median"].get<double>());
        if (const nlohmann::json& samplers = s["samplers"]; !samplers.empty()) {
            std::string list;
            for (const auto& [name, n] : samplers.items())
                list += (list.empty() ? "" : ", ") + name + " " + std::to_string(n.get<int>());
            std::printf("textured items by sampler: %s\n", list.c_str());
        }
        if (s.contains("motion")) {
            std::printf("\n%-13s %9s %10s %10s %9s %11s %5s\n", "sequences", "count", "px/frame", "max px",
                        "moving", "disoccluded", "cuts");
            auto line = [](const std::string& name, const nlohmann::json& m) {
                std::printf("%-13s %9d %10.2f %10.2f %8.1f%% %10.1f%% %5d\n", name.c_str(),
                            m["sequences"].get<int>(), m["mean_speed"].get<double>(),
                            m["max_speed"].get<double>(), 100 * m["moving_fraction"].get<double>(),
                            100 * m["disoccluded_fraction"].get<double>(), m["cuts"].get<int>());
            };
            for (const auto& [family, f] : s["families"].items())
                if (f.contains("motion")) line(family, f["motion"]);
            line("all", s["motion"]);
            std::string moves;
            for (const auto& [kind, n] : s["motion"]["moves"].items())
                moves += (moves.empty() ? "" : ", ") + kind + " " + std::to_string(n.get<int>());
            std::printf("camera moves: %s\n", moves.c_str());
        }
        if (const nlohmann::json& flat = s["flat_items"]; !flat.empty()) {
            std::string list;
            for (size_t i = 0; i < flat.size() && i < 10; ++i)
                list += std::string(i ? ", " : "") + flat[i]["id"].get<std::string>() + " (" +
                        flat[i]["family"].get<std::string>() + ", " + flat[i]["split"].get<std::string>() +
                        ")";
            if (flat.size() > 10) list += ", ...";
            std::printf(
                "%zu item%s with nothing to anti-alias (aliased frame %.0f dB or more against its truth): "
                "%s\n",
                flat.size(), flat.size() == 1 ? "" : "s", data::kFlatItemPsnr, list.c_str());
        }
        if (s.contains("patch_sampler"))
            std::printf(
                "patch sampler (%d px): %.1f %% aliasing pixels per patch, %.1f %% with uniform crops\n",
                *statsPatch, 100 * s["patch_sampler"]["aliasing_pixels_biased"].get<double>(),
                100 * s["patch_sampler"]["aliasing_pixels_uniform"].get<double>());
    });
}

}  // namespace dejag::cli

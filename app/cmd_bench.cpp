// dejag bench TARGET: benchmarks that print figures next to the machine's measured peak.
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>

#include "app/cli.h"
#include "app/commands.h"
#include "base/error.h"
#include "base/files.h"
#include "base/thread_pool.h"
#include "bench/accuracy.h"
#include "bench/bench.h"
#include "bench/collective_bench.h"
#include "bench/filter_bench.h"
#include "bench/glsl_bench.h"
#include "bench/quality.h"
#include "bench/reach.h"
#include "bench/render_bench.h"
#include "bench/stability.h"
#include "bench/taa_bench.h"
#include "bench/texture_bench.h"
#include "data/plot.h"
#include "infer/filter.h"
#include "nn/model.h"
#include "render/scene.h"

namespace dejag::cli {
namespace {

std::vector<int> parseThreadList(const std::string& text) {
    std::vector<int> threads;
    std::stringstream stream(text);
    std::string item;
    while (std::getline(stream, item, ',')) {
        try {
            size_t used = 0;
            int value = std::stoi(item, &used);
            if (used != item.size() || value < 1 || value > 1024) throw std::invalid_argument(item);
            threads.push_back(value);
        } catch (const std::exception&) {
            throw Error("--thread-counts '" + text +
                        "' is not a comma-separated list of thread counts (e.g. 1,2)");
        }
    }
    if (threads.empty()) throw Error("--thread-counts is empty");
    return threads;
}

// A bench that sweeps thread counts: --thread-counts LIST (the sweep, 1,2 by default) or --threads N (one
// count, as everywhere else).
struct ThreadSweep {
    std::string counts = "1,2";
    int threads = 0;
    CLI::Option* countsOption = nullptr;
    void add(CLI::App* command) {
        countsOption =
            command->add_option("--thread-counts", counts, "the thread counts swept, comma-separated")
                ->capture_default_str();
        command->add_option("--threads", threads, "one thread count instead of the sweep")
            ->check(CLI::Range(1, 1024));
    }
    std::vector<int> resolve() const {
        if (threads > 0 && countsOption->count() > 0)
            throw Error("give --threads or --thread-counts, not both");
        return threads > 0 ? std::vector<int>{threads} : parseThreadList(counts);
    }
};

struct BenchArguments {
    std::string size = "1920x1080";
    int repeat = 15;
    ThreadSweep sweep;
    bool json = false;
    RuntimeOptions runtime;
};

void printRows(const std::vector<bench::Row>& rows, bool json) {
    if (json) {
        for (const bench::Row& row : rows) {
            nlohmann::json out = {{"name", row.name},
                                  {"threads", row.threads},
                                  {"simd", row.simd},
                                  {"ms", row.ms},
                                  {"gmacs", row.gmacs},
                                  {"peak_gmacs", row.peakGmacs},
                                  {"peak_fraction", row.peakFraction}};
            if (row.targetMs > 0) {
                out["target_ms"] = row.targetMs;
                out["target_met"] = row.ms <= row.targetMs;
            }
            std::printf("%s\n", out.dump().c_str());
        }
        return;
    }
    std::printf("%-44s %7s %7s %10s %9s %11s %7s  %s\n", "case", "threads", "simd", "median ms", "GMAC/s",
                "peak GMAC/s", "% peak", "target");
    for (const bench::Row& row : rows) {
        std::string target = "-";
        if (row.targetMs > 0)
            target = "<= " + std::to_string(int(row.targetMs)) +
                     " ms: " + (row.ms <= row.targetMs ? "met" : "NOT met");
        std::printf("%-44s %7d %7s %10.2f %9.2f %11.2f %6.1f%%  %s\n", row.name.c_str(), row.threads,
                    row.simd.c_str(), row.ms, row.gmacs, row.peakGmacs, 100.0 * row.peakFraction,
                    target.c_str());
    }
}

}  // namespace

// `dejag bench nn` runs dejag-bench-nn, built next to this binary: the peers (oneDNN, libtorch) are
// linked only there, so they never load with dejag itself.
[[noreturn]] void runNnBenchmark(const std::vector<std::string>& arguments) {
    std::error_code ec;
    const std::filesystem::path self = std::filesystem::read_symlink("/proc/self/exe", ec);
    const std::filesystem::path tool = self.parent_path() / "dejag-bench-nn";
    if (ec || !std::filesystem::exists(tool))
        throw Error("'" + tool.string() + "' is missing: build it with 'make bench'");
    std::vector<std::string> argv = {tool.string()};
    argv.insert(argv.end(), arguments.begin(), arguments.end());
    std::vector<char*> pointers;
    for (std::string& a : argv) pointers.push_back(a.data());
    pointers.push_back(nullptr);
    std::fflush(stdout);
    // The peers' OpenMP threads must sleep when idle, not spin: a spinning thread would steal the other
    // core from dejag's next measurement and from the FMA peak burst. (libgomp reads this at load time.)
    ::setenv("OMP_WAIT_POLICY", "PASSIVE", 0);
    ::execv(tool.c_str(), pointers.data());
    throw Error("cannot run '" + tool.string() + "': " + std::strerror(errno));
}

void registerBenchCommand(CLI::App& app) {
    CLI::App* bench =
        app.add_subcommand("bench", "benchmarks: median times, throughput and the measured peak");
    bench->require_subcommand(1);

    CLI::App* nn = bench->add_subcommand(
        "nn", "nn kernels vs oneDNN and libtorch side by side (runs dejag-bench-nn; dejag bench nn --help)");
    nn->prefix_command();  // everything after 'nn' goes to dejag-bench-nn
    nn->set_help_flag();
    nn->callback([nn] { runNnBenchmark(nn->remaining()); });

    struct RenderBenchArguments {
        int repeat = 5;
        std::string cases = "frames,truth,samplers", textures = "checker,stripes,text",
                    samplerSize = "512x512";
        bool json = false, quick = false;
    };
    auto renderArgs = std::make_shared<RenderBenchArguments>();
    CLI::App* renderBench = bench->add_subcommand(
        "render",
        "renderer: ms per frame (colour only, every buffer) at 800x800 and 1920x1080, the 128-sample truth "
        "with and without --adaptive, and the texture samplers' cost beside their aliasing");
    renderBench->add_option("--repeat", renderArgs->repeat, "timed frames per case (median reported)")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    renderBench->add_option("--cases", renderArgs->cases, "which cases: frames, truth, samplers (a list)")
        ->capture_default_str();
    renderBench
        ->add_option("--textures", renderArgs->textures,
                     "the samplers' textures: checker, bricks, stripes, text, noise (a list)")
        ->capture_default_str();
    renderBench->add_option("--sampler-size", renderArgs->samplerSize, "the samplers' frame size, WxH")
        ->capture_default_str();
    renderBench->add_flag("--quick", renderArgs->quick, "small sizes and one scene (a smoke test)");
    renderBench->add_flag("--json", renderArgs->json, "one JSON object per case");
    renderBench->callback([renderArgs] {
        bench::RenderBenchOptions options;
        options.repeat = renderArgs->repeat;
        options.samplerTextures = splitList(renderArgs->textures);
        for (const std::string& texture : options.samplerTextures)
            render::makeTexture(texture, 64, 1);  // checks the name
        const Size samplerSize = parseSize(renderArgs->samplerSize, "--sampler-size");
        options.samplerSize = {samplerSize.width, samplerSize.height};
        const std::vector<std::string> cases = splitList(renderArgs->cases);
        for (const std::string& c : cases)
            if (c != "frames" && c != "truth" && c != "samplers")
                throw Error("--cases takes frames, truth and samplers, not '" + c + "'");
        const auto wanted = [&](const char* name) {
            return std::find(cases.begin(), cases.end(), name) != cases.end();
        };
        if (renderArgs->quick) {
            options.scenes = {"pipe"}, options.sizes = {{96, 64}}, options.truthScenes = {"pipe"};
            options.truthSize = {96, 64}, options.truthSamples = 16;
            options.samplerTextures = {"checker"}, options.samplerSize = {128, 128},
            options.samplerTruthSamples = 16;
        }
        if (!wanted("frames")) options.scenes.clear();
        if (!wanted("truth")) options.truthScenes.clear();
        if (!wanted("samplers")) options.samplerTextures.clear();
        const std::vector<nlohmann::json> rows = bench::benchRender(options);
        if (renderArgs->json) {
            for (const nlohmann::json& row : rows) std::printf("%s\n", row.dump().c_str());
            return;
        }
        std::printf("%-26s %-13s %9s %10s\n", "case", "scene", "size", "median ms");
        for (const nlohmann::json& row : rows) {
            const std::string size =
                std::to_string(row["width"].get<int>()) + "x" + std::to_string(row["height"].get<int>());
            std::printf("%-26s %-13s %9s %10.1f", row["name"].get<std::string>().c_str(),
                        row["scene"].get<std::string>().c_str(), size.c_str(), row["ms"].get<double>());
            if (row.contains("adaptive_ms"))
                std::printf(
                    "  adaptive %.1f ms, %.2fx fewer tile-samples, aliased PSNR %.3f vs %.3f dB (%+.3f)",
                    row["adaptive_ms"].get<double>(), row["tile_samples_saving"].get<double>(),
                    row["aliased_psnr_adaptive_truth"].get<double>(),
                    row["aliased_psnr_full_truth"].get<double>(), row["psnr_difference_db"].get<double>());
            if (row.contains("aliasing"))
                std::printf("  %s: aliasing %.4f (%.1f dB), detail kept %.3f, PSNR %.2f dB, setup %.0f ms",
                            row["texture"].get<std::string>().c_str(), row["aliasing"].get<double>(),
                            row["aliasing_db"].get<double>(), row["detail_kept"].get<double>(),
                            row["psnr"].get<double>(), row["setup_ms"].get<double>());
            std::printf("\n");
        }
        std::printf("OSMesa llvmpipe renders with its own threads (LP_NUM_THREADS, default: all cores).\n");
    });

    struct FilterBenchArguments {
        int repeat = 15;
        std::string size = "1920x1080";
        ThreadSweep sweep;
        std::string temporalModel = "models/dejag-temporal.safetensors";
        std::string fastModel = "models/dejag-fast.safetensors,models/dejag-guided.safetensors";
        bool json = false;
    };
    auto filterArgs = std::make_shared<FilterBenchArguments>();
    CLI::App* filterBench = bench->add_subcommand("filter",
                                                  "every post-process method on a rendered frame: median ms "
                                                  "at 1920x1080 per thread count, beside its memory floor");
    filterBench->add_option("--repeat", filterArgs->repeat, "timed runs per case (median reported)")
        ->check(CLI::Range(1, 10000))
        ->capture_default_str();
    filterArgs->sweep.add(filterBench);
    filterBench->add_option("--size", filterArgs->size, "frame size WIDTHxHEIGHT")->capture_default_str();
    filterBench
        ->add_option("--temporal-model", filterArgs->temporalModel,
                     "the temporal network timed as dejag-temporal ('' or a missing default: not timed)")
        ->capture_default_str();
    filterBench
        ->add_option("--models", filterArgs->fastModel,
                     "single-frame networks timed, comma-separated files or shipped names, each named by its "
                     "file's stem ('' or a missing default: none)")
        ->capture_default_str();
    filterBench->add_flag("--json", filterArgs->json, "one JSON object per case");
    filterBench->callback([filterArgs, filterBench] {
        bench::FilterBenchOptions options;
        const Size size = parseSize(filterArgs->size, "--size");
        options.width = size.width, options.height = size.height;
        options.repeat = filterArgs->repeat;
        options.threads = filterArgs->sweep.resolve();
        options.temporalModel = shippedModelPath(filterArgs->temporalModel);
        if (!options.temporalModel.empty() && !std::filesystem::exists(options.temporalModel)) {
            if (filterBench->count("--temporal-model"))
                throw Error("--temporal-model: no model file " + options.temporalModel);
            options.temporalModel.clear();  // the shipped model is timed when it is there
        }
        for (const std::string& model : shippedModelPaths(splitList(filterArgs->fastModel))) {
            if (std::filesystem::exists(model))
                options.frameModels.push_back(model);
            else if (filterBench->count("--models"))
                throw Error("--models: no model file " + model);  // a missing default is skipped
        }
        const std::vector<nlohmann::json> rows = bench::benchFilters(options);
        if (filterArgs->json) {
            for (const nlohmann::json& row : rows) std::printf("%s\n", row.dump().c_str());
            return;
        }
        std::printf("%-34s %3s %10s %8s %9s %10s  %s\n", "case", "thr", "median ms", "target", "floor ms",
                    "processed", "PSNR vs 64-sample truth");
        for (const nlohmann::json& row : rows) {
            std::printf("%-34s %3d %10.2f %8.1f %9.2f %9.1f%%", row["name"].get<std::string>().c_str(),
                        row["threads"].get<int>(), row["ms"].get<double>(), row["target_ms"].get<double>(),
                        row["floor_ms"].get<double>(), 100 * row["processed_fraction"].get<double>());
            if (row.contains("psnr_after"))
                std::printf("  %.2f -> %.2f dB", row["psnr_before"].get<double>(),
                            row["psnr_after"].get<double>());
            if (row.contains("peak_gmacs"))
                std::printf("  %.0f MACs/px; %.1f of the measured FMA peak's %.1f GMAC/s",
                            row["macs_per_pixel"].get<double>(),
                            row["macs_per_pixel"].get<double>() * row["width"].get<double>() *
                                row["height"].get<double>() / (row["ms"].get<double>() * 1e6),
                            row["peak_gmacs"].get<double>());
            std::printf("\n");
        }
        std::printf(
            "frame: hard-edges, %s, sRGB-encoded float RGB; floor: the bytes each method must move "
            "at least, at the memory bandwidth measured in this run (a network: its multiply-adds at the FMA "
            "peak measured in this run)\n",
            filterArgs->size.c_str());
    });

    struct GlslBenchArguments {
        int repeat = 5;
        std::string size = "960x540", methods;
        bool json = false;
    };
    auto glslArgs = std::make_shared<GlslBenchArguments>();
    CLI::App* glslBench = bench->add_subcommand(
        "glsl",
        "every method's GPU form (GLSL, off screen) beside its CPU filter on the same rendered frames");
    glslBench->add_option("--repeat", glslArgs->repeat, "timed frames per method (median reported)")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    glslBench->add_option("--size", glslArgs->size, "frame size WIDTHxHEIGHT")->capture_default_str();
    glslBench->add_option("--methods", glslArgs->methods, "comma-separated methods (default: every one)");
    glslBench->add_flag("--json", glslArgs->json, "one JSON object per method");
    glslBench->callback([glslArgs] {
        bench::GlslBenchOptions options;
        const Size size = parseSize(glslArgs->size, "--size");
        options.width = size.width, options.height = size.height;
        options.repeat = glslArgs->repeat;
        if (!glslArgs->methods.empty()) options.methods = splitList(glslArgs->methods);
        options.pathResolver = shippedModelPath;
        const std::vector<nlohmann::json> rows = bench::benchGlsl(options);
        if (glslArgs->json) {
            for (const nlohmann::json& row : rows) std::printf("%s\n", row.dump().c_str());
            return;
        }
        std::printf("%-13s %10s %10s %8s  %s\n", "method", "GPU ms", "CPU ms", "GPU/CPU",
                    "slowest GPU passes");
        for (const nlohmann::json& row : rows) {
            std::vector<std::pair<double, std::string>> passes;
            for (const nlohmann::json& p : row["passes"])
                passes.push_back({p["ms"].get<double>(), p["name"].get<std::string>()});
            std::sort(passes.rbegin(), passes.rend());
            std::string slowest;
            for (size_t i = 0; i < std::min<size_t>(3, passes.size()); ++i) {
                char text[96];
                std::snprintf(text, sizeof text, "%s%s %.1f", i ? ", " : "", passes[i].second.c_str(),
                              passes[i].first);
                slowest += text;
            }
            std::printf("%-13s %10.2f %10.2f %8.1f  %s\n", row["method"].get<std::string>().c_str(),
                        row["gpu_ms"].get<double>(), row["cpu_ms"].get<double>(),
                        row["gpu_over_cpu"].get<double>(), slowest.c_str());
        }
        if (!rows.empty())
            std::printf(
                "frames: hard-edges %s along its camera path, every buffer, Halton jitter; OpenGL: %s%s; the "
                "CPU "
                "filters with their defaults (gated, bf16 where the CPU has it), on %d threads\n",
                glslArgs->size.c_str(), rows[0]["opengl"].get<std::string>().c_str(),
                rows[0]["emulated"].get<bool>() ? " (emulated on the CPU: its times are CPU times)" : "",
                threadCount());
    });

    struct CollectiveArguments {
        int repeat = 20;
        std::vector<int64_t> floats = bench::CollectiveBenchOptions().floats;
        std::vector<int> ranks = bench::CollectiveBenchOptions().ranks;
        std::string model;
        double stepSeconds = 0, latencyUs = 0, gbPerS = 0;
        bool json = false;
    };
    auto collectiveArgs = std::make_shared<CollectiveArguments>();
    CLI::App* collective = bench->add_subcommand(
        "collective",
        "what sharing training between processes costs (run under mpirun with dejag-mpi): the ordered "
        "gradient sum beside MPI's all-reduce, and the scaling efficiency it implies at more ranks");
    collective->add_option("--repeat", collectiveArgs->repeat, "timed calls per size (median reported)")
        ->check(CLI::Range(1, 10000))
        ->capture_default_str();
    collective->add_option("--floats", collectiveArgs->floats, "values each rank sends, one size per value")
        ->delimiter(',')
        ->check(CLI::Range(int64_t(1), int64_t(1) << 28));
    collective->add_option("--model", collectiveArgs->model,
                           "a model file or shipped name: its gradient size for the efficiency model");
    collective
        ->add_option("--step-seconds", collectiveArgs->stepSeconds,
                     "one process's time for a training step of the global batch (run.json: seconds / steps)")
        ->check(CLI::Range(0.0, 1e6));
    collective->add_option("--ranks", collectiveArgs->ranks, "rank counts of the efficiency model")
        ->delimiter(',')
        ->check(CLI::Range(2, 1 << 20));
    collective
        ->add_option("--network-latency-us", collectiveArgs->latencyUs,
                     "model a cluster's network: its latency per message (with --network-gb-per-s)")
        ->check(CLI::Range(0.0, 1e6));
    collective
        ->add_option("--network-gb-per-s", collectiveArgs->gbPerS, "model a cluster's network: its bandwidth")
        ->check(CLI::Range(0.0, 1e6));
    collective->add_flag("--json", collectiveArgs->json, "the result as one JSON object");
    collective->callback([collectiveArgs] {
        bench::CollectiveBenchOptions options;
        options.repeat = collectiveArgs->repeat, options.floats = collectiveArgs->floats;
        options.ranks = collectiveArgs->ranks, options.stepSeconds = collectiveArgs->stepSeconds;
        options.networkLatencyUs = collectiveArgs->latencyUs, options.networkGbPerS = collectiveArgs->gbPerS;
        if (!collectiveArgs->model.empty())
            options.parameters = nn::loadModel(shippedModelPath(collectiveArgs->model)).parameterCount();
        const nlohmann::json r = bench::benchCollective(options);
        if (collectiveArgs->json) {
            std::printf("%s\n", r.dump().c_str());
            return;
        }
        if (r["ranks"].get<int>() < 2) {
            std::printf(
                "one process: nothing to measure; run it as mpirun -np N dejag-mpi bench collective\n");
            return;
        }
        std::printf("%d ranks; medians of the slowest rank\n%12s %15s %14s\n", r["ranks"].get<int>(),
                    "floats/rank", "ordered sum ms", "all-reduce ms");
        for (const nlohmann::json& row : r["sizes"])
            std::printf("%12lld %15.4f %14.4f\n", (long long)row["floats"].get<int64_t>(),
                        row["ordered_ms"].get<double>(), row["allreduce_ms"].get<double>());
        const nlohmann::json& fit = r["fit"];
        std::printf(
            "fit: ordered sum %.2f us a step + %.2f GB/s, all-reduce %.2f us a step + %.2f GB/s (the "
            "ordered sum takes N-1+log2 N steps, an all-reduce 2 log2 N; both move 2 (N-1)/N 4P "
            "bytes)\n",
            fit["ordered"]["latency_us"].get<double>(), fit["ordered"]["gb_per_s"].get<double>(),
            fit["allreduce"]["latency_us"].get<double>(), fit["allreduce"]["gb_per_s"].get<double>());
        if (!r.contains("model")) return;
        std::printf(
            "model: %lld parameters, %.3f s a step on one process (strong scaling: the batch shared), %s\n",
            (long long)r["parameters"].get<int64_t>(), r["step_seconds"].get<double>(),
            r.contains("network") ? "the given network" : "the fit above");
        std::printf("%6s %11s %15s %14s %11s %16s\n", "ranks", "compute ms", "ordered sum ms",
                    "all-reduce ms", "efficiency", "with all-reduce");
        for (const nlohmann::json& m : r["model"])
            std::printf("%6d %11.2f %15.3f %14.3f %10.1f%% %15.1f%%\n", m["ranks"].get<int>(),
                        m["compute_ms"].get<double>(), m["ordered_ms"].get<double>(),
                        m["allreduce_ms"].get<double>(), 100 * m["efficiency_ordered"].get<double>(),
                        100 * m["efficiency_allreduce"].get<double>());
    });

    struct StabilityArguments {
        int configurations = 1000;
        uint64_t seed = 1;
        bool json = false;
        std::string model = "models/dejag-fast.safetensors", frame = "3840x2160", denormalFrame = "1920x1080";
        int repeat = 7, trainingSteps = 20;
        bool noModel = false;
    };
    auto stabilityArgs = std::make_shared<StabilityArguments>();
    CLI::App* stability = bench->add_subcommand(
        "stability",
        "gradient checks in double of every nn layer and loss on random configurations, and float32 "
        "against double on the same cases (exit 1 if a check exceeds 1e-6)");
    stability
        ->add_option("--configs", stabilityArgs->configurations,
                     "random configurations, round-robin over the kinds")
        ->check(CLI::Range(1, 1000000))
        ->capture_default_str();
    stability->add_option("--seed", stabilityArgs->seed, "seed of the configurations")->capture_default_str();
    stability->add_flag("--json", stabilityArgs->json, "one JSON object per kind");
    stability->add_option("--model", stabilityArgs->model, "model for the accumulation and denormal figures")
        ->capture_default_str();
    stability
        ->add_option("--frame", stabilityArgs->frame,
                     "frame of the accumulation figure (float32 inference against double)")
        ->capture_default_str();
    stability->add_option("--denormal-frame", stabilityArgs->denormalFrame, "frame of the denormal figure")
        ->capture_default_str();
    stability->add_option("--repeat", stabilityArgs->repeat, "timed runs per denormal median")
        ->check(CLI::Range(1, 1000))
        ->capture_default_str();
    stability->add_option("--training-steps", stabilityArgs->trainingSteps, "Steps of the determinism check")
        ->check(CLI::Range(1, 100000))
        ->capture_default_str();
    stability->add_flag("--no-model", stabilityArgs->noModel, "layer and loss checks only");
    stability->callback([stabilityArgs] {
        bench::StabilityOptions options;
        options.configurations = stabilityArgs->configurations, options.seed = stabilityArgs->seed;
        const std::vector<bench::StabilityRow> rows = bench::benchStability(options);
        int failing = 0;
        for (const bench::StabilityRow& r : rows) failing += r.overTolerance;
        if (stabilityArgs->json) {
            for (const bench::StabilityRow& r : rows)
                std::printf("%s\n", nlohmann::json{{"kind", r.kind},
                                                   {"configurations", r.configurations},
                                                   {"coordinates", r.coordinates},
                                                   {"kinks_skipped", r.kinks},
                                                   {"worst_gradient_error", r.worstGradient},
                                                   {"median_gradient_error", r.medianGradient},
                                                   {"over_tolerance", r.overTolerance},
                                                   {"float32_vs_double", r.worstFloat}}
                                        .dump()
                                        .c_str());
        } else {
            std::printf("%-24s %7s %7s %6s %12s %12s %6s %14s\n", "kind", "configs", "coords", "kinks",
                        "worst grad", "median grad", "> tol", "f32 vs f64");
            for (const bench::StabilityRow& r : rows)
                std::printf("%-24s %7d %7d %6d %12.2e %12.2e %6d %14.2e\n", r.kind.c_str(), r.configurations,
                            r.coordinates, r.kinks, r.worstGradient, r.medianGradient, r.overTolerance,
                            r.worstFloat);
            std::printf(
                "gradient errors: double backward against central differences (relative, per "
                "coordinate; tolerance %.0e); f32 vs f64: normwise relative error of outputs and "
                "gradients\n",
                options.tolerance);
        }
        if (failing > 0)
            throw Error(std::to_string(failing) + " configurations exceed the gradient tolerance");

        const std::vector<bench::SsimDegenerateRow> degenerate = bench::ssimDegenerateChecks();
        if (!stabilityArgs->json)
            std::printf("\n1 - SSIM on degenerate patches (double): %-34s %10s %7s %12s %12s %12s %s\n",
                        "patch", "loss", "finite", "d/dt error", "slope h", "slope h/100", "");
        int degenerateFailing = 0;
        for (const bench::SsimDegenerateRow& r : degenerate) {
            degenerateFailing += r.passed ? 0 : 1;
            if (stabilityArgs->json)
                std::printf("%s\n", nlohmann::json{{"kind", "ssim degenerate: " + r.patch},
                                                   {"loss", r.loss},
                                                   {"finite", r.finite},
                                                   {"directional_derivative_error", r.directionalError},
                                                   {"slope", r.slope},
                                                   {"slope_fine", r.slopeFine},
                                                   {"passed", r.passed}}
                                        .dump()
                                        .c_str());
            else
                std::printf("  %-34s %10.3e %7s %12.2e %12.3e %12.3e %s\n", r.patch.c_str(), r.loss,
                            r.finite ? "yes" : "NO", r.directionalError, r.slope, r.slopeFine,
                            r.passed ? "ok" : "FAILED");
        }
        if (!stabilityArgs->json)
            std::printf(
                "d/dt error: derivative along a random direction, analytic against central difference; "
                "slopes: largest |dL|/dt over a sweep around the patch (a jump would grow it 100x at "
                "h/100)\n");
        if (degenerateFailing > 0)
            throw Error(std::to_string(degenerateFailing) + " degenerate SSIM patches fail their checks");
        if (stabilityArgs->noModel) return;

        // A whole network: accumulation error on a large frame, and what denormal inputs cost.
        constexpr double kAccumulationLimit = 1e-5, kDenormalLimit = 1.10;
        stabilityArgs->model = shippedModelPath(stabilityArgs->model);
        const Size frame = parseSize(stabilityArgs->frame, "--frame");
        const Size denormalFrame = parseSize(stabilityArgs->denormalFrame, "--denormal-frame");
        const bench::AccumulationResult a =
            bench::benchAccumulation(stabilityArgs->model, frame.width, frame.height);
        const bench::DenormalResult d = bench::benchDenormals(stabilityArgs->model, denormalFrame.width,
                                                              denormalFrame.height, stabilityArgs->repeat);
        const double ratio = d.denormalMs / d.normalMs,
                     ratioNoFlush = d.denormalMsNoFlush / d.normalMsNoFlush;
        if (stabilityArgs->json) {
            std::printf("%s\n", nlohmann::json{{"kind", "accumulation"},
                                               {"model", a.model},
                                               {"width", a.width},
                                               {"height", a.height},
                                               {"normwise_relative_error", a.normwise},
                                               {"largest_relative_error", a.largest},
                                               {"limit", kAccumulationLimit},
                                               {"float32_ms", a.floatMs},
                                               {"double_seconds", a.doubleSeconds}}
                                    .dump()
                                    .c_str());
            std::printf("%s\n", nlohmann::json{{"kind", "denormals"},
                                               {"model", a.model},
                                               {"width", d.width},
                                               {"height", d.height},
                                               {"threads", d.threads},
                                               {"normal_ms", d.normalMs},
                                               {"denormal_ms", d.denormalMs},
                                               {"ratio", ratio},
                                               {"limit", kDenormalLimit},
                                               {"no_flush_normal_ms", d.normalMsNoFlush},
                                               {"no_flush_denormal_ms", d.denormalMsNoFlush},
                                               {"no_flush_ratio", ratioNoFlush}}
                                    .dump()
                                    .c_str());
        } else {
            std::printf(
                "\naccumulation: %s float32 inference on a %dx%d frame against its forward in double: "
                "normwise relative error %.2e, largest %.2e (limit %.0e); float32 %.0f ms, double %.0f s\n",
                a.model.c_str(), a.width, a.height, a.normwise, a.largest, kAccumulationLimit, a.floatMs,
                a.doubleSeconds);
            std::printf(
                "denormals: %dx%d, %d threads, FTZ/DAZ on: %.1f ms normal, %.1f ms denormal input "
                "(x%.3f, limit x%.2f: %s); 1 thread, FTZ/DAZ off: %.1f ms against %.1f ms (x%.2f)\n",
                d.width, d.height, d.threads, d.normalMs, d.denormalMs, ratio, kDenormalLimit,
                ratio <= kDenormalLimit ? "met" : "NOT met", d.denormalMsNoFlush, d.normalMsNoFlush,
                ratioNoFlush);
        }
        const bench::DeterminismResult t = bench::benchDeterminism(
            stabilityArgs->model, stabilityArgs->trainingSteps, denormalFrame.width, denormalFrame.height);
        std::string threadList;
        for (int n : t.threadCounts) threadList += (threadList.empty() ? "" : ",") + std::to_string(n);
        if (stabilityArgs->json) {
            std::printf("%s\n", nlohmann::json{{"kind", "determinism"},
                                               {"training_steps", t.steps},
                                               {"threads", t.threadCounts},
                                               {"training_repeatable", t.trainingRepeatable},
                                               {"inference_repeatable", t.inferenceRepeatable},
                                               {"training_across_threads", t.trainingAcrossThreads},
                                               {"inference_across_threads", t.inferenceAcrossThreads}}
                                    .dump()
                                    .c_str());
        } else {
            std::printf(
                "determinism: threads %s; same seed and threads: %s weights after %d training steps, %s "
                "inference outputs; across thread counts: weights differ by %.2e, outputs by %.2e "
                "(largest, relative to the largest value)\n",
                threadList.c_str(), t.trainingRepeatable ? "identical" : "DIFFERENT", t.steps,
                t.inferenceRepeatable ? "identical" : "DIFFERENT", t.trainingAcrossThreads,
                t.inferenceAcrossThreads);
        }
        if (!t.trainingRepeatable || !t.inferenceRepeatable)
            throw Error("the same seed and thread count gave different results");
        if (!(a.normwise <= kAccumulationLimit))
            throw Error("accumulation error " + std::to_string(a.normwise) + " exceeds 1e-5");
    });

    struct TextureBenchArguments {
        std::string size = "384x384", cases = "checker,stripes,text,normal-map", out;
        std::string models = "models/dejag-fast.safetensors,models/dejag-guided.safetensors",
                    temporalModel = "models/dejag-temporal.safetensors";
        int truth = 256, frames = 16;
        double jitterSpread = 1.0;
        bool json = false, quick = false;
    };
    auto textureArgs = std::make_shared<TextureBenchArguments>();
    CLI::App* textureBench = bench->add_subcommand(
        "texture",
        "which tool fixes which aliasing: the texture samplers, super bump mapping, the post-process and the "
        "temporal methods on texture and shading scenes, cost against error, with the Pareto front");
    textureBench->add_option("--size", textureArgs->size, "frame size, WxH")->capture_default_str();
    textureBench
        ->add_option("--cases", textureArgs->cases,
                     "planes textures (checker, bricks, stripes, text, noise) and "
                     "normal-map, a list")
        ->capture_default_str();
    textureBench->add_option("--truth", textureArgs->truth, "the truth's samples a pixel")
        ->check(CLI::Range(1, 4096))
        ->capture_default_str();
    textureBench->add_option("--frames", textureArgs->frames, "the temporal methods' still history (frames)")
        ->check(CLI::Range(1, 256))
        ->capture_default_str();
    textureBench
        ->add_option("--jitter-spread", textureArgs->jitterSpread, "the frames' Halton jitter spread, pixels")
        ->check(CLI::Range(0.0, 4.0))
        ->capture_default_str();
    textureBench
        ->add_option("--models", textureArgs->models,
                     "single-frame networks, a list (the shipped ones are compared when present)")
        ->capture_default_str();
    textureBench->add_option("--temporal-model", textureArgs->temporalModel, "the temporal network")
        ->capture_default_str();
    textureBench->add_option("--out", textureArgs->out,
                             "folder for pareto-CASE.png, frequency-test.png (aliasing against detail) and "
                             "results.json");
    textureBench->add_flag("--json", textureArgs->json, "one JSON object per row");
    textureBench->add_flag(
        "--quick", textureArgs->quick,
        "a small smoke test: 96x96, 16 samples, 4 frames, checker and normal-map, no networks");
    textureBench->callback([textureBench, textureArgs] {
        bench::TextureBenchOptions options;
        const Size size = parseSize(textureArgs->size, "--size");
        options.width = size.width, options.height = size.height;
        options.truthSamples = textureArgs->truth, options.frames = textureArgs->frames;
        options.jitterSpread = textureArgs->jitterSpread;
        options.cases = splitList(textureArgs->cases);
        for (const std::string& c : options.cases)
            if (c != "normal-map") render::makeTexture(c, 64, 1);  // an unknown one: one line
        // A model named on the command line must be there; the shipped ones are compared when present.
        const auto present = [&](const std::string& given, const char* flag) {
            const std::string path = shippedModelPath(given);
            if (path.empty() || std::filesystem::exists(path)) return path;
            if (textureBench->count(flag) > 0) throw Error(std::string(flag) + ": no model file " + path);
            return std::string();
        };
        for (const std::string& model : splitList(textureArgs->models))
            if (const std::string path = present(model, "--models"); !path.empty())
                options.models.push_back(path);
        options.temporalModel = present(textureArgs->temporalModel, "--temporal-model");
        if (textureArgs->quick) {
            options.width = options.height = 96, options.truthSamples = 16, options.frames = 4;
            options.cases = {"checker", "normal-map"}, options.models.clear(), options.temporalModel.clear();
        }
        if (!textureArgs->out.empty()) std::filesystem::create_directories(textureArgs->out);
        options.quiet = textureArgs->json;
        const std::vector<nlohmann::json> rows = bench::benchTexture(options);
        if (!textureArgs->out.empty()) {
            for (const std::string& c : options.cases) {
                Plot plot;
                plot.title = "bench texture, " + c + ": cost against error";
                plot.xLabel = "ms a frame (render + method)", plot.yLabel = "PSNR dB against the truth";
                plot.logX = true, plot.legendOutside = true;
                for (const nlohmann::json& row : rows) {
                    if (row["case"] != c) continue;
                    PlotSeries point;
                    point.name = row["method"].get<std::string>() + (row["pareto"].get<bool>() ? " *" : "");
                    point.lines = false, point.markers = true, point.labels = true;
                    point.x.push_back(std::max(row["ms"].get<double>(), 0.01));
                    point.y.push_back(row["psnr"].get<double>());
                    point.pointLabels.push_back(row["method"].get<std::string>());
                    plot.series.push_back(point);
                }
                writePlotPng((std::filesystem::path(textureArgs->out) / ("pareto-" + c + ".png")).string(),
                             plot);
            }
            // The thesis' frequency-test shape: aliasing against detail kept, a series per tool that
            // works at the source, a point per case.
            Plot shape;
            shape.title = "bench texture: aliasing against detail kept (the tools at the source)";
            shape.xLabel = "detail kept (share of the truth's spectral energy)";
            shape.yLabel = "aliasing dB (lower is better)";
            shape.legendOutside = true;
            for (const nlohmann::json& row : rows) {
                if (row["family"] != "source") continue;
                const std::string method = row["method"].get<std::string>();
                auto series = std::find_if(shape.series.begin(), shape.series.end(),
                                           [&](const PlotSeries& p) { return p.name == method; });
                if (series == shape.series.end()) {
                    shape.series.push_back({});
                    series = shape.series.end() - 1;
                    series->name = method, series->lines = false, series->markers = true,
                    series->labels = true;
                }
                series->x.push_back(row["detail_kept"].get<double>());
                series->y.push_back(row["aliasing_db"].get<double>());
                series->pointLabels.push_back(row["case"].get<std::string>());
            }
            writePlotPng((std::filesystem::path(textureArgs->out) / "frequency-test.png").string(), shape);
            nlohmann::json all = rows;
            writeTextFileAtomically((std::filesystem::path(textureArgs->out) / "results.json").string(),
                                    all.dump(1) + "\n");
        }
        if (textureArgs->json) {
            for (const nlohmann::json& row : rows) std::printf("%s\n", row.dump().c_str());
            return;
        }
        std::printf(
            "%dx%d, truth %d samples a pixel; temporal methods after %d still jittered frames. * = on the "
            "Pareto front of its case (no row both cheaper and closer)\n",
            options.width, options.height, options.truthSamples, options.frames);
        std::string current;
        for (const nlohmann::json& row : rows) {
            if (row["case"] != current) {
                current = row["case"].get<std::string>();
                std::printf("\n%s\n  %-32s %-13s %9s %12s %7s %9s\n", current.c_str(), "method", "family",
                            "ms", "aliasing dB", "detail", "PSNR dB");
            }
            std::printf("%s %-32s %-13s %9.1f %12.1f %7.3f %9.2f\n", row["pareto"].get<bool>() ? " *" : "  ",
                        row["method"].get<std::string>().c_str(), row["family"].get<std::string>().c_str(),
                        row["ms"].get<double>(), row["aliasing_db"].get<double>(),
                        row["detail_kept"].get<double>(), row["psnr"].get<double>());
        }
        std::printf("\nOSMesa llvmpipe renders in software: render times are a CPU's, not a GPU's.\n");
    });

    struct TaaBenchArguments {
        std::string size = "800x450", ghostSize = "400x225", out;
        int truth = 128, frames = 64, ghostFrames = 100, ghostTruth = 32, movingFrames = 40;
        bool noGhosting = false, noMoving = false, json = false, noUnjitter = false;
        std::string truthSpace = "linear";
        std::vector<std::string> settings, temporalSettings, scenes, movingScenes;
        std::string temporalModel = "models/dejag-temporal.safetensors",
                    fastModel = "models/dejag-fast.safetensors";
        double jitterSpread = 1.7;
    };
    auto taaArgs = std::make_shared<TaaBenchArguments>();
    CLI::App* taaBench = bench->add_subcommand(
        "taa",
        "the thesis' comparison: static test (No AA, FXAA, U-TAA, T-TAA, taa-hq and the oracle vs truth), "
        "ghosting test and moving-camera test with flicker");
    taaBench->add_option("--size", taaArgs->size, "static test frame size")->capture_default_str();
    taaBench
        ->add_option("--frames", taaArgs->frames,
                     "static test: jittered frames before the scored one (the oracle averages the last 16)")
        ->check(CLI::Range(16, 100000))
        ->capture_default_str();
    taaBench->add_option("--truth", taaArgs->truth, "truth samples (static test)")->capture_default_str();
    taaBench->add_option("--ghost-size", taaArgs->ghostSize, "ghosting test frame size")
        ->capture_default_str();
    taaBench->add_option("--ghost-frames", taaArgs->ghostFrames, "ghosting test frames")
        ->capture_default_str();
    taaBench->add_option("--ghost-truth", taaArgs->ghostTruth, "truth samples per ghosting frame")
        ->capture_default_str();
    taaBench->add_flag("--no-ghosting", taaArgs->noGhosting, "no ghosting test");
    taaBench->add_flag("--no-moving", taaArgs->noMoving, "no moving-camera test");
    taaBench
        ->add_option("--moving-frames", taaArgs->movingFrames,
                     "frames of each moving-camera sequence (scored from frame 8, or half way if fewer)")
        ->check(CLI::Range(2, 100000))
        ->capture_default_str();
    taaBench
        ->add_option(
            "--moving-scenes", taaArgs->movingScenes,
            "the moving-camera test's scenes (dejag render --list; default pipe,atrium,flowers,hard-edges)")
        ->delimiter(',');
    taaBench->add_flag("--no-unjitter", taaArgs->noUnjitter,
                       "U-TAA and T-TAA use the jittered frame as it is (no unjitter)");
    taaBench
        ->add_option("--truth-space", taaArgs->truthSpace,
                     "linear: the truth averaged in linear light; display: as 8-bit sRGB values, like the "
                     "thesis' accumulation buffer")
        ->check(CLI::IsMember({"linear", "display"}))
        ->capture_default_str();
    taaBench->add_option("--set", taaArgs->settings,
                         "a parameter of taa-hq, NAME=VALUE (dejag filter --list-methods)");
    taaBench->add_option("--temporal-set", taaArgs->temporalSettings,
                         "a parameter of dejag-temporal's cnn-temporal, NAME=VALUE (e.g. gate=off)");
    taaBench
        ->add_option("--scenes", taaArgs->scenes,
                     "only these scenes (e.g. flowers, or 'pipe tilted'), in every test that has them")
        ->delimiter(',');
    taaBench
        ->add_option(
            "--temporal-model", taaArgs->temporalModel,
            "the temporal network compared as dejag-temporal ('' or a missing default: not compared)")
        ->capture_default_str();
    taaBench
        ->add_option(
            "--fast-model", taaArgs->fastModel,
            "the single-frame network compared as dejag-fast ('' or a missing default: not compared)")
        ->capture_default_str();
    taaBench
        ->add_option("--jitter-spread", taaArgs->jitterSpread,
                     "the spread of the frames' Halton jitter in pixels (1: within the pixel)")
        ->check(CLI::Range(0.0, 4.0))
        ->capture_default_str();
    taaBench->add_option("--out", taaArgs->out, "folder for the static test's SSIM-map PNGs");
    taaBench->add_flag("--json", taaArgs->json, "one JSON object per row");
    taaBench->callback([taaArgs, taaBench] {
        bench::TaaBenchOptions options;
        const Size size = parseSize(taaArgs->size, "--size"),
                   ghost = parseSize(taaArgs->ghostSize, "--ghost-size");
        options.width = size.width, options.height = size.height, options.truthSamples = taaArgs->truth;
        options.historyFrames = taaArgs->frames;
        options.displayTruth = taaArgs->truthSpace == "display";
        options.unjitter = !taaArgs->noUnjitter;
        options.moving = !taaArgs->noMoving;
        options.movingFrames = taaArgs->movingFrames,
        options.movingSkip = std::min(8, taaArgs->movingFrames / 2);
        for (const std::string& setting : taaArgs->settings) options.taaHq.setAssignment(setting);
        options.scenes = taaArgs->scenes;
        if (!taaArgs->movingScenes.empty()) {
            for (const std::string& name : taaArgs->movingScenes)
                render::buildScene(name);  // unknown: one line
            options.movingScenes = taaArgs->movingScenes;
        }
        infer::makeFilter("taa-hq", options.taaHq);  // an unknown or out-of-range setting: one line, now
        // A model named on the command line must be there; the shipped ones are compared when present.
        auto model = [taaBench](const std::string& given, const char* flag, const char* shipped) {
            const std::string path = shippedModelPath(given);  // a shipped model from any folder
            if (path.empty() ||
                (taaBench->count(flag) == 0 && given == shipped && !std::filesystem::exists(path)))
                return std::string();
            if (!std::filesystem::exists(path)) throw Error(std::string(flag) + ": no model file " + path);
            return path;
        };
        options.temporalModel =
            model(taaArgs->temporalModel, "--temporal-model", "models/dejag-temporal.safetensors");
        options.fastModel = model(taaArgs->fastModel, "--fast-model", "models/dejag-fast.safetensors");
        for (const std::string& setting : taaArgs->temporalSettings) options.temporal.setAssignment(setting);
        if (!options.temporalModel.empty()) {  // an unknown or out-of-range setting: one line, now
            infer::FilterParameters check = options.temporal;
            check.setAssignment("model=" + options.temporalModel);
            infer::makeFilter("cnn-temporal", check);
        }
        options.jitterSpread = taaArgs->jitterSpread;
        options.ghostWidth = ghost.width, options.ghostHeight = ghost.height;
        options.ghostFrames = taaArgs->ghostFrames, options.ghostTruthSamples = taaArgs->ghostTruth;
        options.ghosting = !taaArgs->noGhosting, options.ssimMapFolder = taaArgs->out,
        options.quiet = taaArgs->json;
        if (options.truthSamples < 1 || options.ghostFrames < 1 || options.ghostTruthSamples < 1)
            throw Error("--truth, --ghost-frames and --ghost-truth must be at least 1");
        const std::vector<nlohmann::json> rows = bench::benchTaa(options);
        if (taaArgs->json) {
            for (const nlohmann::json& row : rows) std::printf("%s\n", row.dump().c_str());
            return;
        }
        std::printf(
            "Static test, %s, %d jittered frames, 8-bit sRGB against the %d-sample truth: PSNR dB "
            "(SSIM)\n",
            taaArgs->size.c_str(), taaArgs->frames, taaArgs->truth);
        std::vector<std::string> methods;  // in the rows' order
        for (const nlohmann::json& row : rows)
            if (row["test"] == "static" &&
                std::find(methods.begin(), methods.end(), row["method"].get<std::string>()) == methods.end())
                methods.push_back(row["method"].get<std::string>());
        std::printf("%-14s", "scene");
        for (const std::string& m : methods) std::printf(" %18s", m.c_str());
        std::printf("\n");
        for (size_t i = 0; i + methods.size() <= rows.size(); i += methods.size()) {
            if (rows[i]["test"] != "static") break;
            std::printf("%-14s", rows[i]["scene"].get<std::string>().c_str());
            for (size_t k = 0; k < methods.size(); ++k)
                std::printf("   %6.2f (%.4f)", rows[i + k]["psnr"].get<double>(),
                            rows[i + k]["ssim"].get<double>());
            std::printf("\n");
        }
        for (const nlohmann::json& row : rows) {
            if (row["test"] != "moving") continue;
            std::printf(
                "moving %-11s %-12s %-18s PSNR best %.2f worst %.2f mean %.2f dB, SSIM mean %.4f, flicker "
                "%.5f\n",
                row["scene"].get<std::string>().c_str(), row["motion"].get<std::string>().c_str(),
                row["method"].get<std::string>().c_str(), row["psnr"]["best"].get<double>(),
                row["psnr"]["worst"].get<double>(), row["psnr"]["mean"].get<double>(),
                row["ssim"]["mean"].get<double>(), row["flicker"].get<double>());
        }
        for (const nlohmann::json& row : rows) {
            if (row["test"] != "ghosting") continue;
            std::printf(
                "ghosting %-22s %-18s PSNR best %.2f worst %.2f mean %.2f dB, SSIM mean %.4f, flicker %.5f\n",
                row["scene"].get<std::string>().c_str(), row["method"].get<std::string>().c_str(),
                row["psnr"]["best"].get<double>(), row["psnr"]["worst"].get<double>(),
                row["psnr"]["mean"].get<double>(), row["ssim"]["mean"].get<double>(),
                row["flicker"].get<double>());
        }
        // Each method's mean over the scenes (and motions) of each test.
        for (const char* test : {"static", "moving", "ghosting"}) {
            std::vector<std::string> order;
            std::map<std::string, std::array<double, 3>> sums;  // PSNR, flicker, count
            for (const nlohmann::json& row : rows) {
                if (row["test"] != test) continue;
                const std::string method = row["method"];
                if (!sums.count(method)) order.push_back(method), sums[method] = {0, 0, 0};
                auto& sum = sums[method];
                sum[0] +=
                    row["psnr"].is_object() ? row["psnr"]["mean"].get<double>() : row["psnr"].get<double>();
                sum[1] += row.value("flicker", 0.0), sum[2] += 1;
            }
            if (order.empty()) continue;
            std::printf("mean of the %s test:", test);
            for (const std::string& m : order) {
                std::printf("  %s %.2f dB", m.c_str(), sums[m][0] / sums[m][2]);
                if (std::string(test) != "static") std::printf(" (flicker %.5f)", sums[m][1] / sums[m][2]);
            }
            std::printf("\n");
        }
    });

    auto quality = std::make_shared<bench::QualityBenchOptions>();
    quality->data = "out/dataset";
    auto qualityModels = std::make_shared<std::string>(bench::kShippedModels);
    auto qualityJson = std::make_shared<bool>(false);
    auto qualityRuntime = std::make_shared<RuntimeOptions>();
    CLI::App* qualityBench = bench->add_subcommand(
        "quality",
        "run time against error: every single-frame method on the test split, report and Pareto plot");
    qualityBench->add_option("--data", quality->data, "dataset folder (its test split; \"\" to skip)")
        ->capture_default_str();
    qualityBench->add_option("--pairs", quality->pairs, "folder of NAME_input.* / NAME_truth.* pairs");
    qualityBench->add_option("--models", *qualityModels, "comma-separated model files")
        ->capture_default_str();
    qualityBench->add_option("--out", quality->out, "report folder")->capture_default_str();
    qualityBench
        ->add_option("--test-images", quality->limit, "test images scored, spread over the split (0: all)")
        ->capture_default_str();
    qualityBench->add_option("--repeat", quality->repeat, "timing repeats")->capture_default_str();
    qualityBench->add_option("--report-items", quality->reportItems, "frames shown with crops in the report")
        ->capture_default_str();
    qualityBench->add_flag(
        "--no-1080p", [quality](int64_t) { quality->fullHd = false; }, "skip timing on a 1920x1080 frame");
    qualityBench->add_flag("--json", *qualityJson, "print every row as a JSON line");
    qualityBench->add_flag("--quiet", quality->quiet, "no progress bar");
    addRuntimeOptions(qualityBench, *qualityRuntime);
    qualityBench->footer(
        "Methods: no AA, FXAA presets 12/23/39, SMAA, each model gated and ungated, FXAA then each model.\n"
        "Writes "
        "OUT/results.csv, results.json, pareto.png (ms at 1920x1080 against PSNR), mosaic.png and "
        "report.html.");
    qualityBench->callback([=] {
        applyRuntimeOptions(*qualityRuntime);
        quality->models = shippedModelPaths(splitList(*qualityModels));
        const std::vector<nlohmann::json> rows = bench::benchQuality(*quality);
        bench::printQualityRows(rows, *qualityJson, true);
        if (!*qualityJson) std::printf("report: %s/report.html\n", quality->out.c_str());
    });

    struct ReachArguments {
        std::string size = "1920x1080",
                    fastModel = "models/dejag-fast.safetensors,models/dejag-guided.safetensors";
        std::vector<std::string> scenes;
        int truth = 64;
        bool json = false, quiet = false;
        RuntimeOptions runtime;
    };
    auto reachArgs = std::make_shared<ReachArguments>();
    CLI::App* reach = bench->add_subcommand(
        "reach",
        "where along an edge each single-frame method gains: edge pixels by the length of their run");
    reach->add_option("--size", reachArgs->size, "frame size WIDTHxHEIGHT")->capture_default_str();
    reach->add_option("--scenes", reachArgs->scenes,
                      "scenes (dejag render --list; default atrium, pipe, hard-edges, flowers, hairball)");
    reach->add_option("--truth", reachArgs->truth, "truth samples")
        ->check(CLI::Range(1, 4096))
        ->capture_default_str();
    reach
        ->add_option("--models", reachArgs->fastModel,
                     "single-frame networks compared, comma-separated files or shipped names, each named by "
                     "its file's "
                     "stem ('' or a missing default: none)")
        ->capture_default_str();
    reach->add_flag("--json", reachArgs->json, "one JSON object per row");
    reach->add_flag("--quiet", reachArgs->quiet, "no progress bar");
    addRuntimeOptions(reach, reachArgs->runtime);
    reach->callback([reachArgs, reach] {
        applyRuntimeOptions(reachArgs->runtime);
        bench::ReachBenchOptions options;
        const Size size = parseSize(reachArgs->size, "--size");
        options.width = size.width, options.height = size.height;
        if (!reachArgs->scenes.empty()) options.scenes = reachArgs->scenes;
        for (const std::string& scene : options.scenes)
            render::buildScene(scene, {});  // unknown: one line, now
        options.truthSamples = reachArgs->truth;
        options.quiet = reachArgs->quiet || reachArgs->json;
        for (const std::string& model : shippedModelPaths(splitList(reachArgs->fastModel))) {
            if (std::filesystem::exists(model))
                options.fastModels.push_back(model);
            else if (reach->count("--models"))
                throw Error("--models: no model file " + model);  // a missing default is skipped
        }
        const std::vector<nlohmann::json> rows = bench::benchReach(options);
        if (reachArgs->json) {
            for (const nlohmann::json& r : rows) std::printf("%s\n", r.dump().c_str());
            return;
        }
        // Per scene and pooled: each class's pixels, no AA's PSNR and every method's gain over it.
        std::vector<std::string> methods;
        for (const nlohmann::json& r : rows)
            if (std::find(methods.begin(), methods.end(), r["method"].get<std::string>()) == methods.end())
                methods.push_back(r["method"].get<std::string>());
        std::printf("%-12s %-6s %9s %9s", "scene", "run", "pixels", "no AA dB");
        for (size_t m = 1; m < methods.size(); ++m) std::printf(" %12s", (methods[m] + " +dB").c_str());
        std::printf("\n");
        for (size_t i = 0; i < rows.size(); i += methods.size()) {
            const nlohmann::json& base = rows[i];
            std::printf("%-12s %-6s %9lld %9.2f", base["scene"].get<std::string>().c_str(),
                        base["run"].get<std::string>().c_str(), (long long)base["pixels"].get<int64_t>(),
                        base["psnr"].get<double>());
            for (size_t m = 1; m < methods.size(); ++m)
                std::printf(" %12.2f", rows[i + m]["gain_db"].get<double>());
            std::printf("\n");
        }
    });

    auto args = std::make_shared<BenchArguments>();
    CLI::App* metrics = bench->add_subcommand(
        "metrics", "SSIM and the full metrics of two RGB images: median ms per thread count and SIMD level");
    metrics->add_option("--size", args->size, "image size WIDTHxHEIGHT")->capture_default_str();
    metrics->add_option("--repeat", args->repeat, "timed runs per case (median reported)")
        ->check(CLI::Range(1, 10000))
        ->capture_default_str();
    args->sweep.add(metrics);
    metrics->add_option("--simd", args->runtime.simd, "force a SIMD path: scalar, avx2 or avx512")
        ->check(CLI::IsMember({"scalar", "avx2", "avx512"}));
    metrics->add_flag("--json", args->json, "one JSON object per case");
    metrics->callback([args] {
        applyRuntimeOptions(args->runtime);
        bench::Options options;
        const Size size = parseSize(args->size, "--size");
        options.width = size.width;
        options.height = size.height;
        options.repeat = args->repeat;
        options.threads = args->sweep.resolve();
        printRows(bench::benchMetrics(options), args->json);
    });
}

}  // namespace dejag::cli

// dejag train: trains a network on a dataset (checkpoints, resume, validation, logs, plots) and exports
// it as a shipped model with its model card.
#include <cstdio>
#include <memory>
#include <sstream>
#include <tuple>

#include "app/cli.h"
#include "app/commands.h"
#include "base/communicator.h"
#include "base/error.h"
#include "infer/filter.h"
#include "train/trainer.h"

namespace dejag::cli {
namespace {

// A method of the filter face as training scores it (sRGB RGB images in and out).
train::Method filterMethod(const std::string& label, const std::string& method) {
    std::shared_ptr<infer::Filter> filter = infer::makeFilter(method, {});
    return {label, [filter](const Image& im) {
                Image out = im;
                infer::Frame frame;
                frame.width = im.width, frame.height = im.height, frame.channels = im.channels();
                frame.colour = im.pixels.data();
                filter->apply(frame, out.pixels.data());
                return out;
            }};
}

// A single-frame method of the filter face on sRGB RGB in place, as --input-method runs it before a network
// (a filter per call: the sampler loads items in parallel).
std::function<void(float*, int, int)> inputTransform(const std::string& method) {
    return [method](float* rgb, int width, int height) {
        const auto filter = infer::makeFilter(method, {});
        std::vector<float> out(size_t(width) * size_t(height) * 3);
        infer::Frame frame;
        frame.width = width, frame.height = height, frame.channels = 3, frame.colour = rgb;
        filter->apply(frame, out.data());
        std::copy(out.begin(), out.end(), rgb);
    };
}

// A temporal method of the filter face run over a whole sequence (training's planar tensors in and out),
// restarted where the sequence's history restarts.
train::SequenceMethod sequenceFilterMethod(const std::string& label, const std::string& method) {
    return {label, [method](const data::SequenceBatch& batch) {
                const std::unique_ptr<infer::Filter> filter = infer::makeFilter(method, {});
                std::vector<nn::Tensor> out;
                std::vector<float> colour, motion, result;
                for (const data::SequenceFrame& f : batch.frames) {
                    const int64_t H = f.colour.dim(2), W = f.colour.dim(3), plane = H * W;
                    colour.resize(size_t(3 * plane)), motion.resize(size_t(2 * plane)),
                        result.resize(colour.size());
                    for (int64_t p = 0; p < plane; ++p) {
                        for (int c = 0; c < 3; ++c)
                            colour[size_t(3 * p + c)] = f.colour.data()[c * plane + p];
                        for (int c = 0; c < 2; ++c)
                            motion[size_t(2 * p + c)] = f.motion.data()[c * plane + p];
                    }
                    infer::Frame frame;
                    frame.width = int(W), frame.height = int(H), frame.colour = colour.data();
                    frame.motion = motion.data(), frame.depth = f.depth.data(),
                    frame.previousDepth = f.previousDepth.data();
                    frame.hasJitter = true, frame.jitter[0] = f.jitter[0], frame.jitter[1] = f.jitter[1];
                    if (f.fresh[0]) filter->reset();
                    filter->apply(frame, result.data());
                    nn::Tensor rgb({1, 3, H, W});
                    for (int64_t p = 0; p < plane; ++p)
                        for (int c = 0; c < 3; ++c) rgb.data()[c * plane + p] = result[size_t(3 * p + c)];
                    out.push_back(std::move(rgb));
                }
                return out;
            }};
}

// The comparison methods of validation and of the model card: the unfiltered frame, FXAA 3.11 at its
// highest preset and SMAA 1x at its ultra preset (train/ cannot depend on infer/, so they are wired in
// here).
std::vector<train::Method> standardBaselines() {
    return {filterMethod("no AA", "none"), filterMethod("FXAA", "fxaa"), filterMethod("SMAA", "smaa")};
}

std::vector<int64_t> parseSteps(const std::string& text) {
    std::vector<int64_t> steps;
    std::stringstream stream(text);
    std::string item;
    while (std::getline(stream, item, ',')) {
        if (item.empty()) continue;
        try {
            size_t used = 0;
            steps.push_back(std::stoll(item, &used));
            if (used != item.size()) throw std::invalid_argument(item);
        } catch (const std::exception&) {
            throw Error("--poison-steps: '" + item + "' is not a step number");
        }
    }
    return steps;
}

}  // namespace

void registerTrainCommand(CLI::App& app) {
    CLI::App* trainCommand =
        app.add_subcommand("train", "train an anti-aliasing network; `train export` ships it");
    auto config = std::make_shared<train::TrainConfig>();
    auto runtime = std::make_shared<RuntimeOptions>();
    auto poison = std::make_shared<std::string>();
    trainCommand->add_option("--data", config->data, "dataset folder (dejag data generate)");
    trainCommand->add_option("--input-method", config->inputMethod,
                             "a single-frame method the network runs after (e.g. smaa): its patches and "
                             "validation images pass through it, and dejag filter runs it first");
    trainCommand->add_option("--guide-method", config->guideMethod,
                             "a single-frame method (e.g. smaa) whose result the network reads beside the "
                             "frame and may blend in per pixel (kpn family: kpn:WxD+guide)");
    trainCommand
        ->add_option(
            "--arch", config->arch,
            "seed2020 | fast | fast:WIDTHxDEPTH (the fast family at another size, e.g. fast:12x3) | "
            "kpn | kpn:WIDTHxDEPTH (fast's trunk predicting a 3x3 kernel per pixel) | temporal | "
            "temporal:WIDTHxDEPTH (recurrent; trains on a dataset of sequences) | accumulate | "
            "accumulate:WIDTHxDEPTH[+depth][+clip] (recurrent, blending as a TAA's running mean; +depth: "
            "the depth buffers as inputs; +clip: the history clamped to the frame's neighbourhood) | "
            "FILE.json")
        ->capture_default_str();
    trainCommand->add_option("--out", config->out, "run folder (checkpoints, logs, plots)");
    trainCommand
        ->add_option(
            "--loss", config->loss,
            "ssim | l1 | mse | ssim+l1 | weighted sums like 0.84*ssim+0.16*l1; harm, harmN (per N px "
            "block) and texharm (on texture pixels) penalise an output worse than its input")
        ->capture_default_str();
    trainCommand->add_option("--steps", config->steps, "optimizer steps");
    trainCommand->add_option("--epochs", config->epochs,
                             "or epochs (an epoch covers the train split's pixels once)");
    trainCommand->add_option("--batch", config->batch, "patches per batch")->capture_default_str();
    trainCommand->add_option("--patch", config->patch, "patch side in pixels (a multiple of 8)")
        ->capture_default_str();
    trainCommand->add_option("--lr", config->learningRate, "learning rate of Adam (cosine decay, warm-up)")
        ->capture_default_str();
    trainCommand->add_option("--warmup", config->warmupSteps, "warm-up steps")->capture_default_str();
    trainCommand->add_option("--clip", config->clipNorm, "gradient norm clip (0: off)")
        ->capture_default_str();
    trainCommand->add_option("--seed", config->seed, "seed of the initial weights and the batches")
        ->capture_default_str();
    trainCommand->add_option("--eval-every", config->evalEvery, "steps between validations")
        ->capture_default_str();
    trainCommand->add_option("--checkpoint-every", config->checkpointEvery, "steps between checkpoints")
        ->capture_default_str();
    trainCommand
        ->add_option("--val-images", config->validationImages, "validation images per evaluation (0: all)")
        ->capture_default_str();
    trainCommand
        ->add_option("--patience", config->patience,
                     "stop after this many evaluations without improvement (0: never)")
        ->capture_default_str();
    auto families = std::make_shared<std::string>();
    trainCommand->add_option(
        "--families", *families,
        "train and validate on these families only (comma-separated; default: all but the test ones)");
    trainCommand->add_flag("--resume", config->resume, "continue the run in --out from its checkpoint");
    trainCommand->add_flag("--json", config->json, "log lines as JSON objects");
    trainCommand->add_flag("--quiet", config->quiet, "no progress bar");
    trainCommand->add_option("--poison-steps", *poison, "testing: put a NaN into these steps' batches")
        ->group("");
    auto killAt = std::make_shared<std::string>();
    trainCommand
        ->add_option("--kill-rank-at", *killAt,
                     "testing: RANK:STEP, the process of that rank kills itself (SIGKILL) at that step")
        ->group("");
    trainCommand
        ->add_option("--micro-batches", config->microBatches,
                     "split each batch into this many micro-batches, each run alone and their gradients "
                     "summed in order: a run's weights then do not depend on how many processes share it "
                     "(dejag-mpi: default one per process; docs/mpi.md)")
        ->check(CLI::Range(0, 4096));
    trainCommand
        ->add_option(
            "--adversarial", config->adversarialFraction,
            "stress testing: insert constant, noise, HDR-spike or NaN-poisoned batches as this fraction "
            "of the steps, on top of the clean ones --steps counts (default 0)")
        ->check(CLI::Range(0.0, 0.9));
    trainCommand
        ->add_option("--uniform-patches", config->uniformPatches,
                     "share of the patches placed uniformly over the frames; the rest are centred near an "
                     "aliasing pixel")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str();
    trainCommand
        ->add_option("--skip-outliers", config->outlierFactor,
                     "skip a step whose loss exceeds K times its running average, or whose input's "
                     "detail lies above K times or below 1/K^2 of its own (0: off; K > 1)")
        ->check(CLI::Range(0.0, 1e6))
        ->capture_default_str();
    trainCommand
        ->add_option("--frames", config->frames,
                     "sequences: frames each crop is unrolled over (0: the dataset's sequence length)")
        ->check(CLI::Range(0, 1000))
        ->capture_default_str();
    trainCommand
        ->add_option("--temporal-loss", config->temporalLoss,
                     "sequences: weight of the temporal term, |(X_t - X_t-1) - (R_t - R_t-1)| (the flicker "
                     "against the truth's own change)")
        ->check(CLI::Range(0.0, 100.0))
        ->capture_default_str();
    addRuntimeOptions(trainCommand, *runtime);
    trainCommand->footer(
        "Writes RUN/run.json, checkpoint.safetensors (atomically, every --checkpoint-every steps), "
        "best.safetensors\n"
        "(best validation PSNR), final.safetensors, log.csv, loss.png and validation.png. Validation scores "
        "the\n"
        "network, no AA and FXAA on whole images, edge pixels and texture pixels. Interrupted? Add --resume: "
        "the\n"
        "result is the same, bit for bit, with the same --threads.\n"
        "Several processes (mpirun -np N dejag-mpi train ...): each runs its share of every batch; the\n"
        "weights equal one process's with --micro-batches N, bit for bit. docs/mpi.md.\n"
        "Then: dejag train export RUN models/NAME.safetensors");

    auto exportRun = std::make_shared<std::string>();
    auto exportModel = std::make_shared<std::string>();
    auto testImages = std::make_shared<int>(0);
    auto exportQuiet = std::make_shared<bool>(false);
    auto exportRuntime = std::make_shared<RuntimeOptions>();
    CLI::App* exportCommand = trainCommand->add_subcommand(
        "export", "write a run's best model and its model card (scored on the validation and test splits)");
    exportCommand->add_option("run", *exportRun, "run folder")->required();
    exportCommand
        ->add_option("model", *exportModel, "model file to write, e.g. models/dejag-fast.safetensors")
        ->required();
    exportCommand->add_option("--test-images", *testImages, "test images to score (0: all)")
        ->capture_default_str();
    auto exportBench = std::make_shared<std::string>();
    exportCommand->add_option("--bench-taa", *exportBench,
                              "the rows `dejag bench taa --json` printed for this model: the card carries "
                              "their table");
    exportCommand->add_flag("--quiet", *exportQuiet, "print nothing but errors");
    addRuntimeOptions(exportCommand, *exportRuntime);
    exportCommand->callback([=] {
        applyRuntimeOptions(*exportRuntime);
        const std::string card =
            train::exportModel(*exportRun, *exportModel, standardBaselines(), *testImages, *exportQuiet,
                               {sequenceFilterMethod("taa-hq", "taa-hq")}, *exportBench, inputTransform);
        if (!*exportQuiet) std::printf("%s", card.c_str());
    });

    trainCommand->callback([=] {
        if (exportCommand->parsed()) return;
        applyRuntimeOptions(*runtime);
        train::TrainFaults faults;
        faults.poisonSteps = parseSteps(*poison);
        if (!killAt->empty()) {
            const size_t colon = killAt->find(':');
            try {
                if (colon == std::string::npos) throw std::invalid_argument("no colon");
                faults.killRank = std::stoi(killAt->substr(0, colon));
                faults.killStep = std::stoll(killAt->substr(colon + 1));
            } catch (const std::exception&) {
                throw Error("--kill-rank-at: '" + *killAt + "' is not RANK:STEP");
            }
        }
        config->families = splitList(*families);
        config->commandLine = invocation();
        for (auto [flag, method, transform] :
             {std::tuple{"--input-method", &config->inputMethod, &config->inputTransform},
              std::tuple{"--guide-method", &config->guideMethod, &config->guideTransform}}) {
            if (method->empty()) continue;
            const auto check = infer::makeFilter(*method, {});  // an unknown method: one line, now
            if (check->needs() != 0 || check->temporal() || !check->stages().empty())
                throw Error(std::string(flag) + ": " + *method +
                            " is not a single-frame method on colour alone");
            *transform = inputTransform(*method);
        }
        const train::TrainResult r = train::trainModel(*config, standardBaselines(), faults);
        if (config->json)
            std::printf("%s\n", nlohmann::json{{"event", "finished"},
                                               {"steps", r.steps},
                                               {"skipped", r.skippedSteps},
                                               {"seconds", r.seconds},
                                               {"best_step", r.bestStep},
                                               {"best_psnr", r.bestPsnr},
                                               {"largest_loss", r.largestLoss},
                                               {"outliers_skipped", r.outlierSteps},
                                               {"adversarial",
                                                {{"constant", r.adversarialSteps[1]},
                                                 {"noise", r.adversarialSteps[2]},
                                                 {"hdr_spikes", r.adversarialSteps[3]},
                                                 {"poisoned", r.adversarialSteps[4]}}},
                                               {"stopped_early", r.stoppedEarly},
                                               {"micro_batches", r.microBatches},
                                               {"ranks", communicator().size()},
                                               {"communication_seconds", r.communicationSeconds},
                                               {"wait_seconds", r.waitSeconds}}
                                    .dump()
                                    .c_str());
        else
            std::printf(
                "trained %lld steps in %.0f s (%lld skipped); best validation PSNR %.2f dB at step %lld%s\n",
                (long long)r.steps, r.seconds, (long long)r.skippedSteps, r.bestPsnr, (long long)r.bestStep,
                r.stoppedEarly ? " (stopped early)" : "");
    });
}

}  // namespace dejag::cli

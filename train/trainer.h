// dejag/train: the training loop behind `dejag train`, its run folder, and model export.
//
// A run folder RUN/ holds
//   run.json                 the configuration, the command line, the data set, wall time so far
//   checkpoint.safetensors   everything a resumed run needs: parameters, Adam moments, step, LR scale,
//                            early-stopping state and the log history (written atomically)
//   best.safetensors         the model of the best validation PSNR so far (a model file)
//   final.safetensors        the model at the last step
//   log.csv, loss.png, validation.png   the log and its plots, rewritten at every evaluation
// Batch k depends only on the seed and k (data/patches.h) and every kernel is deterministic for a
// thread count, so a resumed run ends with the same weights, bit for bit, as an uninterrupted one.
//
// A step whose batch, loss or gradient is not finite is skipped (the weights and the optimizer state are
// untouched), logged, and the learning rate is halved; `maxBadSteps` bad steps in a row stop the run
// with an error, the last checkpoint intact.
#pragma once

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "data/evaluation.h"
#include "data/patches.h"
#include "data/sequences.h"
#include "nn/frame_network.h"
#include "nn/model.h"

namespace dejag::train {

struct TrainConfig {
    std::string data;            // dataset folder (data/dataset.h)
    std::string arch = "fast";   // seed2020 | fast | FILE.json
    std::string out;             // run folder
    std::string loss = "ssim";   // nn::CompositeLoss::parse: ssim, ssim+l1, 0.84*ssim+0.16*l1, ...
    int64_t steps = 0;           // clean steps (0: from epochs); adversarial ones come on top
    double epochs = 0;           // one epoch: as many patch pixels as the train split has pixels
    int batch = 16, patch = 96;  // patches per batch, patch side
    double learningRate = 1e-3;  // Adam; cosine decay to 5 % after a linear warm-up
    int64_t warmupSteps = 200;
    double clipNorm = 1.0;  // global gradient-norm clip (0: off)
    uint64_t seed = 1;
    int64_t evalEvery = 250;  // steps between validations
    int64_t checkpointEvery = 250;
    int validationImages = 48;  // validation items scored at each evaluation (0: all)
    int patience = 0;           // evaluations without a better validation PSNR before stopping (0: off)
    int maxBadSteps = 8;        // non-finite steps in a row before giving up
    bool resume = false;
    bool quiet = false;  // no progress bar
    bool json = false;   // log lines as JSON objects on stdout
    // Stress testing: this fraction of the steps, chosen by the seed and the step, trains on an
    // adversarial batch (see AdversarialKind): constant patches, pure noise, HDR spikes up to 1e4, or
    // NaN/Inf-poisoned input that the guard must reject. They are inserted between the clean batches,
    // which stay the same batches in the same order.
    double adversarialFraction = 0;
    // The outlier guard: a step whose loss exceeds this many times the running average of the recent
    // losses is skipped (not counted as a failure, the learning rate kept). 0: off.
    double outlierFactor = 0;
    // The share of each batch's patches placed uniformly over the frames; the others are centred near an
    // aliasing pixel (data::PatchOptions::uniformFraction).
    double uniformPatches = data::PatchOptions().uniformFraction;
    std::string commandLine;            // recorded in run.json and the model card
    std::vector<std::string> families;  // train and validate on these families only (empty: all but test)
    // A dataset of sequences (a temporal network, train/temporal.h): frames per crop (0: the sequences'
    // length) and the weight of the temporal term of the loss.
    int frames = 0;
    double temporalLoss = 0;
    // The global batch as this many equal micro-batches, each run forward and backward alone and their
    // gradients summed in order: a run's numbers then depend on it and not on the processes that share
    // the batch (dejag-mpi: rank r runs its contiguous share of them; docs/mpi.md). 0: the number of
    // processes, or a resumed run's own.
    int microBatches = 0;
    // A single-frame method the network runs after (its name, recorded in the model's architecture as
    // "input_method", and the method itself on sRGB RGB in place): training patches and validation images
    // reach the network through it, and the filter runs it before the network.
    std::string inputMethod;
    std::function<void(float* rgb, int width, int height)> inputTransform;
    // A single-frame method whose result the network reads beside the frame (recorded as "guide_method";
    // the kpn family with a guide, kpn:WxD+guide, which --guide-method picks for kpn and kpn:WxD): its
    // result on each patch and validation image is the network's channels 3..5.
    std::string guideMethod;
    std::function<void(float* rgb, int width, int height)> guideTransform;
};

// The batches `--adversarial` mixes in. Constant: every patch one grey level, input = target; noise:
// uniform noise, input = target; HDR spikes: the step's batch with 1 % of its pixels set to 10^[0, 4] in
// input and target; poisoned: the step's batch with NaN and Inf values in its input.
enum class AdversarialKind { None, Constant, Noise, HdrSpikes, Poisoned };
const char* adversarialKindName(AdversarialKind kind);
// Which kind step `step` of a run with this seed gets (None for most steps); a pure function, so a
// resumed run sees the same batches.
AdversarialKind adversarialKindAt(uint64_t seed, int64_t step, double fraction);
// Rewrites the batch (N, C, P, P) as that kind, deterministically from seed and step.
void makeAdversarial(nn::Tensor& input, nn::Tensor& target, AdversarialKind kind, uint64_t seed,
                     int64_t step);

// A method to score: the network under training, or a comparison method for validation and the model
// card (no AA and FXAA: the app makes them through infer/filter.h, which train/ does not depend on).
// Takes an sRGB RGB image; returns RGB, or luma for a grey model.
struct Method {
    std::string name;
    std::function<Image(const Image&)> apply;
};

struct TrainResult {
    int64_t steps = 0, skippedSteps = 0;
    double seconds = 0;   // wall time of the whole run, including resumed sessions
    double bestPsnr = 0;  // validation PSNR (whole images) of best.safetensors
    int64_t bestStep = 0;
    bool stoppedEarly = false;
    bool interrupted = false;          // TrainFaults::stopAfterSteps ended the session: resume
    double largestLoss = 0;            // of the steps taken (not skipped), over the whole run
    int64_t outlierSteps = 0;          // skipped by the outlier guard, over the whole run
    int64_t adversarialSteps[5] = {};  // steps of each AdversarialKind, over the whole run
    int microBatches = 1;
    double communicationSeconds = 0;  // this session's, in the gradients' gather (several processes)
    double waitSeconds = 0;           // this session's, waiting for the slowest rank before the gather
};

// Faults injected for tests, kept out of the configuration (a run never records them): steps whose batch
// gets a NaN (the guard must skip it), steps whose target is multiplied by 1000 (a loss spike), and a
// session that ends after this many steps, checkpointed, as if killed then (0: run to the end).
struct TrainFaults {
    std::vector<int64_t> poisonSteps, spikeSteps;
    int64_t stopAfterSteps = 0;
    // The process of this rank (dejag-mpi) kills itself with SIGKILL as it reaches this step (-1: never).
    int killRank = -1;
    int64_t killStep = -1;
    bool stopsAfter(int64_t sessionSteps) const;
    void inject(int64_t step, nn::Tensor& input, nn::Tensor& target) const;
};

// Trains, writing the run folder as it goes. Throws dejag::Error on bad configuration or data, or when
// training diverges (after maxBadSteps bad steps in a row).
TrainResult trainModel(const TrainConfig& config, const std::vector<Method>& baselines,
                       const TrainFaults& faults = {});

// The architecture --arch names: seed2020, fast, fast:WIDTH[xDEPTH] (the fast family at another size),
// or a JSON file. Throws dejag::Error naming what is wrong.
nlohmann::json architectureFor(const std::string& arch);

// Runs a network on a whole sRGB RGB image through the contract every caller uses (nn/frame_network.h):
// RGB out for RGB and grey models alike (a grey model's change of the luma on R, G and B).
// guide: a guided network's guide image (the guide method's result on `rgb`), required for one.
Image runNetwork(nn::FrameNetwork& network, const Image& rgb, const Image* guide = nullptr);

// Scores methods on the items: returns a summary per method (same order as `methods`). The first
// method is the reference of "harm" (the unfiltered frame, in every caller): an image is harmed by a
// method whose PSNR on it is more than kHarmDb below the first method's, and its texture harmed when
// the texture region's PSNR is below the first method's at all. Flat items (data::kFlatItemPsnr) are
// left out of both counts.
inline constexpr double kHarmDb = 0.1;
struct MethodScores {
    std::string name;
    data::ScoreSummary summary;
    double millisecondsPerImage = 0;  // median
    int harmed = 0, textureHarmed = 0;
    double worstGainDb = 0;  // the lowest per-image PSNR gain over the first method (0 for the first)
    std::string worstItem;   // its family/id
};
std::vector<MethodScores> scoreMethods(const std::vector<data::EvaluationItem>& items,
                                       const std::vector<Method>& methods, bool grey);

// `dejag train export`: writes RUN's best model to `modelPath` (metadata: the provenance) and the model
// card next to it (NAME.md): architecture, parameters, MACs per pixel, data recipe, training command,
// wall time, and validation and test metrics against the baselines. Returns the card's text.
// A temporal network's run (a dataset of sequences) is scored on whole validation and test sequences next
// to `sequenceBaselines` (each run over a whole sequence, a batch of one: every frame's sRGB RGB,
// (1, 3, H, W)) and the jittered frames themselves; `testImages` then limits the test sequences.
// `benchTaa` (empty: none): a file of `dejag bench taa --json` rows whose tables the card carries
// (train/bench_card.h), read before anything is scored.
struct SequenceMethod {
    std::string name;
    std::function<std::vector<nn::Tensor>(const data::SequenceBatch&)> apply;
};
// inputMethod: makes, by name, the method a network trained with --input-method runs after, or reads
// beside the frame (--guide-method) (the model's architecture names it); its validation and test images
// pass through it before the network, or it makes their guides. Null: such a model is refused.
using InputMethodFactory =
    std::function<std::function<void(float* rgb, int width, int height)>(const std::string&)>;
std::string exportModel(const std::string& run, const std::string& modelPath,
                        const std::vector<Method>& baselines, int testImages, bool quiet,
                        const std::vector<SequenceMethod>& sequenceBaselines = {},
                        const std::string& benchTaa = "", const InputMethodFactory& inputMethod = nullptr);

}  // namespace dejag::train

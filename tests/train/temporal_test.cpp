// Training a recurrent network: the unrolled step's gradient (backpropagation through time) against
// central differences of the same loss computed independently in double; the sequence sampler's crops,
// whose motion vectors still carry each truth onto the next under every flip and transpose.
#include "train/temporal.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <random>
#include <string>
#include <vector>

#include "base/error.h"
#include "data/sequences.h"
#include "nn/gradient_check.h"
#include "nn/layers.h"
#include "nn/safetensors.h"
#include "tests/test_util.h"
#include "train/trainer.h"

namespace dejag::train {
namespace {

namespace fs = std::filesystem;

// A batch of K frames of N random crops: random colour and truth, motion up to 1.5 px, jitter, and
// a history that restarts at frame 0 and, for the second crop, at a cut at frame 2.
data::SequenceBatch randomBatch(int K, int N, int P, uint32_t seed) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> unit(0.0f, 1.0f), motion(-1.5f, 1.5f), jitter(-0.5f, 0.5f);
    data::SequenceBatch batch;
    for (int t = 0; t < K; ++t) {
        data::SequenceFrame f;
        f.colour = nn::Tensor({N, 3, P, P}), f.truth = nn::Tensor({N, 3, P, P}),
        f.motion = nn::Tensor({N, 2, P, P});
        for (int64_t i = 0; i < f.colour.numel(); ++i)
            f.colour.data()[i] = unit(rng), f.truth.data()[i] = unit(rng);
        for (int n = 0; n < N; ++n) {
            f.fresh.push_back(t == 0 || (n == 1 && t == 2));
            f.jitter.push_back(jitter(rng)), f.jitter.push_back(jitter(rng));
            for (int64_t i = 0; i < 2 * P * P; ++i)
                f.motion.data()[int64_t(n) * 2 * P * P + i] = f.fresh.back() ? 0.0f : motion(rng);
        }
        batch.frames.push_back(std::move(f));
    }
    return batch;
}

// The unrolled loss in double, written out independently of the Unroller: each frame's input made from
// the batch and the previous output, forwardInDouble, the per-frame loss in double, the temporal term.
double referenceLoss(const nn::Model& model, const data::SequenceBatch& batch, const TemporalLoss& loss) {
    const int K = int(batch.frames.size());
    const int64_t N = batch.frames[0].colour.dim(0), P = batch.frames[0].colour.dim(2), plane = P * P;
    const int64_t H = model.outputChannels(), C = 3 + H + 4;
    std::vector<double> previous, rgbBefore;
    double total = 0;
    for (int t = 0; t < K; ++t) {
        const data::SequenceFrame& f = batch.frames[size_t(t)];
        std::vector<double> input(size_t(N * C * plane));
        for (int64_t n = 0; n < N; ++n)
            for (int64_t i = 0; i < plane; ++i) {
                double* in = input.data() + n * C * plane + i;
                for (int c = 0; c < 3; ++c) in[c * plane] = f.colour.data()[(n * 3 + c) * plane + i];
                for (int c = 0; c < H; ++c)
                    in[(3 + c) * plane] = t > 0 && !f.fresh[size_t(n)]
                                              ? previous[size_t((n * H + c) * plane + i)]
                                          : c < 3 ? f.colour.data()[(n * 3 + c) * plane + i]
                                                  : 0.0;
                for (int c = 0; c < 2; ++c)
                    in[(3 + H + c) * plane] = f.motion.data()[(n * 2 + c) * plane + i];
                for (int c = 0; c < 2; ++c) in[(5 + H + c) * plane] = f.jitter[size_t(2 * n + c)];
            }
        const std::vector<double> y = nn::forwardInDouble(model, input, {N, C, P, P});
        std::vector<double> rgb(size_t(N * 3 * plane)), truth(rgb.size());
        for (int64_t n = 0; n < N; ++n)
            for (int64_t i = 0; i < 3 * plane; ++i)
                rgb[size_t(n * 3 * plane + i)] = y[size_t(n * H * plane + i)],
                                           truth[size_t(n * 3 * plane + i)] =
                                               f.truth.data()[n * 3 * plane + i];
        total += loss.perFrame.evaluate<double>(nullptr, rgb.data(), truth.data(), {N, 3, P, P, 1.0}) / K;
        if (t > 0)
            for (int64_t n = 0; n < N; ++n) {
                if (f.fresh[size_t(n)]) continue;
                double sum = 0;
                const data::SequenceFrame& g = batch.frames[size_t(t - 1)];
                for (int64_t i = 0; i < 3 * plane; ++i) {
                    const size_t at = size_t(n * 3 * plane + i);
                    sum +=
                        std::abs(rgb[at] - rgbBefore[at] - (double(f.truth.data()[at]) - g.truth.data()[at]));
                }
                total += loss.temporalWeight * sum / (3.0 * double(plane)) / (double(N) * (K - 1));
            }
        previous = y, rgbBefore = rgb;
    }
    return total;
}

// Backpropagation through time: the gradient of the unrolled loss (per-frame 1 - SSIM and L1, the
// temporal term) w.r.t. every kind of parameter, through three frames, the warp of the history and a cut,
// against central differences of the loss computed in double.
TEST(TemporalTraining, TheUnrolledGradientMatchesCentralDifferences) {
    nn::ModelOptions options;
    options.width = 4, options.depth = 2, options.state = 1;
    nn::Model model = nn::Model::builtin("temporal", options);
    model.initialize(5);
    // The blend's logits and the state's correction start small; bring them to full size so that every
    // path matters.
    for (const nn::ParameterInfo& p : model.parameters())
        if (p.name.rfind("blend_logits", 0) == 0 || p.name.rfind("state_correction", 0) == 0)
            for (int64_t i = 0; i < nn::shapeNumel(p.shape); ++i) model.parameterData()[p.offset + i] *= 10;
    // Parameters on a grid of 2^-20, so that a step of 2^-14 moves each one exactly in float.
    for (int64_t i = 0; i < model.parameterCount(); ++i)
        model.parameterData()[i] = std::ldexp(std::round(std::ldexp(model.parameterData()[i], 20)), -20);
    TemporalLoss loss;
    loss.temporalWeight = 0.5;
    const data::SequenceBatch batch = randomBatch(3, 2, 12, 7);
    Unroller unroller(model, loss);
    const double value = unroller.run(batch, true);
    EXPECT_NEAR(value, referenceLoss(model, batch, loss), 1e-5 * std::max(1.0, std::abs(value)));
    std::vector<double> analytic(model.gradientData(), model.gradientData() + model.parameterCount());
    std::vector<double> parameters(model.parameterData(), model.parameterData() + model.parameterCount());
    auto scalar = [&] {
        for (size_t i = 0; i < parameters.size(); ++i) model.parameterData()[i] = float(parameters[i]);
        return referenceLoss(model, batch, loss);
    };
    nn::GradientCheckOptions check;
    check.samples = 60, check.step = std::ldexp(1.0, -14), check.floorOfLargest = 1e-2,
    check.piecewise = true;
    std::mt19937_64 coordinates(3);
    const nn::GradientCheckResult result =
        nn::checkGradient(parameters, analytic, scalar, coordinates, check);
    std::printf("[bptt] worst relative error %.2e over %d parameters (%d on kinks)\n", result.worst,
                result.checked, result.kinks);
    EXPECT_LE(result.worst, 2e-3) << result.checked << " checked, " << result.kinks << " on kinks";
    EXPECT_GE(result.checked, 40);
    // Without the history's gradient passed back in time the check fails: the frames are coupled.
    double largest = 0;
    for (double g : analytic) largest = std::max(largest, std::abs(g));
    EXPECT_GT(largest, 1e-3);
}

// The output blends the frame's neighbourhood and the warped history with weights that sum to 1, so a
// sequence of one colour per channel stays that colour whatever the weights (here a random initialisation).
TEST(TemporalTraining, AConstantSequenceStaysConstant) {
    nn::Model model = nn::Model::builtin("temporal");
    model.initialize(2);
    data::SequenceBatch batch = randomBatch(4, 2, 16, 9);
    for (data::SequenceFrame& f : batch.frames)
        for (int64_t i = 0; i < f.colour.numel(); ++i)
            f.colour.data()[i] = f.truth.data()[i] = 0.25f + 0.5f * (i / 256 % 3 == 1);
    Unroller unroller(model, {});
    unroller.run(batch, false);
    for (int t = 0; t < 4; ++t) {
        const nn::Tensor& out = unroller.output(t);
        for (int64_t n = 0; n < 2; ++n)
            for (int64_t i = 0; i < 3 * 256; ++i)
                EXPECT_NEAR(out.data()[n * 4 * 256 + i],
                            batch.frames[size_t(t)].colour.data()[n * 3 * 256 + i], 1e-5);
    }
}

// A rendered dataset of sequences, shared by the tests below: 24 sequences of 4 frames at 64x48 (the
// foliage ones the test split).
class TemporalData : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        folder_ = (fs::temp_directory_path() / ("dejag-temporal-" + std::to_string(::getpid()))).string();
        fs::remove_all(folder_);
        const std::string command =
            "'" + std::string(DEJAG_BINARY) +
            "' data generate --families pipes,shapes,thin,foliage --test-families foliage --count 24 "
            "--size 64x48 --truth 8 --sequence-length 4 --workers 2 --quiet --out '" +
            folder_ + "/data'";
        ASSERT_EQ(std::system(command.c_str()), 0);
    }
    static void TearDownTestSuite() { fs::remove_all(folder_); }
    static std::string data() { return folder_ + "/data"; }
    static TrainConfig tinyConfig(const std::string& name) {
        TrainConfig c;
        c.data = data(), c.out = folder_ + "/" + name, c.arch = "temporal:4x2";
        c.steps = 12, c.batch = 2, c.patch = 32, c.learningRate = 2e-3, c.warmupSteps = 2;
        c.evalEvery = 6, c.checkpointEvery = 3, c.validationImages = 2, c.quiet = true;
        c.frames = 3, c.temporalLoss = 0.2;
        return c;
    }
    static std::vector<float> finalWeights(const TrainConfig& c) {
        std::vector<float> all;  // every tensor, in name order
        for (const auto& [name, tensor] : nn::readSafetensors(c.out + "/final.safetensors").tensors)
            all.insert(all.end(), tensor.f32.begin(), tensor.f32.end());
        return all;
    }
    static std::string folder_;
};
std::string TemporalData::folder_;

// The sampler's crops of a rendered sequence dataset: under each of the 8 flips and transposes, the
// motion still says where each pixel was, jitter stays within its spread, and batch k is the same every
// time.
TEST_F(TemporalData, SampledCropsKeepTheirMotionUnderEverySymmetry) {
    const std::string folder = data();
    data::SequenceOptions options;
    options.patchSize = 32, options.batchSize = 16, options.frames = 3;
    options.split = data::Split::Train;
    const data::SequenceSampler sampler(folder, options);
    EXPECT_GT(sampler.sequenceCount(), 5);
    EXPECT_EQ(sampler.frames(), 3);
    // Per crop with enough motion: the previous truth read at p - motion against it read with the motion
    // put through each of the other 7 symmetries (signs flipped, x and y swapped); the crop's own must be
    // the best in nearly every crop (a symmetry applied to the image but not to the motion is not).
    int crops = 0, best = 0;
    nn::WarpDesc d;
    d.batch = 1, d.channels = 3, d.height = d.width = 32, d.filter = nn::WarpFilter::Bilinear;
    std::vector<float> was(3 * 32 * 32), variant(2 * 32 * 32);
    for (uint64_t index = 0; index < 8; ++index) {
        const data::SequenceBatch batch = sampler.assemble(index);
        ASSERT_EQ(batch.frames.size(), 3u);
        for (int t = 1; t < 3; ++t) {
            const data::SequenceFrame &f = batch.frames[size_t(t)], &g = batch.frames[size_t(t - 1)];
            for (int n = 0; n < 16; ++n) {
                EXPECT_LE(std::abs(f.jitter[size_t(2 * n)]), 0.5f);
                if (f.fresh[size_t(n)]) continue;
                const float* motion = f.motion.data() + n * 2 * 1024;
                double speed = 0;
                for (int i = 0; i < 1024; ++i) speed += std::abs(motion[i]) + std::abs(motion[1024 + i]);
                if (speed / 1024 < 0.75) continue;
                double error[8] = {};
                for (int v = 0; v < 8; ++v) {
                    for (int i = 0; i < 1024; ++i) {
                        float mx = motion[i], my = motion[1024 + i];
                        if (v & 1) mx = -mx;
                        if (v & 2) my = -my;
                        if (v & 4) std::swap(mx, my);
                        variant[size_t(i)] = mx, variant[size_t(1024 + i)] = my;
                    }
                    nn::warpForward(was.data(), g.truth.data() + n * 3 * 1024, variant.data(), d);
                    for (int y = 3; y < 29; ++y)
                        for (int x = 3; x < 29; ++x)
                            for (int c = 0; c < 3; ++c)
                                error[v] += std::abs(f.truth.data()[(n * 3 + c) * 1024 + y * 32 + x] -
                                                     was[size_t(c * 1024 + y * 32 + x)]);
                }
                ++crops;
                best += *std::min_element(error + 1, error + 8) >= error[0];
            }
        }
    }
    EXPECT_GE(crops, 20);
    EXPECT_GE(best, 0.9 * crops) << best << " of " << crops << " crops";
    const data::SequenceBatch a = sampler.assemble(3), b = sampler.assemble(3);
    for (size_t t = 0; t < a.frames.size(); ++t) {
        EXPECT_EQ(std::vector<float>(a.frames[t].colour.data(),
                                     a.frames[t].colour.data() + a.frames[t].colour.numel()),
                  std::vector<float>(b.frames[t].colour.data(),
                                     b.frames[t].colour.data() + b.frames[t].colour.numel()));
        EXPECT_EQ(a.frames[t].fresh, b.frames[t].fresh);
    }
    // Crops longer than the sequences are refused.
    options.frames = 9;
    EXPECT_THROW(data::SequenceSampler(folder, options), Error);
}

// dejag train on a dataset of sequences: the run folder as for single frames, and a run interrupted twice
// and resumed ends with the weights of the uninterrupted one, bit for bit.
TEST_F(TemporalData, ResumedTrainingEqualsTheUninterruptedRunBitForBit) {
    const TrainConfig straight = tinyConfig("straight");
    const TrainResult done = trainModel(straight, {});
    EXPECT_EQ(done.steps, 12);
    EXPECT_GT(done.bestPsnr, 10.0);
    for (const char* f : {"run.json", "checkpoint.safetensors", "best.safetensors", "final.safetensors",
                          "log.csv", "loss.png", "validation.png"})
        EXPECT_TRUE(fs::exists(straight.out + "/" + f)) << f;
    TrainConfig broken = tinyConfig("broken");
    TrainFaults faults;
    faults.stopAfterSteps = 4;
    EXPECT_TRUE(trainModel(broken, {}, faults).interrupted);
    broken.resume = true;
    faults.stopAfterSteps = 4;  // past an evaluation
    EXPECT_TRUE(trainModel(broken, {}, faults).interrupted);
    faults.stopAfterSteps = 0;
    EXPECT_EQ(trainModel(broken, {}, faults).steps, 12);
    EXPECT_EQ(finalWeights(straight), finalWeights(broken));
    EXPECT_GT(finalWeights(straight).size(), 1000u);
    // Export: the best model and its card, scored on whole sequences next to the jittered frames and a
    // given baseline (here the frames themselves under another name: the same figures).
    const std::string exported = folder_ + "/models/dejag-temporal-test.safetensors";
    fs::create_directories(folder_ + "/models");
    const SequenceMethod copy{"copy", [](const data::SequenceBatch& b) {
                                  std::vector<nn::Tensor> out;
                                  for (const data::SequenceFrame& f : b.frames)
                                      out.push_back(f.colour.clone());
                                  return out;
                              }};
    const std::string card = exportModel(straight.out, exported, {}, 0, true, {copy});
    for (const char* text : {"| no AA |", "| copy |", "| network |", "### Test split", "`temporal`"})
        EXPECT_NE(card.find(text), std::string::npos) << text;
    std::map<std::string, std::string> metadata;
    const nn::Model shipped = nn::loadModel(exported, &metadata);
    const nlohmann::json scores = nlohmann::json::parse(metadata.at("dejag.card"));
    EXPECT_EQ(scores["validation"]["copy"], scores["validation"]["no AA"]);
    EXPECT_TRUE(fs::exists(folder_ + "/models/dejag-temporal-test.md"));
    // A NaN in a batch is skipped, the weights untouched by it.
    TrainConfig poisoned = tinyConfig("poisoned");
    TrainFaults poison;
    poison.poisonSteps = {5};
    EXPECT_EQ(trainModel(poisoned, {}, poison).skippedSteps, 1);
    for (float w : finalWeights(poisoned)) ASSERT_TRUE(std::isfinite(w));
    // A single-frame network, or single-frame settings, on sequences: one clear error.
    TrainConfig wrong = tinyConfig("wrong");
    wrong.arch = "fast";
    EXPECT_THROW(trainModel(wrong, {}), Error);
    wrong = tinyConfig("wrong2");
    wrong.adversarialFraction = 0.1;
    EXPECT_THROW(trainModel(wrong, {}), Error);
}

TEST(TemporalTraining, SingleFrameModelsAreRefused) {
    nn::Model fast = nn::Model::builtin("fast");
    try {
        Unroller unroller(fast, {});
        ADD_FAILURE() << "accepted a single-frame model";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("not a temporal network"), std::string::npos) << e.what();
    }
}

}  // namespace
}  // namespace dejag::train

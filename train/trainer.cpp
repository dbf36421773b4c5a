#include "train/trainer.h"

#include "train/bench_card.h"
#include "train/temporal.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <exception>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <numeric>
#include <optional>
#include <sstream>

#include "base/communicator.h"
#include "base/error.h"
#include "base/files.h"
#include "base/luma.h"
#include "base/progress.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "data/dataset.h"
#include "data/patches.h"
#include "data/plot.h"
#include "nn/inference.h"
#include "nn/init.h"
#include "nn/losses.h"
#include "nn/ops.h"
#include "nn/optim.h"
#include "nn/safetensors.h"

namespace dejag::train {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr const char* kCheckpointFormat = "dejag-checkpoint-1";
// A validation PSNR counts as better (a new best model, patience restarts) only above the best by this.
constexpr double kMinimumImprovementDb = 0.001;

std::string readText(const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error("cannot read '" + path + "'");
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
}

// A JSON file dejag wrote (run.json, dataset.json); a truncated or edited one is one error line.
json readJsonFile(const std::string& path) {
    try {
        return json::parse(readText(path));
    } catch (const json::exception& e) {
        throw Error("'" + path + "' is corrupt (not valid JSON: " + e.what() + ")");
    }
}

}  // namespace

nlohmann::json architectureFor(const std::string& arch) {
    if (arch == "seed2020" || arch == "fast" || arch == "kpn" || arch == "temporal" || arch == "accumulate")
        return nn::Model::builtinArchitecture(arch);
    // fast:W, fast:WxD, kpn:W, kpn:WxD, temporal:W, temporal:WxD, accumulate:W, accumulate:WxD: the
    // family with first width W and D levels (default 16 and 3).
    const std::string family = arch.substr(0, arch.find(':'));
    if ((family == "fast" || family == "kpn" || family == "temporal" || family == "accumulate") &&
        arch.size() > family.size()) {
        nn::ModelOptions options;
        std::string spec = arch.substr(family.size() + 1);
        // accumulate:WxD[+depth][+clip]: with the depth inputs; the history clamped to the neighbourhood.
        // kpn:WxD+guide: a guide method's result beside the frame (--guide-method).
        auto suffix = [&](const std::string& s, const std::string& of) {
            const bool has =
                family == of && spec.size() > s.size() && spec.substr(spec.size() - s.size()) == s;
            if (has) spec.resize(spec.size() - s.size());
            return has;
        };
        options.guide = suffix("+guide", "kpn");
        options.clip = suffix("+clip", "accumulate");
        options.depthInput = suffix("+depth", "accumulate");
        size_t used = 0, usedDepth = 0;
        try {
            options.width = std::stoi(spec, &used);
            if (used < spec.size() && spec[used] == 'x') {
                options.depth = std::stoi(spec.substr(used + 1), &usedDepth);
                used += 1 + usedDepth;
            }
        } catch (const std::exception&) {
            used = 0;
        }
        if (used == 0 || used != spec.size())
            throw Error("--arch '" + arch + "': expected " + family + ":WIDTH or " + family +
                        ":WIDTHxDEPTH (e.g. " + family + ":12x3" +
                        (family == "accumulate" ? ", or accumulate:8x2+depth+clip"
                         : family == "kpn"      ? ", or kpn:8x3+guide"
                                                : "") +
                        ")");
        return nn::Model::builtinArchitecture(family, options);
    }
    if (!fs::exists(arch))
        throw Error(
            "--arch '" + arch +
            "' is neither seed2020, fast, fast:WxD, kpn, kpn:WxD, temporal, temporal:WxD, accumulate, "
            "accumulate:WxD nor an existing "
            "JSON file");
    try {
        return json::parse(readText(arch));
    } catch (const json::exception& e) {
        throw Error("architecture file '" + arch + "' is not valid JSON: " + e.what());
    }
}

namespace {

json configToJson(const TrainConfig& c) {
    return {{"data", c.data},
            {"arch", c.arch},
            {"loss", c.loss},
            {"steps", c.steps},
            {"epochs", c.epochs},
            {"batch", c.batch},
            {"patch", c.patch},
            {"lr", c.learningRate},
            {"warmup_steps", c.warmupSteps},
            {"clip_norm", c.clipNorm},
            {"seed", c.seed},
            {"eval_every", c.evalEvery},
            {"checkpoint_every", c.checkpointEvery},
            {"validation_images", c.validationImages},
            {"patience", c.patience},
            {"families", c.families},
            {"adversarial", c.adversarialFraction},
            {"outlier_factor", c.outlierFactor},
            {"uniform_patches", c.uniformPatches},
            {"frames", c.frames},
            {"temporal_loss", c.temporalLoss},
            {"micro_batches", c.microBatches > 0 ? c.microBatches : communicator().size()},
            {"threads", threadCount()}};
}

// The settings that must not change when a run is resumed (they change the batches or the updates).
void requireSameRun(const json& saved, const json& now) {
    // A setting missing from an older run's record had the value it took before the option existed.
    const std::pair<const char*, json> keys[] = {
        {"arch", nullptr},
        {"loss", nullptr},
        {"batch", nullptr},
        {"patch", nullptr},
        {"lr", nullptr},
        {"warmup_steps", nullptr},
        {"clip_norm", nullptr},
        {"seed", nullptr},
        {"families", json::array()},
        {"adversarial", json(0.0)},
        {"outlier_factor", json(0.0)},
        {"uniform_patches", json(data::PatchOptions().uniformFraction)},
        {"frames", json(0)},
        {"temporal_loss", json(0.0)},
        {"micro_batches", json(1)}};
    for (const auto& [key, absent] : keys) {
        const json before = saved.contains(key) ? saved.at(key) : absent;
        if (before != now.at(key))
            throw Error(std::string("--resume: '") + key + "' was " + before.dump() + " in this run, now " +
                        now.at(key).dump() + "; resume with the same settings or start a new --out");
    }
}

// One row of the log: the mean loss since the previous row, and validation figures at evaluations.
struct LogRow {
    int64_t step = 0;
    double seconds = 0, learningRate = 0, loss = NAN;
    int64_t skipped = 0;
    bool evaluated = false;
    double psnr[int(data::Region::Count)]{}, ssim[int(data::Region::Count)]{};
};

json rowToJson(const LogRow& r) {
    json j = {{"step", r.step}, {"seconds", r.seconds}, {"lr", r.learningRate}, {"skipped", r.skipped}};
    j["loss"] = std::isfinite(r.loss) ? json(r.loss) : json(nullptr);
    if (r.evaluated) {
        for (int k = 0; k < int(data::Region::Count); ++k) {
            j[std::string("psnr_") + data::regionName(data::Region(k))] = r.psnr[k];
            j[std::string("ssim_") + data::regionName(data::Region(k))] = r.ssim[k];
        }
    }
    return j;
}

double numberOrNan(const json& j) {
    return j.is_null() ? NAN : j.get<double>();  // JSON has no NaN: nlohmann writes it as null
}

LogRow rowFromJson(const json& j) {
    LogRow r;
    r.step = j.at("step"), r.seconds = j.at("seconds"), r.learningRate = j.at("lr"),
    r.skipped = j.at("skipped");
    r.loss = numberOrNan(j.at("loss"));
    r.evaluated = j.contains("psnr_whole");
    if (r.evaluated)
        for (int k = 0; k < int(data::Region::Count); ++k) {
            r.psnr[k] = numberOrNan(j.at(std::string("psnr_") + data::regionName(data::Region(k))));
            r.ssim[k] = numberOrNan(j.at(std::string("ssim_") + data::regionName(data::Region(k))));
        }
    return r;
}

// The outlier guard (TrainConfig::outlierFactor): the losses' running average, and how many steps it
// needs before it judges. Early spikes do the most harm: Adam's second-moment estimate is young, so one
// huge gradient sets the step size of the next thousand steps (measured: an HDR batch let through at step
// 67 of 10,000 while the guard still waited for 100 steps). The loss falls fastest at the start, so an
// average of ten steps lags above the losses that follow and does not skip clean batches.
constexpr double kLossAverageRate = 0.02;
constexpr int64_t kOutlierWarmupSteps = 10;

// A running average that judges outliers against itself (the outlier guard keeps two: the loss, and the
// detail of the input). It starts from the median of the first kOutlierWarmupSteps values (an
// adversarial batch among them does not set it), then follows every value clipped to
// [average / K, K × average]: a lasting shift in the data moves it within a few hundred steps, a spike
// barely does.
struct RunningAverage {
    double average = 0;
    int64_t count = 0;
    std::vector<double> firstValues;  // until the warm-up ends

    bool judging() const { return count >= kOutlierWarmupSteps; }
    // How many times the average `value` is, when that is above `factor` or (`below`: low values are
    // judged too) below 1 / `factor`²; nothing when `value` is not an outlier. Low values get the wider
    // margin: a batch of flat patches is unusual, not wrong, while one with no detail at all says nothing.
    std::optional<double> outlierRatio(double value, double factor, bool below) const {
        if (factor <= 0 || !judging() || !(average > 0) || !std::isfinite(value)) return std::nullopt;
        const double ratio = value / average;
        if (ratio > factor || (below && ratio < 1 / (factor * factor))) return ratio;
        return std::nullopt;
    }
    void add(double value, double factor) {
        if (!std::isfinite(value)) return;
        ++count;
        if (count <= kOutlierWarmupSteps) {
            firstValues.push_back(value);
            std::vector<double> sorted = firstValues;
            std::nth_element(sorted.begin(), sorted.begin() + ptrdiff_t(sorted.size() / 2), sorted.end());
            average = sorted[sorted.size() / 2];
            if (count == kOutlierWarmupSteps) firstValues.clear();
            return;
        }
        if (factor > 0) value = std::clamp(value, average / factor, average * factor);
        average += kLossAverageRate * (value - average);
    }
    json toJson() const { return {{"average", average}, {"count", count}, {"first_values", firstValues}}; }
    static RunningAverage fromJson(const json& j) {
        RunningAverage r;
        r.average = j.at("average").get<double>(), r.count = j.at("count").get<int64_t>();
        r.firstValues = j.at("first_values").get<std::vector<double>>();
        return r;
    }
};

// The detail of a batch's input: the mean absolute difference between horizontal and vertical
// neighbours (every channel). Rendered frames, aliased or not, keep it within a small range; a constant
// batch has none and pure noise about a third of the value range.
double inputDetail(const nn::Tensor& input) {
    const int64_t planes = input.dim(0) * input.dim(1), h = input.dim(2), w = input.dim(3);
    double sum = 0;
    for (int64_t p = 0; p < planes; ++p) {
        const float* plane = input.data() + p * h * w;
        for (int64_t y = 0; y < h; ++y)
            for (int64_t x = 0; x < w; ++x) {
                const float v = plane[y * w + x];
                if (x + 1 < w) sum += std::abs(plane[y * w + x + 1] - v);
                if (y + 1 < h) sum += std::abs(plane[(y + 1) * w + x] - v);
            }
    }
    const double pairs = double(planes) * double(h * (w - 1) + (h - 1) * w);
    return pairs > 0 ? sum / pairs : 0;
}

// What a checkpoint holds besides the tensors.
struct TrainState {
    int64_t step = 0;  // steps done (the next batch is batch `step`)
    int64_t skipped = 0, badInRow = 0;
    double largestLoss = 0;
    int64_t adversarial[5] = {};
    RunningAverage loss, detail;  // the outlier guard's: finite losses, and the inputs' detail
    int64_t outliers = 0;
    double learningRateScale = 1.0;
    double bestPsnr = -1e30;
    int64_t bestStep = -1;
    int evaluationsSinceBest = 0;
    double seconds = 0;
    std::vector<LogRow> log;
};

void saveCheckpoint(const std::string& path, const nn::Model& model, const nn::Optimizer& optimizer,
                    const TrainState& state, const json& config) {
    const int64_t n = model.parameterCount();
    for (int64_t i = 0; i < n; ++i)
        if (!std::isfinite(model.parameterData()[i]))
            throw Error("refusing to checkpoint non-finite weights (parameter " + std::to_string(i) + ")");
    json meta = {{"step", state.step},
                 {"optimizer_steps", optimizer.steps()},
                 {"skipped", state.skipped},
                 {"bad_in_row", state.badInRow},
                 {"lr_scale", state.learningRateScale},
                 {"largest_loss", state.largestLoss},
                 {"adversarial", state.adversarial},
                 {"loss_average", state.loss.toJson()},
                 {"detail_average", state.detail.toJson()},
                 {"outliers", state.outliers},
                 {"best_psnr", state.bestPsnr},
                 {"best_step", state.bestStep},
                 {"evaluations_since_best", state.evaluationsSinceBest},
                 {"seconds", state.seconds},
                 {"config", config}};
    json log = json::array();
    for (const LogRow& r : state.log) log.push_back(rowToJson(r));
    meta["log"] = log;
    const nn::Optimizer& m = optimizer;
    nn::writeSafetensors(path,
                         {{"parameters", {n}, model.parameterData()},
                          {"adam.m", {int64_t(m.firstMoment().size())}, m.firstMoment().data()},
                          {"adam.v", {int64_t(m.secondMoment().size())}, m.secondMoment().data()}},
                         {{"dejag.format", kCheckpointFormat},
                          {"dejag.architecture", model.architecture().dump()},
                          {"dejag.state", meta.dump()}});
}

TrainState loadCheckpoint(const std::string& path, nn::Model& model, nn::Optimizer& optimizer, json* config) {
    const nn::SafetensorsFile file = nn::readSafetensors(path);
    auto meta = [&](const std::string& key) -> const std::string& {
        const auto it = file.metadata.find(key);
        if (it == file.metadata.end()) throw Error("checkpoint '" + path + "' has no " + key);
        return it->second;
    };
    if (meta("dejag.format") != kCheckpointFormat) throw Error("'" + path + "' is not a dejag checkpoint");
    if (json::parse(meta("dejag.architecture")) != model.architecture())
        throw Error("checkpoint '" + path + "' holds another architecture than --arch");
    const int64_t n = model.parameterCount();
    const std::vector<float> params = file.at("parameters").asFloat(), m = file.at("adam.m").asFloat(),
                             v = file.at("adam.v").asFloat();
    if (int64_t(params.size()) != n || int64_t(m.size()) != n || int64_t(v.size()) != n)
        throw Error("checkpoint '" + path + "' has the wrong number of parameters");
    std::copy(params.begin(), params.end(), model.parameterData());
    optimizer.firstMoment() = m, optimizer.secondMoment() = v;
    const json s = json::parse(meta("dejag.state"));
    optimizer.setSteps(s.at("optimizer_steps"));
    TrainState state;
    state.step = s.at("step"), state.skipped = s.at("skipped"), state.badInRow = s.at("bad_in_row");
    state.learningRateScale = s.at("lr_scale"), state.bestPsnr = s.at("best_psnr"),
    state.bestStep = s.at("best_step");
    state.evaluationsSinceBest = s.at("evaluations_since_best"), state.seconds = s.at("seconds");
    state.largestLoss = s.value("largest_loss", 0.0);  // (absent from checkpoints before stress runs)
    // (Runs recorded before the guard kept its warm-up values, or the input's detail, start them afresh.)
    if (s.contains("loss_average") && s["loss_average"].is_object())
        state.loss = RunningAverage::fromJson(s["loss_average"]);
    if (s.contains("detail_average")) state.detail = RunningAverage::fromJson(s["detail_average"]);
    state.outliers = s.value("outliers", int64_t(0));
    if (s.contains("adversarial"))
        for (size_t k = 0; k < 5; ++k) state.adversarial[k] = s.at("adversarial").at(k);
    for (const json& r : s.at("log")) state.log.push_back(rowFromJson(r));
    *config = s.at("config");
    return state;
}

void writeLogCsv(const std::string& path, const std::vector<LogRow>& log) {
    std::ostringstream csv;
    csv << "step,seconds,lr,loss,skipped,val_psnr,val_ssim,val_edge_psnr,val_edge_ssim,val_texture_psnr,"
           "val_texture_ssim\n";
    char line[512];
    for (const LogRow& r : log) {
        std::snprintf(line, sizeof line, "%lld,%.3f,%.6g,%s,%lld", (long long)r.step, r.seconds,
                      r.learningRate, std::isfinite(r.loss) ? std::to_string(r.loss).c_str() : "",
                      (long long)r.skipped);
        csv << line;
        for (int k = 0; k < int(data::Region::Count); ++k) {
            if (r.evaluated)
                std::snprintf(line, sizeof line, ",%.4f,%.6f", r.psnr[k], r.ssim[k]);
            else
                std::snprintf(line, sizeof line, ",,");
            csv << line;
        }
        csv << '\n';
    }
    writeTextFileAtomically(path, csv.str());
}

void writePlots(const std::string& run, const std::vector<LogRow>& log,
                const std::vector<MethodScores>& baselines, const std::string& name) {
    Plot loss{"training loss (" + name + ")", "step", "loss", {}, false, 900, 540};
    PlotSeries l;
    l.name = "train loss";
    for (const LogRow& r : log)
        if (std::isfinite(r.loss)) l.x.push_back(double(r.step)), l.y.push_back(r.loss);
    loss.series.push_back(l);
    // The loss of one batch is noisy: a centred moving mean over a window of 1/25 of the points (odd, at
    // least 3) shows the trend beside it.
    if (l.y.size() >= 5) {
        PlotSeries smooth;
        const size_t half = std::max<size_t>(1, l.y.size() / 50);
        smooth.name = "moving mean of " + std::to_string(2 * half + 1) + " logged steps";
        for (size_t i = 0; i < l.y.size(); ++i) {
            const size_t from = i >= half ? i - half : 0, to = std::min(l.y.size(), i + half + 1);
            double sum = 0;
            for (size_t j = from; j < to; ++j) sum += l.y[j];
            smooth.x.push_back(l.x[i]);
            smooth.y.push_back(sum / double(to - from));
        }
        loss.series.push_back(smooth);
    }
    writePlotPng((fs::path(run) / "loss.png").string(), loss);

    Plot validation{"validation PSNR, whole images (" + name + ")", "step", "PSNR (dB)", {}, false, 900, 540};
    PlotSeries net;
    net.name = "network";
    net.markers = true;
    for (const LogRow& r : log)
        if (r.evaluated) net.x.push_back(double(r.step)), net.y.push_back(r.psnr[0]);
    validation.series.push_back(net);
    if (!net.x.empty())
        for (const MethodScores& b : baselines) {
            PlotSeries line;
            line.name = b.name;
            line.x = {net.x.front(), net.x.back()};
            line.y = {b.summary.psnr[0], b.summary.psnr[0]};
            validation.series.push_back(line);
        }
    writePlotPng((fs::path(run) / "validation.png").string(), validation);
}

bool allFinite(const nn::Tensor& t) {
    return t.findNonFinite() < 0;
}

}  // namespace

// ---- Running a model on whole images ------------------------------------------------------------------

Image runNetwork(nn::FrameNetwork& network, const Image& rgb, const Image* guide) {
    if (rgb.channels() != 3) throw Error("the network filter needs an RGB image, got " + rgb.describe());
    if (guide && (guide->width != rgb.width || guide->height != rgb.height || guide->channels() != 3))
        throw Error("the guide " + guide->describe() + " does not match the image " + rgb.describe());
    Image result(rgb.width, rgb.height, Image::defaultChannelNames(3), rgb.storage);
    network.run(rgb.pixels.data(), result.pixels.data(), rgb.width, rgb.height, 3,
                guide ? guide->pixels.data() : nullptr);
    return result;
}

namespace {

using Transform = std::function<void(float* rgb, int width, int height)>;

// The network on an RGB image as dejag filter runs it: after the input method (if any), beside the guide
// method's result on the frame it sees (if any).
Image runThrough(nn::FrameNetwork& network, const Image& rgb, const Transform& input,
                 const Transform& guide) {
    if (!input && !guide) return runNetwork(network, rgb);
    Image frame = rgb;
    if (input) input(frame.pixels.data(), frame.width, frame.height);
    if (!guide) return runNetwork(network, frame);
    Image guideImage = frame;
    guide(guideImage.pixels.data(), guideImage.width, guideImage.height);
    return runNetwork(network, frame, &guideImage);
}

}  // namespace

std::vector<MethodScores> scoreMethods(const std::vector<data::EvaluationItem>& items,
                                       const std::vector<Method>& methods, bool grey) {
    std::vector<MethodScores> scores;
    std::vector<data::ImageScore> reference;  // the first method's, per item
    for (const Method& method : methods) {
        MethodScores s;
        s.name = method.name;
        std::vector<double> ms;
        for (size_t i = 0; i < items.size(); ++i) {
            const data::EvaluationItem& item = items[i];
            const auto start = std::chrono::steady_clock::now();
            Image out = method.apply(item.input);
            ms.push_back(
                std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count());
            if (grey && out.channels() == 3) out = data::lumaImage(out);
            const data::ImageScore score = data::scoreImage(item, out);
            s.summary.add(score);
            if (scores.empty()) {
                reference.push_back(score);
                continue;
            }
            // A flat item (its input already data::kFlatItemPsnr from the truth) has nothing to harm.
            if (reference[i].region[0].psnr >= data::kFlatItemPsnr) continue;
            const double gain = score.region[0].psnr - reference[i].region[0].psnr;
            s.harmed += gain < -kHarmDb;
            const int texture = int(data::Region::Texture);
            s.textureHarmed += score.region[texture].scored && reference[i].region[texture].scored &&
                               score.region[texture].psnr < reference[i].region[texture].psnr;
            if (s.worstItem.empty() || gain < s.worstGainDb)
                s.worstGainDb = gain, s.worstItem = item.family + "/" + item.id;
        }
        s.summary.finish();
        s.millisecondsPerImage = median(ms);
        scores.push_back(std::move(s));
    }
    return scores;
}

// ---- Training -----------------------------------------------------------------------------------------

// ---- Adversarial batches (stress testing) -------------------------------------------------------------

const char* adversarialKindName(AdversarialKind kind) {
    switch (kind) {
        case AdversarialKind::Constant:
            return "constant";
        case AdversarialKind::Noise:
            return "noise";
        case AdversarialKind::HdrSpikes:
            return "hdr-spikes";
        case AdversarialKind::Poisoned:
            return "poisoned";
        default:
            return "none";
    }
}

namespace {
// A generator for (seed, step) of its own stream, apart from the sampler's and the initialiser's.
nn::Rng adversarialRng(uint64_t seed, int64_t step) {
    return nn::Rng(seed * 0x9E3779B97F4A7C15ull + uint64_t(step), 0xAD5E);
}
}  // namespace

AdversarialKind adversarialKindAt(uint64_t seed, int64_t step, double fraction) {
    if (fraction <= 0) return AdversarialKind::None;
    nn::Rng rng = adversarialRng(seed, step);
    if (rng.uniform() >= fraction) return AdversarialKind::None;
    return AdversarialKind(1 + rng.below(4));
}

void makeAdversarial(nn::Tensor& input, nn::Tensor& target, AdversarialKind kind, uint64_t seed,
                     int64_t step) {
    nn::Rng rng = adversarialRng(seed, step);
    rng.uniform(), rng.below(4);  // the draws that chose the kind
    const int64_t n = input.dim(0), c = input.dim(1), plane = input.dim(2) * input.dim(3);
    float* in = input.data();
    float* out = target.data();
    switch (kind) {
        case AdversarialKind::Constant:
            for (int64_t i = 0; i < n; ++i) {
                const float level = rng.uniform();
                std::fill(in + i * c * plane, in + (i + 1) * c * plane, level);
                std::fill(out + i * c * plane, out + (i + 1) * c * plane, level);
            }
            break;
        case AdversarialKind::Noise:
            for (int64_t i = 0; i < input.numel(); ++i) in[i] = out[i] = rng.uniform();
            break;
        case AdversarialKind::HdrSpikes:
            for (int64_t i = 0; i < n; ++i)
                for (int64_t p = 0; p < plane; ++p) {
                    if (rng.uniform() >= 0.01f) continue;
                    const float value = std::pow(10.0f, rng.uniform(0.0f, 4.0f));
                    for (int64_t ch = 0; ch < c; ++ch)
                        in[(i * c + ch) * plane + p] = out[(i * c + ch) * plane + p] = value;
                }
            break;
        case AdversarialKind::Poisoned:
            for (int k = 0; k < 8; ++k) {
                const int64_t at = int64_t(rng.below(uint32_t(input.numel())));
                in[at] = k % 2 ? INFINITY : NAN;
            }
            break;
        default:
            break;
    }
}

// ---- The training loop, in its units ------------------------------------------------------------------
//
// trainModel() reads as the steps of training: next batch, guard, forward, loss, backward, update,
// evaluate, checkpoint. Each of these is a unit below: the configuration's checks, the run folder and its
// checkpoints (RunFolder), the batches with their adversarial and injected faults (Batches), the step
// guard (StepGuard), validation and the log (Validation). A new training mode replaces the forward and
// loss of a step and keeps the guard, the folder and the checkpoints as they are.

namespace {

void checkConfig(const TrainConfig& config) {
    if (config.data.empty() || config.out.empty()) throw Error("--data and --out are required");
    if (config.batch < 1 || config.patch < 16 || config.patch % 8 != 0)
        throw Error("--batch must be >= 1 and --patch a multiple of 8, at least 16");
    if (!(config.learningRate > 0) || !std::isfinite(config.learningRate))
        throw Error("--lr must be positive");
    if (config.steps < 0 || config.epochs < 0 || (config.steps == 0 && config.epochs == 0))
        throw Error("give --steps N or --epochs E (positive)");
    if (!(config.outlierFactor == 0 || (config.outlierFactor > 1 && std::isfinite(config.outlierFactor))))
        throw Error("--skip-outliers must be 0 (off) or above 1");
    if (!(config.uniformPatches >= 0 && config.uniformPatches <= 1))
        throw Error("--uniform-patches must be between 0 and 1");
    if (!(config.adversarialFraction >= 0 && config.adversarialFraction <= 0.9))
        throw Error("--adversarial must be between 0 and 0.9");
    if (config.evalEvery < 1 || config.checkpointEvery < 1)
        throw Error("evaluation and checkpoint intervals must be >= 1");
    // A batch is allocated whole (inputs, targets, every activation of it): bounded like an image.
    if (double(config.batch) * config.patch * config.patch * 3 > double(kMaxImageSamples))
        throw Error("--batch " + std::to_string(config.batch) + " of --patch " +
                    std::to_string(config.patch) +
                    " patches is more than dejag allocates (batch x patch^2 x 3 at most 2^28 samples)");
    if (config.warmupSteps < 0) throw Error("--warmup must be >= 0");
    if (!(config.clipNorm >= 0)) throw Error("--clip must be >= 0 (0: off)");
    if (config.validationImages < 0) throw Error("--val-images must be >= 0 (0: all)");
    if (config.patience < 0) throw Error("--patience must be >= 0 (0: never stop early)");
}

// A dataset's frame size (dataset.json).
struct DatasetSizeCheck {
    int width = 0, height = 0;
};
DatasetSizeCheck datasetSize(const std::string& folder) {
    std::ifstream in(fs::path(folder) / "dataset.json");
    const data::DatasetSpec spec = data::DatasetSpec::fromJson(json::parse(in, nullptr, false));
    return {spec.width, spec.height};
}

// The network --arch names, checked for what training does with it.
nn::Model buildModel(const TrainConfig& config, bool temporal) {
    std::string arch = config.arch;
    if (!config.guideMethod.empty()) {
        if (temporal) throw Error("--guide-method is for single-frame networks");
        if (!config.inputMethod.empty()) throw Error("--guide-method and --input-method: choose one");
        // kpn and kpn:WxD get their guide here; an architecture file must declare its own.
        if (arch == "kpn")  // the built-in kpn's own size
            arch = "kpn:" + std::to_string(nn::ModelOptions().width) + "x" +
                   std::to_string(nn::ModelOptions().depth);
        if (arch.rfind("kpn:", 0) == 0 && arch.find("+guide") == std::string::npos) arch += "+guide";
    }
    nlohmann::json architecture = architectureFor(arch);
    if (!config.inputMethod.empty()) {
        if (temporal) throw Error("--input-method is for single-frame networks");
        architecture["input_method"] = config.inputMethod;
    }
    if (!config.guideMethod.empty()) architecture["guide_method"] = config.guideMethod;
    const bool guided = architecture.value("input_channels", 0) == 6 && !temporal;
    if (guided && config.guideMethod.empty())
        throw Error("--arch '" + config.arch +
                    "' reads a guide beside the frame: name its method (--guide-method)");
    if (!config.guideMethod.empty() && !guided)
        throw Error(
            "--guide-method needs a network taking 6 channels (the frame and the guide), as "
            "kpn:WxD+guide does; --arch '" +
            config.arch + "' does not");
    nn::Model model = nn::Model::fromArchitecture(architecture);
    if (temporal) {
        const TemporalLayout layout = temporalLayout(model);  // throws for a single-frame network
        const nn::Shape out = model.outputShape({1, layout.inputChannels(), config.patch, config.patch});
        if (out[2] != config.patch || out[3] != config.patch)
            throw Error("the architecture does not return the size of a " + std::to_string(config.patch) +
                        " px patch");
        return model;
    }
    if (!config.inputMethod.empty() && model.inputChannels() != 3)
        throw Error("--input-method needs an RGB network");
    if (guided) {
        nn::FrameNetwork::borrowing(model);  // throws unless it takes the frame and guide and returns RGB
    } else if (model.inputChannels() != 1 && model.inputChannels() != 3)
        throw Error("the architecture takes " + std::to_string(model.inputChannels()) +
                    " channels; dejag trains on RGB (3) or luma (1)");
    if (model.outputChannels() != (guided ? 3 : model.inputChannels()))
        throw Error("the architecture outputs " + std::to_string(model.outputChannels()) + " channels for " +
                    std::to_string(model.inputChannels()) + " in");
    // The network learns to map a patch to its truth: its output has the patch's size (the loss and the
    // validation compare them pixel by pixel). Checked for the patch and for the stride-padded frames of
    // validation alike.
    for (const int side : {config.patch, 64}) {
        const nn::Shape out = model.outputShape({1, model.inputChannels(), side, side});  // throws if unfit
        if (out[2] != side || out[3] != side)
            throw Error("the architecture returns " + std::to_string(out[3]) + "x" + std::to_string(out[2]) +
                        " pixels for a " + std::to_string(side) + "x" + std::to_string(side) +
                        " input; an anti-aliasing network returns the size it is given");
    }
    return model;
}

// The run folder: made (and removed again if the run fails before writing anything into it, so a typo in
// --data leaves no empty run behind), locked for one process, and the files written into it.
class RunFolder {
  public:
    // A reader (the other ranks of a job) makes, locks and writes nothing: it reads what rank 0 writes.
    RunFolder(const std::string& folder, bool writer)
        : folder_(folder), made_(writer && !fs::exists(folder)), writer_(writer) {
        if (!writer) return;
        std::error_code madeError;
        fs::create_directories(folder, madeError);
        if (madeError || !fs::is_directory(folder))
            throw Error("cannot make the run folder '" + folder + "': " +
                        (madeError ? madeError.message() : std::string("a file of that name exists")));
        lock_.emplace(folder, "a training run");
    }
    RunFolder(const RunFolder&) = delete;
    RunFolder& operator=(const RunFolder&) = delete;
    ~RunFolder() {
        lock_.reset();
        if (!made_ || std::uncaught_exceptions() == 0) return;
        std::error_code ec;
        for (const auto& entry : fs::directory_iterator(folder_, ec))
            if (entry.path().filename() != FolderLock::kFileName) return;
        fs::remove_all(folder_, ec);
    }
    std::string path(const std::string& name) const { return (fs::path(folder_) / name).string(); }
    bool hasCheckpoint() const { return fs::exists(path("checkpoint.safetensors")); }
    TrainState loadCheckpoint(nn::Model& model, nn::Optimizer& optimizer, json* config) const {
        return train::loadCheckpoint(path("checkpoint.safetensors"), model, optimizer, config);
    }
    void saveCheckpoint(const nn::Model& model, const nn::Optimizer& optimizer, const TrainState& state,
                        const json& config) const {
        if (writer_) train::saveCheckpoint(path("checkpoint.safetensors"), model, optimizer, state, config);
    }
    void saveModel(const std::string& name, const nn::Model& model, const std::string& provenance,
                   int64_t step) const {
        if (writer_)
            nn::saveModel(path(name), model,
                          {{"dejag.provenance", provenance}, {"dejag.step", std::to_string(step)}});
    }
    void writeRunJson(const json& run) const {
        if (writer_) writeTextFileAtomically(path("run.json"), run.dump(2) + "\n");
    }
    bool writer() const { return writer_; }
    json readRunJson() const { return readJsonFile(path("run.json")); }

  private:
    std::string folder_;
    bool made_, writer_;
    std::optional<FolderLock> lock_;
};

// A micro-batch of a batch: items [from, from + count).
nn::Tensor itemsOf(const nn::Tensor& t, int64_t from, int64_t count) {
    if (t.numel() == 0) return {};
    nn::Shape shape = t.shape();
    const int64_t item = t.numel() / shape[0];
    shape[0] = count;
    nn::Tensor part(shape);
    std::copy_n(t.data() + from * item, count * item, part.data());
    return part;
}
data::Batch itemsOf(const data::Batch& b, int64_t from, int64_t count) {
    data::Batch part;
    part.input = itemsOf(b.input, from, count), part.target = itemsOf(b.target, from, count);
    part.texture = itemsOf(b.texture, from, count);
    if (!b.items.empty()) part.items.assign(b.items.begin() + from, b.items.begin() + from + count);
    part.edgeFraction = b.edgeFraction;
    return part;
}
data::SequenceBatch itemsOf(const data::SequenceBatch& b, int64_t from, int64_t count) {
    data::SequenceBatch part;
    for (const data::SequenceFrame& f : b.frames) {
        data::SequenceFrame g;
        g.colour = itemsOf(f.colour, from, count), g.truth = itemsOf(f.truth, from, count);
        g.motion = itemsOf(f.motion, from, count);
        g.depth = itemsOf(f.depth, from, count), g.previousDepth = itemsOf(f.previousDepth, from, count);
        if (!f.jitter.empty())
            g.jitter.assign(f.jitter.begin() + 2 * from, f.jitter.begin() + 2 * (from + count));
        if (!f.fresh.empty()) g.fresh.assign(f.fresh.begin() + from, f.fresh.begin() + from + count);
        part.frames.push_back(std::move(g));
    }
    if (!b.items.empty()) part.items.assign(b.items.begin() + from, b.items.begin() + from + count);
    return part;
}

// The global batch as M micro-batches shared by the job's ranks (TrainConfig::microBatches): rank r runs
// micro-batches [r k, r k + k) (k = ceil(M / ranks)), each forward and backward alone; their gradients
// are summed in micro-batch order by sumInOrder (base/communicator.h: each rank adds up its slice of
// every gradient, then the slices are gathered), so all ranks hold the same bits, and the same as one
// process running the M micro-batches. The gradient is the mean over the batch: the sum times 1 / M
// (each micro-batch's loss is its own mean); the loss, the gathered losses' mean.
class SharedBatch {
  public:
    SharedBatch(int microBatches, int batch, int64_t parameters)
        : M_(microBatches), size_(batch / microBatches), parameters_(parameters) {
        Communicator& comm = communicator();
        perRank_ = (M_ + comm.size() - 1) / comm.size();
        first_ = comm.rank() * perRank_;
        mine_.resize(size_t(perRank_ * parameters_));
        losses_.resize(size_t(perRank_)), allLosses_.resize(size_t(perRank_ * comm.size()));
    }
    // microLoss(from, count): the loss of items [from, from + count) with its gradient in the model's
    // (NaN: not finite, no gradient). Returns the batch's loss, its gradient in the model's.
    double run(nn::Model& model, const std::function<double(int64_t, int64_t)>& microLoss) {
        for (int64_t j = 0; j < perRank_; ++j) {
            const int64_t index = first_ + j;
            float* slot = mine_.data() + j * parameters_;
            double value = 0;  // (a rank's slots past the last micro-batch: not summed)
            if (index < M_) value = microLoss(index * size_, size_);
            if (index < M_ && std::isfinite(value))
                std::copy_n(model.gradientData(), parameters_, slot);
            else
                std::fill_n(slot, parameters_, 0.0f);
            losses_[size_t(j)] = value;
        }
        // The wait for the slowest rank, then the sum itself (timed apart: only the second is
        // communication).
        Communicator& comm = communicator();
        const auto seconds = [](auto from) {
            return std::chrono::duration<double>(std::chrono::steady_clock::now() - from).count();
        };
        auto start = std::chrono::steady_clock::now();
        if (comm.size() > 1) comm.barrier();
        waitSeconds += seconds(start);
        start = std::chrono::steady_clock::now();
        comm.allGather(losses_.data(), perRank_, allLosses_.data());
        double sum = 0;
        for (int64_t i = 0; i < M_; ++i) sum += allLosses_[size_t(i)];
        const double value = sum / double(M_);
        // (The same value on every rank: all sum, or none.)
        if (std::isfinite(value)) {
            float* g = model.gradientData();
            sumInOrder(mine_.data(), perRank_, M_, parameters_, g, scratch_);
            const float scale = 1.0f / float(M_);
            for (int64_t p = 0; p < parameters_; ++p) g[p] *= scale;
        }
        communicationSeconds += seconds(start);
        return value;
    }
    double communicationSeconds = 0, waitSeconds = 0;

  private:
    int64_t M_, size_, parameters_, perRank_ = 1, first_ = 0;
    std::vector<float> mine_, scratch_;
    std::vector<double> losses_, allLosses_;
};

// The batches of the steps: clean batches in the seed's order, with adversarial steps inserted between
// them (each starts from a copy of the next clean batch, which it leaves to the next clean step) and the
// test faults injected on their steps. The learning rate follows the clean batches.
class Batches {
  public:
    // depth: a temporal network that takes the depth buffers.
    Batches(const TrainConfig& config, const TrainFaults& faults, bool grey, int64_t stepsDone, bool temporal,
            bool depth = false, bool textureMask = false)
        : config_(config), faults_(faults) {
        for (int64_t s = 0; s < stepsDone; ++s) cleanBatches_ += kindAt(s) == AdversarialKind::None;
        if (temporal) {
            data::SequenceOptions options;
            options.depth = depth;
            options.patchSize = config.patch, options.batchSize = config.batch, options.seed = config.seed;
            options.frames = config.frames, options.families = config.families;
            sequences_.emplace(config.data, options);
            return;
        }
        data::PatchOptions patches;
        patches.patchSize = config.patch, patches.batchSize = config.batch, patches.seed = config.seed;
        patches.uniformFraction = config.uniformPatches;
        patches.grayscale = grey, patches.firstBatch = uint64_t(cleanBatches_);
        patches.families = config.families;
        patches.inputTransform = config.inputTransform;
        patches.guideTransform = config.guideTransform;
        patches.textureMask = textureMask;
        sampler_.emplace(config.data, patches);
    }
    AdversarialKind kindAt(int64_t step) const {
        return adversarialKindAt(config_.seed, step, config_.adversarialFraction);
    }
    // --steps (or --epochs) counts clean batches; adversarial steps come on top of them, so a stress run
    // and a clean run of the same length train on the same batches at the same learning rates.
    int64_t stepsFor(int64_t cleanSteps) const {
        if (config_.adversarialFraction <= 0) return cleanSteps;
        for (int64_t clean = 0, s = 0;; ++s) {
            if (clean == cleanSteps) return s;
            clean += kindAt(s) == AdversarialKind::None;
        }
    }
    struct Step {
        data::Batch batch;
        data::SequenceBatch sequence;  // a temporal network's
        AdversarialKind adversarial = AdversarialKind::None;
        int64_t schedulePosition = 0;
    };
    Step next(int64_t step) {
        Step s;
        s.adversarial = kindAt(step);
        s.schedulePosition = cleanBatches_;
        if (sequences_) {  // (no adversarial steps: checked with the configuration)
            s.sequence = sequences_->assemble(uint64_t(cleanBatches_++));
            faults_.inject(step, s.sequence.frames[0].colour, s.sequence.frames[0].truth);
            return s;
        }
        s.batch = s.adversarial == AdversarialKind::None ? sampler_->next()
                                                         : sampler_->assemble(uint64_t(cleanBatches_));
        if (s.adversarial == AdversarialKind::None) ++cleanBatches_;
        faults_.inject(step, s.batch.input, s.batch.target);
        if (s.adversarial != AdversarialKind::None)
            makeAdversarial(s.batch.input, s.batch.target, s.adversarial, config_.seed, step);
        return s;
    }

  private:
    const TrainConfig& config_;
    const TrainFaults& faults_;
    std::optional<data::PatchSampler> sampler_;
    std::optional<data::SequenceSampler> sequences_;
    int64_t cleanBatches_ = 0;  // clean batches taken before the next step
};

int64_t cleanStepsOf(const TrainConfig& config) {
    if (config.steps > 0) return config.steps;
    const auto items = data::readManifest(config.data);
    double pixels = 0;
    for (const json& r : items)
        if (r.value("split", "") == "train")
            pixels += double(r["size"][0].get<int>()) * r["size"][1].get<int>() *
                      (r.contains("sequence") ? r["sequence"]["length"].get<double>() : 1.0);
    // A step of a temporal network sees `frames` frames of each crop (0: the sequences' whole length).
    double frames = 1;
    if (!items.empty() && items.front().contains("sequence"))
        frames = config.frames > 0 ? config.frames : items.front()["sequence"]["length"].get<double>();
    return std::max<int64_t>(
        1, int64_t(std::ceil(config.epochs * pixels /
                             (double(config.batch) * config.patch * config.patch * frames))));
}

// The step guard: judges a step at each of its stages and keeps the books of the skipped ones. A step
// whose batch, loss or gradient is not finite is skipped (weights and optimizer untouched) and the
// learning rate halved unless the batch was at fault; with the outlier guard on, a batch unlike the data
// set's (its input's detail) or a loss far above the running average is skipped too, without counting
// towards giving up. maxBadSteps bad steps in a row end the run with an error.
class StepGuard {
  public:
    struct Skip {
        std::string reason;
        bool badData = false;  // the batch was at fault, not the learning rate
        bool outlier = false;  // skipped by the outlier guard: not counted towards giving up
    };
    StepGuard(const TrainConfig& config, TrainState& state) : config_(config), state_(state) {}

    // Before the forward pass: the batch is finite, and its input's detail is no outlier.
    std::optional<Skip> batch(const data::Batch& b) {
        const bool finite = allFinite(b.input) && allFinite(b.target);
        const double detail = finite && config_.outlierFactor > 0 ? inputDetail(b.input) : NAN;
        const std::optional<double> ratio = state_.detail.outlierRatio(detail, config_.outlierFactor, true);
        state_.detail.add(detail, config_.outlierFactor);
        if (!finite) return Skip{"the batch holds NaN or Inf", true, false};
        if (ratio) return Skip{outlierReason("the input's detail", detail, *ratio), true, true};
        return std::nullopt;
    }
    // A temporal network's batch: every frame finite.
    std::optional<Skip> sequence(const data::SequenceBatch& b) {
        for (const data::SequenceFrame& f : b.frames)
            if (!allFinite(f.colour) || !allFinite(f.truth) || !allFinite(f.motion) ||
                !std::all_of(f.jitter.begin(), f.jitter.end(), [](float v) { return std::isfinite(v); }))
                return Skip{"the batch holds NaN or Inf", true, false};
        return std::nullopt;
    }
    // After the loss: it and its gradient are finite, and the loss is no outlier.
    std::optional<Skip> loss(double value, const nn::Tensor& gradient) {
        const std::optional<double> ratio = state_.loss.outlierRatio(value, config_.outlierFactor, false);
        state_.loss.add(value, config_.outlierFactor);
        if (!std::isfinite(value) || !allFinite(gradient))
            return Skip{"the loss or its gradient is not finite"};
        if (ratio) return Skip{outlierReason("the loss", value, *ratio), true, true};
        return std::nullopt;
    }
    // After the backward pass and the clip: the gradient norm is finite.
    std::optional<Skip> gradient(double norm) {
        if (!std::isfinite(norm)) return Skip{"the gradient is not finite"};
        return std::nullopt;
    }
    // A skipped step: counted, logged, the learning rate halved if the step diverged; throws once
    // maxBadSteps steps in a row were bad.
    void skipped(const Skip& s) {
        ++state_.skipped;
        if (s.outlier)
            ++state_.outliers;
        else
            ++state_.badInRow;
        if (!s.badData) state_.learningRateScale *= 0.5;
        if (config_.json) {
            printLine(stdout, json{{"event", "skipped"},
                                   {"step", state_.step},
                                   {"reason", s.reason},
                                   {"lr_scale", state_.learningRateScale}}
                                  .dump());
        } else {
            char line[512];
            std::snprintf(line, sizeof line, "step %6lld  skipped: %s; learning rate scale %s %.3g",
                          (long long)state_.step, s.reason.c_str(), s.badData ? "stays" : "now",
                          state_.learningRateScale);
            printLine(stdout, line);
        }
        if (state_.badInRow >= config_.maxBadSteps)
            throw Error("training diverged: " + std::to_string(state_.badInRow) +
                        " bad steps in a row (last: " + s.reason + "); the last checkpoint in '" +
                        config_.out + "' is intact");
    }
    void taken(double loss) {
        state_.badInRow = 0;
        state_.largestLoss = std::max(state_.largestLoss, loss);
    }

  private:
    static std::string outlierReason(const char* what, double measured, double ratio) {
        char reason[128];
        std::snprintf(reason, sizeof reason, "%s %.4g is an outlier (%.2f times its running average)", what,
                      measured, ratio);
        return reason;
    }
    const TrainConfig& config_;
    TrainState& state_;
};

// Validation: the baselines scored once, the network at every evaluation; the evaluation lines.
// One frame's score: PSNR and SSIM of the whole frame (a sequence's frames carry no region masks), the
// output clamped to [0, 1] as it is displayed.
data::ImageScore frameScore(const nn::Tensor& rgb, const nn::Tensor& truth) {
    std::vector<float> clamped(size_t(rgb.numel()));
    double squared = 0;
    bool finite = true;
    for (int64_t i = 0; i < rgb.numel(); ++i) {
        finite = finite && std::isfinite(rgb.data()[i]);
        clamped[size_t(i)] = std::clamp(rgb.data()[i], 0.0f, 1.0f);
        const double d = double(clamped[size_t(i)]) - truth.data()[i];
        squared += d * d;
    }
    data::ImageScore score;
    score.nonFinite = !finite;
    data::RegionScore& whole = score.region[0];
    whole.scored = true;
    if (!finite) {
        whole.psnr = data::kWorstPsnr, whole.ssim = -1;
        return score;
    }
    const double mse = squared / double(rgb.numel());
    whole.psnr = mse > 0 ? 10 * std::log10(1.0 / mse) : 100.0;
    const nn::SsimLossDesc desc{rgb.dim(0), rgb.dim(1), rgb.dim(2), rgb.dim(3), 1.0};
    whole.ssim = 1.0 - nn::ssimLoss<float>(clamped.data(), truth.data(), desc);
    return score;
}

class Validation {
  public:
    Validation(const TrainConfig& config, const std::vector<Method>& baselines, bool grey, bool temporal,
               bool depth = false)
        : config_(config), grey_(grey) {
        if (temporal) {
            // Whole validation sequences, every frame after the first scored (the first has no history);
            // the baseline is the jittered frame itself (no AA).
            data::SequenceOptions options;
            options.depth = depth;
            options.split = data::Split::Validation, options.families = config.families;
            options.patchSize = 8, options.batchSize = 1;
            sequences_.emplace(config.data, options);
            const int count = config.validationImages > 0
                                  ? std::min(config.validationImages, sequences_->sequenceCount())
                                  : sequences_->sequenceCount();
            for (int i = 0; i < count; ++i)
                chosen_.push_back(int(int64_t(i) * sequences_->sequenceCount() / count));
            MethodScores none;
            none.name = "no aa";
            for (int i : chosen_) {
                const data::SequenceBatch b = sequences_->whole(i);
                for (size_t t = 1; t < b.frames.size(); ++t)
                    none.summary.add(frameScore(b.frames[t].colour, b.frames[t].truth));
            }
            none.summary.finish();
            baselineScores_.push_back(none);
            return;
        }
        items_ = data::loadEvaluationItems(config.data, data::Split::Validation, config.validationImages,
                                           config.families);
        baselineScores_ = scoreMethods(items_, baselines, grey);
    }
    size_t size() const { return sequences_ ? chosen_.size() : items_.size(); }
    const std::vector<data::EvaluationItem>& items() const { return items_; }
    const std::vector<MethodScores>& baselineScores() const { return baselineScores_; }
    json baselinesJson() const {
        json j = json::object();
        for (const MethodScores& b : baselineScores_)
            for (int k = 0; k < int(data::Region::Count); ++k)
                j[b.name][data::regionName(data::Region(k))] = {{"psnr", b.summary.psnr[k]},
                                                                {"ssim", b.summary.ssim[k]}};
        return j;
    }
    // Scores the model into the row; returns how many images its output was not finite on.
    int evaluate(nn::Model& model, LogRow& row) const {
        if (sequences_) {
            data::ScoreSummary summary;
            Unroller unroller(model);
            nn::Tensor rgb;
            for (int i : chosen_) {
                const data::SequenceBatch b = sequences_->whole(i);
                if (std::isnan(unroller.run(b, false))) {  // an output not finite: every frame the worst
                    nn::Tensor bad({1, 3, b.frames[0].colour.dim(2), b.frames[0].colour.dim(3)});
                    bad.data()[0] = NAN;
                    for (size_t t = 1; t < b.frames.size(); ++t)
                        summary.add(frameScore(bad, b.frames[t].truth));
                    continue;
                }
                for (size_t t = 1; t < b.frames.size(); ++t) {
                    const nn::Tensor& out = unroller.output(int(t));
                    rgb = nn::Tensor({1, 3, out.dim(2), out.dim(3)});
                    std::copy_n(out.data(), rgb.numel(), rgb.data());
                    summary.add(frameScore(rgb, b.frames[t].truth));
                }
            }
            summary.finish();
            row.evaluated = true;
            for (int k = 0; k < int(data::Region::Count); ++k)
                row.psnr[k] = summary.psnr[k], row.ssim[k] = summary.ssim[k];
            return summary.nonFiniteImages;
        }
        auto network = nn::FrameNetwork::borrowing(model);
        const std::vector<MethodScores> s =
            scoreMethods(items_,
                         {{"network",
                           [&](const Image& im) {
                               return runThrough(network, im, config_.inputTransform, config_.guideTransform);
                           }}},
                         grey_);
        row.evaluated = true;
        for (int k = 0; k < int(data::Region::Count); ++k)
            row.psnr[k] = s[0].summary.psnr[k], row.ssim[k] = s[0].summary.ssim[k];
        return s[0].summary.nonFiniteImages;
    }
    void print(const LogRow& r) const {
        if (config_.json) {
            json j = rowToJson(r);
            j["event"] = "evaluation";
            for (const MethodScores& b : baselineScores_) j["baseline_psnr_" + b.name] = b.summary.psnr[0];
            printLine(stdout, j.dump());
        } else {
            std::string base;
            for (const MethodScores& b : baselineScores_) {
                char t[64];
                std::snprintf(t, sizeof t, "%s%s %.2f", base.empty() ? "" : ", ", b.name.c_str(),
                              b.summary.psnr[0]);
                base += t;
            }
            // A figure with nothing to measure (no edge or texture pixels in the images scored) is "-".
            auto figure = [](double value) {
                char t[32];
                if (!std::isfinite(value)) return std::string("-");
                std::snprintf(t, sizeof t, "%.2f", value);
                return std::string(t);
            };
            char line[768];
            std::snprintf(line, sizeof line,
                          "step %6lld  loss %.5f  val PSNR %.2f dB (%s)  SSIM %.4f  edge %s  texture %s  "
                          "lr %.2e  %s",
                          (long long)r.step, r.loss, r.psnr[0], base.c_str(), r.ssim[0],
                          figure(r.psnr[1]).c_str(), figure(r.psnr[2]).c_str(), r.learningRate,
                          formatDuration(r.seconds).c_str());
            printLine(stdout, line);
        }
    }

  private:
    const TrainConfig& config_;
    bool grey_;
    std::optional<data::SequenceSampler> sequences_;
    std::vector<int> chosen_;  // the validation sequences scored
    std::vector<data::EvaluationItem> items_;
    std::vector<MethodScores> baselineScores_;
};

}  // namespace

bool TrainFaults::stopsAfter(int64_t sessionSteps) const {
    return stopAfterSteps > 0 && sessionSteps >= stopAfterSteps;
}

void TrainFaults::inject(int64_t step, nn::Tensor& input, nn::Tensor& target) const {
    if (std::find(poisonSteps.begin(), poisonSteps.end(), step) != poisonSteps.end())
        input.data()[input.numel() / 2] = NAN;
    if (std::find(spikeSteps.begin(), spikeSteps.end(), step) != spikeSteps.end())
        for (int64_t i = 0; i < target.numel(); ++i) target.data()[i] *= 1000.0f;
}

TrainResult trainModel(const TrainConfig& config, const std::vector<Method>& baselines,
                       const TrainFaults& faults) {
    checkConfig(config);
    const nn::CompositeLoss loss = nn::CompositeLoss::parse(config.loss);
    // A dataset of sequences trains a recurrent network, unrolled over each crop's frames.
    bool temporal = false;
    if (std::ifstream in(fs::path(config.data) / "dataset.json"); in) {
        const json spec = json::parse(in, nullptr, false);
        temporal = spec.is_object() && spec.contains("sequence");
    }
    if (temporal && loss.needsInput())
        throw Error("the loss's harm term trains single-frame networks; '" + config.data +
                    "' holds sequences");
    if (temporal && (config.adversarialFraction > 0 || config.outlierFactor > 0))
        throw Error("--adversarial and --skip-outliers train single-frame networks; '" + config.data +
                    "' holds sequences");
    if (!temporal && (config.frames != 0 || config.temporalLoss != 0))
        throw Error("--frames and --temporal-loss train on sequences; '" + config.data +
                    "' holds single frames");
    nn::Model model = buildModel(config, temporal);
    if (temporal) {  // validation runs whole sequences: their size must suit the network's strides
        const DatasetSizeCheck check = datasetSize(config.data);
        const nn::Shape out = model.outputShape({1, model.inputChannels(), check.height, check.width});
        if (out[2] != check.height || out[3] != check.width)
            throw Error("the network returns " + std::to_string(out[3]) + "x" + std::to_string(out[2]) +
                        " for the dataset's " + std::to_string(check.width) + "x" +
                        std::to_string(check.height) +
                        " frames: its strides need sizes that are multiples of them");
    }
    const bool grey = model.inputChannels() == 1;
    std::optional<Unroller> unroller;
    if (temporal) {
        TemporalLoss temporalLoss;
        temporalLoss.perFrame = loss, temporalLoss.temporalWeight = config.temporalLoss;
        unroller.emplace(model, temporalLoss);
    }

    // Rank 0 of a job makes, locks and writes the run folder; the others read it (docs/mpi.md).
    Communicator& comm = communicator();
    const bool writer = comm.rank() == 0;
    std::optional<RunFolder> runFolder;
    together([&] {
        if (writer) runFolder.emplace(config.out, true);
    });
    if (!writer) runFolder.emplace(config.out, false);
    const RunFolder& folder = *runFolder;
    json runConfig = configToJson(config);
    nn::OptimizerConfig adam;
    adam.learningRate = config.learningRate;
    nn::Optimizer optimizer(adam, model.parameterCount());
    TrainState state;
    if (folder.hasCheckpoint()) {
        if (!config.resume)
            throw Error(
                "'" + config.out +
                "' already holds a training run; add --resume to continue it or choose another --out");
        json saved;
        state = folder.loadCheckpoint(model, optimizer, &saved);
        // A resumed run keeps its micro-batches, whatever the number of processes now.
        if (config.microBatches == 0) runConfig["micro_batches"] = saved.value("micro_batches", json(1));
        requireSameRun(saved, runConfig);
        if (saved.at("threads") != runConfig.at("threads") && writer)
            std::fprintf(
                stderr,
                "dejag train: resuming with %d threads (the run used %s): results will differ in rounding\n",
                threadCount(), saved.at("threads").dump().c_str());
    } else {
        model.initialize(config.seed);
    }
    const int microBatches = runConfig.at("micro_batches").get<int>();
    if (microBatches < 1 || config.batch % microBatches != 0)
        throw Error("--batch " + std::to_string(config.batch) + " does not split into " +
                    std::to_string(microBatches) + " equal micro-batches" +
                    (config.microBatches == 0 ? " (one per process; set --micro-batches)" : ""));
    runConfig["ranks"] = comm.size();  // (recorded; a resumed run may use another number)
    std::optional<SharedBatch> shared;
    if (microBatches > 1 || comm.size() > 1)
        shared.emplace(microBatches, config.batch, model.parameterCount());

    const bool depthInput = temporal && temporalLayout(model).depth;
    Batches batches(config, faults, grey, state.step, temporal, depthInput, loss.needsMask());
    const int64_t cleanSteps = cleanStepsOf(config), totalSteps = batches.stepsFor(cleanSteps);
    runConfig["total_steps"] = totalSteps;
    nn::LrSchedule schedule;
    schedule.kind = nn::LrSchedule::Kind::Cosine;
    schedule.baseRate = config.learningRate, schedule.minRate = 0.05 * config.learningRate;
    schedule.warmupSteps = config.warmupSteps, schedule.totalSteps = cleanSteps;

    const Validation validation(config, baselines, grey, temporal, depthInput);
    {
        json run = {
            {"format", "dejag-run-1"},
            {"config", runConfig},
            {"command", config.commandLine},
            {"architecture", model.architecture()},
            {"parameters", model.parameterCount()},
            {"macs_per_pixel", double(model.macs({1, model.inputChannels(), 256, 256})) / (256.0 * 256.0)},
            {"validation_items", validation.size()},
            {"temporal", temporal}};
        const std::string datasetJson = (fs::path(config.data) / "dataset.json").string();
        if (fs::exists(datasetJson)) run["dataset"] = readJsonFile(datasetJson);
        run["validation_baselines"] = validation.baselinesJson();
        // A resumed run keeps the command that started it; each --resume is recorded after it.
        if (state.step > 0 && fs::exists(fs::path(config.out) / "run.json")) {
            const json before = folder.readRunJson();
            if (before.contains("command") && before["command"].is_string()) {
                run["command"] = before["command"];
                json resumed = before.value("resumed_commands", json::array());
                resumed.push_back(config.commandLine);
                run["resumed_commands"] = resumed;
            }
        }
        folder.writeRunJson(run);
    }

    TrainResult result;
    result.microBatches = microBatches;
    StepGuard guard(config, state);
    // Log rows fall on checkpoint steps too, so a resumed run logs the same rows.
    const int64_t logEvery =
        std::gcd(std::max<int64_t>(1, std::min<int64_t>(50, totalSteps / 200)), config.checkpointEvery);
    Progress progress("train", totalSteps, config.quiet || !writer);
    progress.resumeAt(state.step);
    const auto sessionStart = std::chrono::steady_clock::now();
    const double secondsBefore = state.seconds;
    auto elapsed = [&] {
        return secondsBefore +
               std::chrono::duration<double>(std::chrono::steady_clock::now() - sessionStart).count();
    };
    double lossSum = 0;
    int64_t lossCount = 0;
    double lastLoss = NAN;
    nn::Tensor dout, frameOnly;  // frameOnly: a guided batch's frames, for the harm term
    int64_t sessionSteps = 0;
    bool stop = config.patience > 0 && state.evaluationsSinceBest >= config.patience;  // finished early
    result.stoppedEarly = stop;
    while (state.step < totalSteps && !stop) {
        if (comm.rank() == faults.killRank && state.step == faults.killStep) std::raise(SIGKILL);
        // 1. The next batch.
        Batches::Step step = batches.next(state.step);
        if (step.adversarial != AdversarialKind::None) ++state.adversarial[int(step.adversarial)];
        const double rate = schedule.rateAt(step.schedulePosition) * state.learningRateScale;
        // 2. Guard, forward and loss, backward, guard again.
        double value = NAN;
        std::optional<StepGuard::Skip> skip =
            temporal ? guard.sequence(step.sequence) : guard.batch(step.batch);
        // The forward pass and the loss of a single-frame batch, its gradient in dout.
        const auto frameLoss = [&](const data::Batch& batch) {
            const nn::Tensor& out = model.forward(batch.input);
            if (dout.shape() != out.shape()) dout = nn::Tensor(out.shape());
            dout.zero();
            const nn::SsimLossDesc desc{out.dim(0), out.dim(1), out.dim(2), out.dim(3), 1.0};
            // The harm term measures against the frame (a guided input's first three channels).
            if (loss.needsInput() && batch.input.dim(1) == 6 && out.dim(1) == 3) {
                const nn::Tensor& in = batch.input;
                if (frameOnly.shape() != out.shape()) frameOnly = nn::Tensor(out.shape());
                const int64_t plane = in.dim(2) * in.dim(3);
                for (int64_t n = 0; n < in.dim(0); ++n)
                    std::copy_n(in.data() + n * 6 * plane, 3 * plane, frameOnly.data() + n * 3 * plane);
            }
            const nn::Tensor& given = batch.input.dim(1) == 6 ? frameOnly : batch.input;
            if (loss.needsInput() && given.shape() != out.shape())
                throw Error(
                    "the loss's harm term compares the output with the input, and this network's "
                    "output is not the input's shape");
            return loss.evaluate(dout.data(), out.data(), batch.target.data(), desc, 1.0,
                                 loss.needsInput() ? given.data() : nullptr,
                                 loss.needsMask() ? batch.texture.data() : nullptr);
        };
        if (!skip && shared) {
            // Micro-batches, shared by the job's ranks: each with its own forward and backward pass.
            value = shared->run(model, [&](int64_t from, int64_t count) -> double {
                if (temporal) return unroller->run(itemsOf(step.sequence, from, count), true);
                // (Kept until the backward pass, which reads the input the forward pass was given.)
                const data::Batch micro = itemsOf(step.batch, from, count);
                const double v = frameLoss(micro);
                if (!std::isfinite(v) || !allFinite(dout)) return NAN;
                model.backward(dout);
                return v;
            });
            skip = guard.loss(value, nn::Tensor());
        } else if (!skip && temporal) {
            // Forward over the frames and backpropagation through time: the gradient is in the model.
            value = unroller->run(step.sequence, true);
            skip = guard.loss(value, dout);
        } else if (!skip) {
            value = frameLoss(step.batch);
            skip = guard.loss(value, dout);
        }
        if (!skip) {
            if (!temporal && !shared) model.backward(dout);
            const double norm =
                config.clipNorm > 0
                    ? nn::clipGradientNorm(model.gradientData(), model.parameterCount(), config.clipNorm)
                    : nn::gradientNorm(model.gradientData(), model.parameterCount());
            skip = guard.gradient(norm);
        }
        // 3. Update, or skip the step.
        if (skip) {
            guard.skipped(*skip);
        } else {
            optimizer.step(model.parameterData(), model.gradientData(), rate);
            guard.taken(value);
            lossSum += value, ++lossCount, lastLoss = value;
        }
        if (step.adversarial != AdversarialKind::None && config.json) {
            printLine(stdout, json{{"event", "adversarial"},
                                   {"step", state.step},
                                   {"kind", adversarialKindName(step.adversarial)},
                                   {"loss", std::isfinite(value) ? json(value) : json(nullptr)},
                                   {"loss_average", state.loss.average},
                                   {"taken", !skip}}
                                  .dump());
        }
        ++state.step;
        // 4. Log and evaluate.
        const bool evaluationStep = state.step % config.evalEvery == 0 || state.step == totalSteps;
        if (state.step % logEvery == 0 || evaluationStep) {
            LogRow row;
            row.step = state.step, row.seconds = elapsed(), row.learningRate = rate,
            row.skipped = state.skipped;
            row.loss = lossCount ? lossSum / double(lossCount) : NAN;
            lossSum = 0, lossCount = 0;
            if (evaluationStep) {
                const int nonFinite = validation.evaluate(model, row);
                if (nonFinite > 0 && writer)
                    printLine(stderr,
                              "dejag train: step " + std::to_string(state.step) +
                                  ": the network's output is not finite on " + std::to_string(nonFinite) +
                                  " validation images; scored as the worst, never kept as the best model");
                if (nonFinite == 0 && row.psnr[0] > state.bestPsnr + kMinimumImprovementDb) {
                    state.bestPsnr = row.psnr[0], state.bestStep = state.step, state.evaluationsSinceBest = 0;
                    folder.saveModel("best.safetensors", model, config.commandLine, state.step);
                } else if (config.patience > 0 && ++state.evaluationsSinceBest >= config.patience) {
                    stop = true;
                    result.stoppedEarly = true;
                }
                state.log.push_back(row);
                validation.print(row);
                if (writer) {
                    writeLogCsv(folder.path("log.csv"), state.log);
                    writePlots(config.out, state.log, validation.baselineScores(), model.name());
                }
            } else {
                state.log.push_back(row);
            }
        }
        // 5. Checkpoint.
        if (state.step % config.checkpointEvery == 0 || state.step == totalSteps || stop) {
            state.seconds = elapsed();
            folder.saveCheckpoint(model, optimizer, state, runConfig);
        }
        char detail[96];
        if (state.bestStep >= 0)
            std::snprintf(detail, sizeof detail, "loss %.5f  best val %.2f dB", lastLoss, state.bestPsnr);
        else
            std::snprintf(detail, sizeof detail, "loss %.5f", lastLoss);
        progress.advance(1, detail);
        if (faults.stopsAfter(++sessionSteps) && state.step < totalSteps && !stop) {
            state.seconds = elapsed();
            folder.saveCheckpoint(model, optimizer, state, runConfig);
            result.interrupted = true;
            result.steps = state.step;
            return result;
        }
    }
    progress.finish();
    folder.saveModel("final.safetensors", model, config.commandLine, state.step);
    state.seconds = elapsed();
    folder.saveCheckpoint(model, optimizer, state, runConfig);
    {
        json run = folder.readRunJson();
        run["finished"] = {{"steps", state.step},
                           {"seconds", state.seconds},
                           {"skipped", state.skipped},
                           {"best_step", state.bestStep},
                           {"best_psnr", state.bestPsnr},
                           {"stopped_early", result.stoppedEarly},
                           {"ranks", comm.size()},
                           {"micro_batches", microBatches},
                           {"communication_seconds", shared ? shared->communicationSeconds : 0.0},
                           {"wait_seconds", shared ? shared->waitSeconds : 0.0}};
        folder.writeRunJson(run);
    }
    result.steps = state.step, result.skippedSteps = state.skipped, result.seconds = state.seconds;
    result.bestPsnr = state.bestPsnr, result.bestStep = state.bestStep;
    result.largestLoss = state.largestLoss;
    result.outlierSteps = state.outliers;
    result.communicationSeconds = shared ? shared->communicationSeconds : 0.0;
    result.waitSeconds = shared ? shared->waitSeconds : 0.0;
    std::copy(std::begin(state.adversarial), std::end(state.adversarial), result.adversarialSteps);
    return result;
}

// ---- Export and the model card ------------------------------------------------------------------------

namespace {

std::string scoreTable(const std::vector<MethodScores>& scores) {
    std::ostringstream t;
    t << "| method | PSNR (dB) | SSIM | edge PSNR | edge SSIM | texture PSNR | texture SSIM | ms per image "
         "| harmed | texture harmed | worst gain dB |\n"
         "|---|---|---|---|---|---|---|---|---|---|---|\n";
    char line[512];
    for (size_t m = 0; m < scores.size(); ++m) {
        const MethodScores& s = scores[m];
        // A region no image has (no edge or texture pixels) is "-", not nan.
        auto figure = [](double value, const char* format) {
            if (!std::isfinite(value)) return std::string("-");
            char text[32];
            std::snprintf(text, sizeof text, format, value);
            return std::string(text);
        };
        t << "| " << s.name;
        for (int k = 0; k < int(data::Region::Count); ++k)
            t << " | " << figure(s.summary.psnr[k], "%.2f") << " | " << figure(s.summary.ssim[k], "%.4f");
        std::snprintf(line, sizeof line, " | %.1f |", s.millisecondsPerImage);
        t << line;
        if (m == 0) {
            t << "  |  |  |\n";
            continue;
        }
        std::snprintf(line, sizeof line, " %d | %d | %+.2f (%s) |\n", s.harmed, s.textureHarmed,
                      s.worstGainDb, s.worstItem.c_str());
        t << line;
    }
    return t.str();
}

json scoresToJson(const std::vector<MethodScores>& scores) {
    json j = json::object();
    for (const MethodScores& s : scores) {
        json m = {{"ms_per_image", s.millisecondsPerImage},
                  {"harmed", s.harmed},
                  {"texture_harmed", s.textureHarmed},
                  {"worst_gain_db", s.worstGainDb},
                  {"worst_item", s.worstItem}};
        for (int k = 0; k < int(data::Region::Count); ++k)
            m[data::regionName(data::Region(k))] = {
                {"psnr", s.summary.psnr[k]}, {"ssim", s.summary.ssim[k]}, {"images", s.summary.images[k]}};
        j[s.name] = m;
    }
    return j;
}

}  // namespace

namespace {

// The fields of a model card's JSON (the model file's dejag.card) that every run has.
// "1 image", "48 images".
std::string countOf(int64_t n, const char* noun) {
    return std::to_string(n) + " " + noun + (n == 1 ? "" : "s");
}

// The card's training commands: the one that started the run, then each --resume.
std::string commandsMarkdown(const json& runJson) {
    std::string md = "Command:\n\n```\n" + runJson.at("command").get<std::string>() + "\n```\n\n";
    if (runJson.contains("resumed_commands") && runJson["resumed_commands"].is_array() &&
        !runJson["resumed_commands"].empty()) {
        md += "Resumed with:\n\n```\n";
        for (const json& c : runJson["resumed_commands"]) md += c.get<std::string>() + "\n";
        md += "```\n\n";
    }
    return md;
}

// The dataset's own recipe: the `dejag data generate` command that makes it again (from its dataset.json).
std::string datasetMarkdown(const json& runJson, const std::string& dataFolder) {
    if (!runJson.contains("dataset")) return "Data: `" + dataFolder + "`.\n\n";
    const json& d = runJson.at("dataset");
    std::string command;
    try {
        const data::DatasetSpec spec = data::DatasetSpec::fromJson(d);
        auto join = [](const std::vector<std::string>& v) {
            std::string out;
            for (const std::string& x : v) out += (out.empty() ? "" : ",") + x;
            return out;
        };
        std::ostringstream c;
        c << "dejag data generate --families " << join(spec.families);
        if (!spec.testFamilies.empty()) c << " --test-families " << join(spec.testFamilies);
        c << " --count " << spec.count << " --size " << spec.width << "x" << spec.height << " --truth "
          << spec.truthSamples << (spec.adaptive ? " --adaptive" : "") << " --seed " << spec.seed;
        if (spec.closeUps > 0) c << " --close-ups " << spec.closeUps;
        if (spec.sequences())
            c << " --sequence-length " << spec.sequenceLength << " --jitter-spread " << spec.jitterSpread;
        c << " --out " << dataFolder;
        command = c.str();
    } catch (const Error&) {
        return "Data: `" + dataFolder + "`, made by `dejag data generate` with " + d.dump() + ".\n\n";
    }
    return "Data: `" + dataFolder + "`, made by\n\n```\n" + command +
           "\n```\n\nthen the training command above (the same `--threads` gives the same weights) and "
           "`dejag train export`.\n\n";
}

// The truth's sample count, as the dataset recorded it.
std::string truthName(const json& runJson) {
    if (runJson.contains("dataset") && runJson["dataset"].contains("truth_samples"))
        return "the " + std::to_string(runJson["dataset"]["truth_samples"].get<int>()) + "-sample truth";
    return "the truth";
}

json cardFields(const json& runJson, const std::string& name, const nn::Model& model) {
    const json& finished = runJson.at("finished");
    return {{"name", name},
            {"architecture", model.name()},
            {"parameters", model.parameterCount()},
            {"macs_per_pixel", runJson.at("macs_per_pixel")},
            {"command", runJson.at("command")},
            {"training_seconds", finished.at("seconds")},
            {"steps", finished.at("steps")},
            {"best_step", finished.at("best_step")}};
}

// The architecture table of a model card.
std::string architectureTable(const nn::Model& model) {
    std::ostringstream md;
    md << "| node | op | inputs | out channels | kernel | stride | activation "
          "|\n|---|---|---|---|---|---|---|\n";
    const auto graph = model.graph();
    for (const nn::GraphNode& n : graph) {
        std::string inputs;
        for (int i : n.inputs)
            inputs += (inputs.empty() ? "" : ", ") + (i < 0 ? std::string("input") : graph[size_t(i)].name);
        const nn::OpCard cells = nn::opDef(n.op).card(n);
        md << "| " << n.name << " | " << nn::graphOpName(n.op) << " | " << inputs << " | "
           << cells.outChannels << " | " << cells.kernel << " | " << cells.stride << " | " << cells.activation
           << " |\n";
    }
    return md.str();
}

// A method's scores over sequences: PSNR and SSIM of every frame after each sequence's first, and the
// flicker against the truth's own change (docs/metrics.md) over the same frames.
struct SequenceScores {
    std::string name;
    data::ScoreSummary summary;
    double flickerSum = 0;
    int flickerFrames = 0;
    double flicker() const { return flickerFrames ? flickerSum / flickerFrames : NAN; }
};

std::vector<SequenceScores> scoreSequences(const data::SequenceSampler& sequences, int limit,
                                           const std::vector<SequenceMethod>& methods) {
    std::vector<SequenceScores> scores(methods.size());
    for (size_t m = 0; m < methods.size(); ++m) scores[m].name = methods[m].name;
    const int count = limit > 0 ? std::min(limit, sequences.sequenceCount()) : sequences.sequenceCount();
    for (int k = 0; k < count; ++k) {
        const data::SequenceBatch batch =
            sequences.whole(int(int64_t(k) * sequences.sequenceCount() / count));
        for (size_t m = 0; m < methods.size(); ++m) {
            const std::vector<nn::Tensor> frames = methods[m].apply(batch);
            for (size_t t = 1; t < frames.size(); ++t) {
                scores[m].summary.add(frameScore(frames[t], batch.frames[t].truth));
                if (batch.frames[t].fresh[0]) continue;
                const nn::Tensor &now = frames[t], &before = frames[t - 1];
                const nn::Tensor &truth = batch.frames[t].truth, &truthBefore = batch.frames[t - 1].truth;
                double sum = 0;
                for (int64_t i = 0; i < now.numel(); ++i) {
                    auto shown = [](float v) {
                        return std::round(std::clamp(v, 0.0f, 1.0f) * 255.0f) / 255.0f;
                    };
                    sum += std::abs(double(shown(now.data()[i]) - shown(before.data()[i])) -
                                    double(shown(truth.data()[i]) - shown(truthBefore.data()[i])));
                }
                scores[m].flickerSum += sum / double(now.numel()), ++scores[m].flickerFrames;
            }
        }
    }
    for (SequenceScores& s : scores) s.summary.finish();
    return scores;
}

std::string sequenceTable(const std::vector<SequenceScores>& scores) {
    std::ostringstream md;
    md << "| method | PSNR dB | SSIM | flicker |\n|---|---|---|---|\n";
    char line[256];
    for (const SequenceScores& s : scores) {
        std::snprintf(line, sizeof line, "| %s | %.2f | %.4f | %.5f |\n", s.name.c_str(), s.summary.psnr[0],
                      s.summary.ssim[0], s.flicker());
        md << line;
    }
    return md.str();
}

json sequenceScoresJson(const std::vector<SequenceScores>& scores) {
    json j = json::object();
    for (const SequenceScores& s : scores)
        j[s.name] = {{"psnr", s.summary.psnr[0]}, {"ssim", s.summary.ssim[0]}, {"flicker", s.flicker()}};
    return j;
}

// The export of a temporal network's run: scored on whole sequences next to the jittered frames and the
// given baselines; its card.
std::string exportTemporal(const json& runJson, nn::Model model, const std::string& modelPath,
                           const std::vector<SequenceMethod>& baselines, int testSequences, bool quiet,
                           const std::optional<BenchCardSection>& bench) {
    const std::string dataFolder = runJson.at("config").at("data");
    std::vector<SequenceMethod> methods;
    methods.push_back({"no AA", [](const data::SequenceBatch& b) {
                           std::vector<nn::Tensor> out;
                           for (const data::SequenceFrame& f : b.frames) out.push_back(f.colour.clone());
                           return out;
                       }});
    for (const SequenceMethod& m : baselines) methods.push_back(m);
    methods.push_back({"network", [&](const data::SequenceBatch& b) {
                           Unroller unroller(model);
                           unroller.run(b, false);
                           std::vector<nn::Tensor> out;
                           for (size_t t = 0; t < b.frames.size(); ++t) {
                               const nn::Tensor& o = unroller.output(int(t));
                               nn::Tensor rgb({1, 3, o.dim(2), o.dim(3)});
                               std::copy_n(o.data(), rgb.numel(), rgb.data());
                               out.push_back(std::move(rgb));
                           }
                           return out;
                       }});
    if (!quiet)
        std::fprintf(stderr, "scoring on the validation and test sequences of '%s'...\n", dataFolder.c_str());
    data::SequenceOptions options;
    options.patchSize = 8, options.batchSize = 1, options.depth = true;
    options.split = data::Split::Validation;
    options.families = runJson.at("config").value("families", std::vector<std::string>{});
    const auto validation = scoreSequences(data::SequenceSampler(dataFolder, options), 0, methods);
    options.split = data::Split::Test, options.families.clear();
    const data::SequenceSampler testSequencesData(dataFolder, options);
    const auto test = scoreSequences(testSequencesData, testSequences, methods);
    const int testCount = testSequences > 0 ? std::min(testSequences, testSequencesData.sequenceCount())
                                            : testSequencesData.sequenceCount();

    const std::string name = fs::path(modelPath).stem().string();
    const json& config = runJson.at("config");
    const json& finished = runJson.at("finished");
    json card = cardFields(runJson, name, model);
    card.update({{"validation", sequenceScoresJson(validation)}, {"test", sequenceScoresJson(test)}});
    if (bench) card["bench_taa"] = bench->summary;
    nn::saveModel(
        modelPath, model,
        {{"dejag.provenance", runJson.at("command").get<std::string>()}, {"dejag.card", card.dump()}});

    std::ostringstream md;
    char line[512];
    md << "# " << name << "\n\n";
    md << "Trained by dejag (`dejag train` on a dataset of sequences, then `dejag train export`). A "
          "recurrent "
          "network: per frame it takes the jittered frame, its own previous output (RGB and state, warped by "
          "the motion inside the network), the motion and the jitter, and returns the frame and its state "
          "(docs/train.md); `dejag filter --method cnn-temporal` runs it.\n\n";
    md << "## Architecture\n\n";
    std::snprintf(line, sizeof line, "`%s`: %lld parameters, %.0f multiply-adds per input pixel.\n\n",
                  model.name().c_str(), (long long)model.parameterCount(),
                  runJson.at("macs_per_pixel").get<double>());
    md << line << architectureTable(model);
    md << "\n## Training\n\n" << commandsMarkdown(runJson);
    std::snprintf(
        line, sizeof line,
        "Loss `%s` per frame plus %g times the temporal term, unrolled over %d frames; Adam, learning "
        "rate %g (cosine decay to 5 %%, %lld warm-up steps), gradient norm clipped at %g, batch %d "
        "crops of %d px, seed %llu, threads: %d.\n",
        config.at("loss").get<std::string>().c_str(), config.value("temporal_loss", 0.0),
        config.value("frames", 0), config.at("lr").get<double>(),
        (long long)config.at("warmup_steps").get<int64_t>(), config.at("clip_norm").get<double>(),
        config.at("batch").get<int>(), config.at("patch").get<int>(),
        (unsigned long long)config.at("seed").get<uint64_t>(), config.at("threads").get<int>());
    md << line;
    std::snprintf(line, sizeof line,
                  "%lld steps in %s of wall time on this machine (2 cores); %lld steps skipped by the NaN "
                  "guard; the weights are those of step %lld, the best validation PSNR (%.2f dB).\n\n",
                  (long long)finished.at("steps").get<int64_t>(),
                  formatDuration(finished.at("seconds")).c_str(),
                  (long long)finished.at("skipped").get<int64_t>(),
                  (long long)finished.at("best_step").get<int64_t>(), finished.at("best_psnr").get<double>());
    md << line;
    md << datasetMarkdown(runJson, dataFolder);
    md << "## Results\n\nEvery frame after each sequence's first (which has no history), whole sequences at "
          "their size: PSNR and SSIM against the frame's own truth on sRGB-encoded values (data range 1), "
          "mean over frames; flicker = mean |(X_t - X_t-1) - (R_t - R_t-1)| on 8-bit values "
          "(docs/metrics.md), "
          "over the frames whose history continues.\n\n";
    md << "### Test split (" << countOf(testCount, "sequence") << " of families never trained on)\n\n";
    md << sequenceTable(test) << "\n### Validation split\n\n" << sequenceTable(validation);
    if (bench) md << "\n" << bench->markdown;
    const std::string cardPath = (fs::path(modelPath).parent_path() / (name + ".md")).string();
    writeTextFileAtomically(cardPath, md.str());
    return md.str();
}

}  // namespace

std::string exportModel(const std::string& run, const std::string& modelPath,
                        const std::vector<Method>& baselines, int testImages, bool quiet,
                        const std::vector<SequenceMethod>& sequenceBaselines, const std::string& benchTaa,
                        const InputMethodFactory& inputMethod) {
    const std::string runJsonPath = (fs::path(run) / "run.json").string();
    const std::string bestPath = (fs::path(run) / "best.safetensors").string();
    requireReadableFile(runJsonPath);
    requireReadableFile(bestPath);
    const json runJson = readJsonFile(runJsonPath);
    if (!runJson.contains("finished"))
        throw Error("the run in '" + run + "' has not finished (resume it first)");
    // Before the scoring, which takes minutes: where the model goes.
    if (const fs::path folder = fs::path(modelPath).parent_path();
        !folder.empty() && !fs::is_directory(folder))
        throw Error("cannot write '" + modelPath + "': folder '" + folder.string() + "' does not exist");
    // (Read before the scoring too: a bad file fails at once.)
    std::optional<BenchCardSection> bench;
    if (!benchTaa.empty()) bench = benchTaaSection(benchTaa);
    if (runJson.value("temporal", false)) {
        std::map<std::string, std::string> metadata;
        return exportTemporal(runJson, nn::loadModel(bestPath, &metadata), modelPath, sequenceBaselines,
                              testImages, quiet, bench);
    }
    std::map<std::string, std::string> metadata;
    nn::Model model = nn::loadModel(bestPath, &metadata);
    // A network trained after an input method is scored after it, as dejag filter runs it.
    const std::string inputName = model.architecture().value("input_method", "");
    const std::string guideName = model.architecture().value("guide_method", "");
    Transform through, guide;
    if (!inputName.empty()) {
        if (!inputMethod)
            throw Error("the network runs after " + inputName + ", which this export cannot make");
        through = inputMethod(inputName);
    }
    if (!guideName.empty()) {
        if (!inputMethod)
            throw Error("the network reads " + guideName + "'s result, which this export cannot make");
        guide = inputMethod(guideName);
    }
    const bool grey = model.inputChannels() == 1;
    const std::string dataFolder = runJson.at("config").at("data");
    std::vector<Method> methods;
    for (const Method& b : baselines) methods.push_back(b);
    auto network = nn::FrameNetwork::borrowing(model);
    methods.push_back({"network", [&](const Image& im) { return runThrough(network, im, through, guide); }});
    if (!quiet)
        std::fprintf(stderr, "scoring on the validation and test splits of '%s'...\n", dataFolder.c_str());
    const std::vector<std::string> families =
        runJson.at("config").value("families", std::vector<std::string>{});
    const auto validation = scoreMethods(
        data::loadEvaluationItems(dataFolder, data::Split::Validation, 0, families), methods, grey);
    const auto testItems = data::loadEvaluationItems(dataFolder, data::Split::Test, testImages);
    const auto test = scoreMethods(testItems, methods, grey);

    const std::string name = fs::path(modelPath).stem().string();
    const json& config = runJson.at("config");
    const json& finished = runJson.at("finished");
    json card = cardFields(runJson, name, model);
    card.update({{"validation", scoresToJson(validation)}, {"test", scoresToJson(test)}});
    if (bench) card["bench_taa"] = bench->summary;
    std::map<std::string, std::string> out = {{"dejag.provenance", runJson.at("command").get<std::string>()},
                                              {"dejag.card", card.dump()}};
    nn::saveModel(modelPath, model, out);

    std::ostringstream md;
    char line[512];
    md << "# " << name << "\n\n";
    md << "Trained by dejag (`dejag train`, then `dejag train export`). Input: "
       << (grey ? "luma " + std::to_string(kLumaRed).substr(0, 4) + " R + " +
                      std::to_string(kLumaGreen).substr(0, 4) + " G + " +
                      std::to_string(kLumaBlue).substr(0, 4) + " B"
                : std::string("RGB"))
       << " of sRGB-encoded values in [0, 1]"
       << (guideName.empty() ? "" : ", and " + guideName + "'s result on it (RGB) beside it")
       << "; output: " << (guideName.empty() ? "the same" : "RGB") << ", anti-aliased.\n\n";
    md << "## Architecture\n\n";
    std::snprintf(line, sizeof line, "`%s`: %lld parameters, %.0f multiply-adds per input pixel.\n\n",
                  model.name().c_str(), (long long)model.parameterCount(),
                  runJson.at("macs_per_pixel").get<double>());
    md << line << architectureTable(model);
    if (!inputName.empty())
        md << "\nThe network runs after " << inputName << " (trained with `--input-method " << inputName
           << "`): `dejag filter --method cnn` runs " << inputName
           << " on the frame first, and the scores below "
           << "are of the pair.\n";
    if (!guideName.empty())
        md << "\nThe network reads " << guideName
           << "'s result beside the frame (trained with `--guide-method " << guideName
           << "`): each pixel is a blend of the frame's 3x3 neighbourhood and " << guideName
           << "'s pixel, and `dejag filter --method cnn` runs " << guideName << " on the frame first.\n";
    md << "\n## Training\n\n" << commandsMarkdown(runJson);
    std::snprintf(
        line, sizeof line,
        "Loss `%s`, Adam, learning rate %g (cosine decay to 5 %%, %lld warm-up steps), gradient norm clipped "
        "at %g, batch %d patches of %d px, seed %llu, threads: %d.\n",
        config.at("loss").get<std::string>().c_str(), config.at("lr").get<double>(),
        (long long)config.at("warmup_steps").get<int64_t>(), config.at("clip_norm").get<double>(),
        config.at("batch").get<int>(), config.at("patch").get<int>(),
        (unsigned long long)config.at("seed").get<uint64_t>(), config.at("threads").get<int>());
    md << line;
    std::snprintf(
        line, sizeof line,
        "%lld steps in %s of wall time on this machine (2 cores); %lld steps skipped by the NaN guard; "
        "the weights are those of step %lld, the best validation PSNR (%.2f dB on %s).\n\n",
        (long long)finished.at("steps").get<int64_t>(), formatDuration(finished.at("seconds")).c_str(),
        (long long)finished.at("skipped").get<int64_t>(), (long long)finished.at("best_step").get<int64_t>(),
        finished.at("best_psnr").get<double>(),
        countOf(runJson.value("validation_items", config.at("validation_images").get<int>()), "image")
            .c_str());
    md << line;
    md << datasetMarkdown(runJson, dataFolder);
    md << "## Results\n\nPSNR and SSIM against " << truthName(runJson)
       << ", on sRGB-encoded values (data range 1), mean over images; "
          "edge = pixels within 1 px of a geometric edge, texture = detailed pixels at least 3 px from one "
          "(data/evaluation.h). Times are single images of the split's size on this machine.\n\n";
    md << "### Test split (" << countOf(int64_t(testItems.size()), "image")
       << " of families never trained on)\n\n";
    md << scoreTable(test) << "\n";
    {
        std::string trained = "every family but the test ones";
        if (!families.empty()) {
            trained.clear();
            for (const std::string& f : families) trained += (trained.empty() ? "" : ", ") + f;
        }
        md << "### Validation split (held-out items of the families trained on: " << trained << ")\n\n"
           << scoreTable(validation) << "\n";
    }
    auto gain = [](const std::vector<MethodScores>& s, size_t method) {
        return s[method].summary.psnr[0] - s[0].summary.psnr[0];
    };
    if (test.size() >= 2) {
        md << "Gain over the first row (" << test[0].name << ") on the test split:";
        for (size_t m = 1; m < test.size(); ++m) {
            std::snprintf(line, sizeof line, " %s %+.2f dB%s", test[m].name.c_str(), gain(test, m),
                          m + 1 < test.size() ? "," : ".\n");
            md << line;
        }
    }
    // The quality targets of the shipped models, checked on the test split (families never trained on).
    auto find = [](const std::vector<MethodScores>& s, const std::string& method) -> const MethodScores* {
        for (const MethodScores& m : s)
            if (m.name == method) return &m;
        return nullptr;
    };
    const MethodScores *none = find(test, "no AA"), *fxaa = find(test, "FXAA"), *net = find(test, "network");
    auto verdict = [](bool ok) { return ok ? "**met**" : "**not met**"; };
    if (none && fxaa && net) {
        md << "\n### Targets on the test split\n\n";
        std::snprintf(line, sizeof line, "- network > FXAA > no AA (PSNR): %s (%.2f > %.2f > %.2f dB)\n",
                      verdict(net->summary.psnr[0] > fxaa->summary.psnr[0] &&
                              fxaa->summary.psnr[0] > none->summary.psnr[0]),
                      net->summary.psnr[0], fxaa->summary.psnr[0], none->summary.psnr[0]);
        md << line;
    }
    // The grey replica also against the thesis' own protocol: trained and tested on one kind of scene, so
    // the validation split (held-out images of the families trained on) is its test set.
    const MethodScores *valNone = find(validation, "no AA"), *valFxaa = find(validation, "FXAA"),
                       *valNet = find(validation, "network");
    if (grey && valNone && valFxaa && valNet) {
        std::snprintf(line, sizeof line,
                      "\n### The thesis' protocol (its test images were of the scene it trained on: here "
                      "the validation split)\n\n- network > FXAA > no AA (PSNR): %s (%.2f > %.2f > %.2f "
                      "dB)\n",
                      verdict(valNet->summary.psnr[0] > valFxaa->summary.psnr[0] &&
                              valFxaa->summary.psnr[0] > valNone->summary.psnr[0]),
                      valNet->summary.psnr[0], valFxaa->summary.psnr[0], valNone->summary.psnr[0]);
        md << line;
    }
    if (none && fxaa && net && !grey) {  // dejag-fast's targets; the grey replica: the published ordering
        const double netGain = net->summary.psnr[0] - none->summary.psnr[0],
                     fxaaGain = fxaa->summary.psnr[0] - none->summary.psnr[0];
        std::snprintf(line, sizeof line,
                      "- PSNR gain over no AA at least twice FXAA's: %s (%+.2f dB against 2 x %+.2f dB)\n",
                      verdict(netGain >= 2 * fxaaGain), netGain, fxaaGain);
        md << line;
        std::snprintf(line, sizeof line, "- SSIM at least FXAA's: %s (%.4f against %.4f)\n",
                      verdict(net->summary.ssim[0] >= fxaa->summary.ssim[0]), net->summary.ssim[0],
                      fxaa->summary.ssim[0]);
        md << line;
        const int t = int(data::Region::Texture);
        std::snprintf(
            line, sizeof line,
            "- texture pixels never below no AA: %s (PSNR %.2f against %.2f dB, SSIM %.4f against %.4f)\n",
            verdict(net->summary.psnr[t] >= none->summary.psnr[t] &&
                    net->summary.ssim[t] >= none->summary.ssim[t]),
            net->summary.psnr[t], none->summary.psnr[t], net->summary.ssim[t], none->summary.ssim[t]);
        md << line;
    }
    if (bench) md << "\n" << bench->markdown;
    const std::string cardPath = (fs::path(modelPath).parent_path() / (name + ".md")).string();
    writeTextFileAtomically(cardPath, md.str());
    return md.str();
}

}  // namespace dejag::train

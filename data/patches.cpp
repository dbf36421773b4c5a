#include "data/patches.h"

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "base/error.h"
#include "base/luma.h"
#include "base/random.h"
#include "base/thread_pool.h"
#include "data/evaluation.h"
#include "data/image.h"

namespace dejag::data {

namespace fs = std::filesystem;

namespace {

uint64_t mix(uint64_t z) {
    return splitMix64(z);
}

class Random {
  public:
    explicit Random(uint64_t seed) : state_(seed) {}
    uint64_t next() { return state_ = mix(state_); }
    double uniform(double low = 0, double high = 1) { return unitInterval(next(), low, high); }
    int below(int n) { return n <= 1 ? 0 : int(next() % uint64_t(n)); }

  private:
    uint64_t state_;
};

uint16_t encode(float linear) {
    const float s = std::clamp(linearToSrgb(std::max(linear, 0.0f)), 0.0f, 1.0f);
    return uint16_t(std::lround(s * 65535.0f));
}

}  // namespace

PatchSampler::PatchSampler(const std::string& folder, const PatchOptions& options) : options_(options) {
    if (options.patchSize < 8 || options.batchSize < 1)
        throw Error("patch size must be >= 8 and batch size >= 1");
    if (options.guideTransform && options.grayscale) throw Error("a guide goes beside RGB patches, not luma");
    const int P = options.patchSize;
    auto loadItem = [&](const nlohmann::json& record, Item& item) {
        item.index = record["index"].get<int>();
        const Image input =
            readImage((fs::path(folder) / record["files"]["input"]["path"].get<std::string>()).string());
        const Image truth =
            readImage((fs::path(folder) / record["files"]["truth"]["path"].get<std::string>()).string());
        if (input.width < P || input.height < P)
            throw Error("patches of " + std::to_string(P) + " px do not fit item " +
                        record["id"].get<std::string>() + " (" + std::to_string(input.width) + "x" +
                        std::to_string(input.height) + ")");
        item.width = input.width, item.height = input.height;
        const int r = input.findChannel("R"), id = input.findChannel("id.ID"),
                  depth = input.findChannel("depth.Z");
        if (r < 0 || truth.findChannel("R") < 0)
            throw Error("item " + record["id"].get<std::string>() + " has no colour");
        const size_t n = input.pixelCount();
        item.input.resize(n * 3), item.truth.resize(n * 3), item.aliasing.assign(n, 0);
        for (size_t p = 0; p < n; ++p)
            for (int c = 0; c < 3; ++c) {
                item.input[p * 3 + size_t(c)] =
                    encode(input.pixels[p * size_t(input.channels()) + size_t(r + c)]);
                item.truth[p * 3 + size_t(c)] =
                    encode(truth.pixels[p * size_t(truth.channels()) + size_t(truth.findChannel("R") + c)]);
            }
        // Aliasing sources: an ID or depth discontinuity with a neighbour, or an aliased-vs-truth
        // difference above 4 % of the range (texture and shading aliasing have no discontinuity).
        for (int y = 0; y < item.height; ++y)
            for (int x = 0; x < item.width; ++x) {
                const size_t p = size_t(y) * size_t(item.width) + size_t(x);
                bool source = false;
                if (id >= 0 && depth >= 0)
                    for (const auto& [dx, dy] :
                         {std::pair{1, 0}, std::pair{0, 1}, std::pair{-1, 0}, std::pair{0, -1}}) {
                        const int nx = x + dx, ny = y + dy;
                        if (nx < 0 || ny < 0 || nx >= item.width || ny >= item.height) continue;
                        const float d0 = input.at(x, y, depth), d1 = input.at(nx, ny, depth);
                        source = source || input.at(x, y, id) != input.at(nx, ny, id) ||
                                 std::abs(d0 - d1) > 0.05f * std::min(d0, d1);
                    }
                for (int c = 0; c < 3 && !source; ++c)
                    source = std::abs(int(item.input[p * 3 + size_t(c)]) -
                                      int(item.truth[p * 3 + size_t(c)])) > 2621;
                item.aliasing[p] = source;
                if (source) item.aliasingPixels.push_back(int(p));
            }
        auto transformed = [&](const auto& transform) {
            std::vector<float> rgb(n * 3);
            for (size_t i = 0; i < rgb.size(); ++i) rgb[i] = float(item.input[i]) / 65535.0f;
            transform(rgb.data(), item.width, item.height);
            std::vector<uint16_t> result(n * 3);
            for (size_t i = 0; i < rgb.size(); ++i)
                result[i] = uint16_t(std::lround(std::clamp(rgb[i], 0.0f, 1.0f) * 65535.0f));
            return result;
        };
        if (options.textureMask) {
            if (id < 0 || depth < 0)
                throw Error("the loss's texharm term needs id and depth buffers, and item " +
                            record["id"].get<std::string>() + " has none");
            EvaluationItem regions;
            regions.id = record["id"].get<std::string>();
            regions.truth = Image(item.width, item.height, Image::defaultChannelNames(3));
            for (size_t i = 0; i < n * 3; ++i) regions.truth.pixels[i] = float(item.truth[i]) / 65535.0f;
            computeRegionMasks(regions, input);
            const Image& mask = regions.masks[int(Region::Texture)];
            item.texture.resize(n);
            for (size_t p = 0; p < n; ++p) item.texture[p] = mask.pixels[p] > 0.5f;
        }
        if (options.inputTransform) item.input = transformed(options.inputTransform);
        if (options.guideTransform) item.guide = transformed(options.guideTransform);
    };
    // Items load in parallel (reading EXRs dominates), each into its own slot: the order stays the
    // manifest's whatever the thread count.
    std::vector<nlohmann::json> records;
    for (nlohmann::json& record : readManifest(folder)) {
        if (record.contains("sequence"))
            throw Error("'" + folder + "' is a dataset of sequences; the patch sampler takes single frames");
        if (record["split"] == splitName(options.split) &&
            (options.families.empty() || std::find(options.families.begin(), options.families.end(),
                                                   record.value("family", "")) != options.families.end()))
            records.push_back(std::move(record));
    }
    items_.resize(records.size());
    parallelFor(0, int64_t(records.size()), 1, [&](int64_t first, int64_t last) {
        for (int64_t i = first; i < last; ++i) loadItem(records[size_t(i)], items_[size_t(i)]);
    });
    if (items_.empty()) {
        if (!std::filesystem::exists(std::filesystem::path(folder) / "manifest.jsonl"))
            throw Error("'" + folder +
                        "' is not a dataset (no manifest.jsonl; dejag data generate makes one)");
        std::string families;
        for (const std::string& f : options.families) families += (families.empty() ? "" : ",") + f;
        throw Error("'" + folder + "' has no " + std::string(splitName(options.split)) + " items" +
                    (families.empty() ? "" : " of the families " + families) + " to sample patches from");
    }
    produced_ = options.firstBatch;
    worker_ = std::thread([this] { produce(); });
}

PatchSampler::~PatchSampler() {
    {
        std::lock_guard<std::mutex> lock(mutex_);
        stopping_ = true;
    }
    changed_.notify_all();
    if (worker_.joinable()) worker_.join();
}

void PatchSampler::produce() {
    while (true) {
        uint64_t index;
        {
            std::unique_lock<std::mutex> lock(mutex_);
            changed_.wait(lock, [&] { return stopping_ || int(ready_.size()) < options_.prefetch; });
            if (stopping_) return;
            index = produced_++;
        }
        Batch batch = assemble(index);
        {
            std::lock_guard<std::mutex> lock(mutex_);
            ready_.push_back(std::move(batch));
        }
        changed_.notify_all();
    }
}

Batch PatchSampler::next() {
    std::unique_lock<std::mutex> lock(mutex_);
    changed_.wait(lock, [&] { return !ready_.empty(); });
    Batch batch = std::move(ready_.front());
    ready_.pop_front();
    lock.unlock();
    changed_.notify_all();
    return batch;
}

Batch PatchSampler::assemble(uint64_t index) const {
    const int P = options_.patchSize, N = options_.batchSize, C = channels();
    const bool guided = bool(options_.guideTransform);
    Random random(mix(options_.seed ^ mix(index + 0x1234)));
    Batch batch;
    batch.input = nn::Tensor({N, guided ? 2 * C : C, P, P});
    batch.target = nn::Tensor({N, C, P, P});
    if (options_.textureMask) batch.texture = nn::Tensor({N, 1, P, P});
    int64_t edgePixels = 0;
    for (int n = 0; n < N; ++n) {
        const Item& item = items_[size_t(random.below(int(items_.size())))];
        batch.items.push_back(item.index);
        int x0, y0;
        if (random.uniform() < options_.uniformFraction || item.aliasingPixels.empty()) {
            x0 = random.below(item.width - P + 1), y0 = random.below(item.height - P + 1);
        } else {
            // A patch holding a random aliasing pixel, at a random place inside it (not always centred).
            const int p = item.aliasingPixels[size_t(random.below(int(item.aliasingPixels.size())))];
            const int px = p % item.width, py = p / item.width;
            x0 = std::clamp(px - random.below(P), 0, item.width - P);
            y0 = std::clamp(py - random.below(P), 0, item.height - P);
        }
        const int orientation =
            options_.augment ? random.below(8) : 0;  // bit 0: flip x, 1: flip y, 2: transpose
        const double gain = 1 + random.uniform(-options_.brightnessJitter, options_.brightnessJitter);
        double channelGain[3];
        for (double& g : channelGain)
            g = gain * (1 + random.uniform(-options_.hueJitter, options_.hueJitter));
        for (int y = 0; y < P; ++y)
            for (int x = 0; x < P; ++x) {
                int sx = x, sy = y;
                if (orientation & 4) std::swap(sx, sy);
                if (orientation & 1) sx = P - 1 - sx;
                if (orientation & 2) sy = P - 1 - sy;
                const size_t p = size_t(y0 + sy) * size_t(item.width) + size_t(x0 + sx);
                edgePixels += item.aliasing[p];
                if (options_.textureMask) batch.texture.at(n, 0, y, x) = float(item.texture[p]);
                float in[3], out[3];
                for (int c = 0; c < 3; ++c) {
                    in[c] = float(std::min(1.0, item.input[p * 3 + size_t(c)] / 65535.0 * channelGain[c]));
                    out[c] = float(std::min(1.0, item.truth[p * 3 + size_t(c)] / 65535.0 * channelGain[c]));
                }
                if (C == 1) {
                    batch.input.at(n, 0, y, x) = luma(in);
                    batch.target.at(n, 0, y, x) = luma(out);
                } else {
                    for (int c = 0; c < 3; ++c)
                        batch.input.at(n, c, y, x) = in[c], batch.target.at(n, c, y, x) = out[c];
                    if (guided)
                        for (int c = 0; c < 3; ++c)
                            batch.input.at(n, 3 + c, y, x) = float(
                                std::min(1.0, item.guide[p * 3 + size_t(c)] / 65535.0 * channelGain[c]));
                }
            }
    }
    batch.edgeFraction = double(edgePixels) / double(int64_t(N) * P * P);
    return batch;
}

}  // namespace dejag::data

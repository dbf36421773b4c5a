#include "data/sequences.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>

#include "base/error.h"
#include "base/random.h"
#include "base/thread_pool.h"
#include "data/image.h"

namespace dejag::data {

namespace fs = std::filesystem;

namespace {

class Random {
  public:
    explicit Random(uint64_t seed) : state_(seed) {}
    uint64_t next() { return state_ = splitMix64(state_); }
    int below(int n) { return n <= 1 ? 0 : int(next() % uint64_t(n)); }

  private:
    uint64_t state_;
};

}  // namespace

SequenceSampler::SequenceSampler(const std::string& folder, const SequenceOptions& options)
    : options_(options) {
    if (options.patchSize < 8 || options.batchSize < 1)
        throw Error("patch size must be >= 8 and batch size >= 1");
    DatasetSpec spec;
    {
        std::ifstream in(fs::path(folder) / "dataset.json");
        if (!in) throw Error("'" + folder + "' is not a dataset (no dataset.json)");
        spec = DatasetSpec::fromJson(nlohmann::json::parse(in, nullptr, false));
    }
    if (!spec.sequences())
        throw Error("'" + folder +
                    "' holds single frames; a temporal network trains on sequences "
                    "(dejag data generate --sequence-length K)");
    frames_ = options.frames > 0 ? options.frames : spec.sequenceLength;
    if (frames_ < 2 || frames_ > spec.sequenceLength)
        throw Error("--frames " + std::to_string(frames_) + ": the dataset's sequences have " +
                    std::to_string(spec.sequenceLength) + " frames (2 or more are needed)");
    std::vector<nlohmann::json> records;
    for (nlohmann::json& r : readManifest(folder))
        if (r["split"] == splitName(options.split) &&
            (options.families.empty() || std::find(options.families.begin(), options.families.end(),
                                                   r.value("family", "")) != options.families.end()))
            records.push_back(std::move(r));
    if (records.empty())
        throw Error("'" + folder + "' has no " + std::string(splitName(options.split)) + " sequences");
    sequences_.resize(records.size());
    const int P = options.patchSize;
    // Sequences load in parallel, each into its own slot: the order stays the manifest's.
    parallelFor(0, int64_t(records.size()), 1, [&](int64_t first, int64_t last) {
        for (int64_t i = first; i < last; ++i) {
            const nlohmann::json& r = records[size_t(i)];
            Sequence& s = sequences_[size_t(i)];
            try {
                s.index = r["index"].get<int>();
                s.length = r["sequence"]["length"].get<int>();
                if (s.length < frames_)
                    throw Error("sequence " + r["id"].get<std::string>() + " has " +
                                std::to_string(s.length) + " frames, fewer than the " +
                                std::to_string(frames_) + " of a crop");
                const size_t pixels =
                    size_t(r["size"][0].get<int>()) * size_t(r["size"][1].get<int>()) * size_t(s.length);
                s.colour.reserve(3 * pixels), s.truth.reserve(3 * pixels), s.motion.reserve(2 * pixels);
                if (options.depth) s.depth.reserve(2 * pixels);
                const fs::path dir =
                    fs::path(folder) / r.at("files").at("render").at("path").get<std::string>();
                std::ifstream in(dir);
                const nlohmann::json sidecar = nlohmann::json::parse(in, nullptr, false);
                if (!sidecar.is_object() || !sidecar.contains("frames") ||
                    int(sidecar["frames"].size()) != s.length)
                    throw Error("sequence " + r["id"].get<std::string>() +
                                ": render.json does not list its " + std::to_string(s.length) + " frames");
                for (int k = 0; k < s.length; ++k) {
                    char key[32];
                    std::snprintf(key, sizeof key, "frame_%04d", k);
                    const Image frame = readImage(
                        (fs::path(folder) / r.at("files").at(key).at("path").get<std::string>()).string());
                    std::snprintf(key, sizeof key, "truth_%04d", k);
                    const Image truth = readImage(
                        (fs::path(folder) / r.at("files").at(key).at("path").get<std::string>()).string());
                    if (k == 0) {
                        s.width = frame.width, s.height = frame.height;
                        if (s.width < P || s.height < P)
                            throw Error("crops of " + std::to_string(P) + " px do not fit sequence " +
                                        r["id"].get<std::string>() + " (" + std::to_string(s.width) + "x" +
                                        std::to_string(s.height) + ")");
                    }
                    const int red = frame.findChannel("R"), mx = frame.findChannel("motion.X"),
                              my = frame.findChannel("motion.Y"), tr = truth.findChannel("R"),
                              dz = frame.findChannel("depth.Z"), pz = frame.findChannel("prevdepth.Z");
                    if (red < 0 || mx < 0 || my < 0 || tr < 0 || dz < 0 || pz < 0 || frame.width != s.width ||
                        truth.width != s.width || frame.height != s.height || truth.height != s.height)
                        throw Error("sequence " + r["id"].get<std::string>() + ", frame " +
                                    std::to_string(k) +
                                    ": colour, motion or truth missing or of another size");
                    const size_t plane = size_t(s.width) * size_t(s.height);
                    for (int c = 0; c < 3; ++c)
                        for (size_t p = 0; p < plane; ++p) {
                            const int x = int(p % size_t(s.width)), y = int(p / size_t(s.width));
                            s.colour.push_back(std::clamp(
                                linearToSrgb(std::max(frame.at(x, y, red + c), 0.0f)), 0.0f, 1.0f));
                        }
                    for (int c = 0; c < 3; ++c)
                        for (size_t p = 0; p < plane; ++p) {
                            const int x = int(p % size_t(s.width)), y = int(p / size_t(s.width));
                            s.truth.push_back(
                                std::clamp(linearToSrgb(std::max(truth.at(x, y, tr + c), 0.0f)), 0.0f, 1.0f));
                        }
                    for (const int channel : {mx, my})
                        for (size_t p = 0; p < plane; ++p)
                            s.motion.push_back(
                                frame.at(int(p % size_t(s.width)), int(p / size_t(s.width)), channel));
                    const float far = sidecar.value("depth_far", 200.0f);
                    if (options.depth)
                        for (const int channel : {dz, pz})
                            for (size_t p = 0; p < plane; ++p)
                                s.depth.push_back(
                                    frame.at(int(p % size_t(s.width)), int(p / size_t(s.width)), channel) /
                                    far);
                    const nlohmann::json& f = sidecar.at("frames").at(size_t(k));
                    s.jitter.push_back(f.at("jitter_pixels").at(0).get<float>());
                    s.jitter.push_back(f.at("jitter_pixels").at(1).get<float>());
                    s.cut.push_back(f.value("cut", false) ? 1 : 0);
                }
            } catch (const nlohmann::json::exception& e) {
                throw Error("sequence " + r.value("id", std::string("?")) +
                            ": its manifest record or render.json is incomplete (" + e.what() + ")");
            }
        }
    });
}

SequenceBatch SequenceSampler::assemble(uint64_t index) const {
    const int N = options_.batchSize, P = options_.patchSize, K = frames_;
    SequenceBatch batch;
    batch.frames.resize(size_t(K));
    for (SequenceFrame& f : batch.frames) {
        f.colour = nn::Tensor({N, 3, P, P}), f.truth = nn::Tensor({N, 3, P, P});
        f.motion = nn::Tensor({N, 2, P, P});
        if (options_.depth) f.depth = nn::Tensor({N, 1, P, P}), f.previousDepth = nn::Tensor({N, 1, P, P});
        f.jitter.assign(size_t(2 * N), 0.0f), f.fresh.assign(size_t(N), 0);
    }
    Random random(splitMix64(options_.seed * 0x9E3779B97F4A7C15ull ^ index));
    for (int n = 0; n < N; ++n) {
        const Sequence& s = sequences_[size_t(random.below(int(sequences_.size())))];
        batch.items.push_back(s.index);
        const int start = random.below(s.length - K + 1);
        const int x0 = random.below(s.width - P + 1), y0 = random.below(s.height - P + 1);
        // Bit 0: mirror x, bit 1: mirror y, bit 2: transpose (applied last): the 8 symmetries of the square.
        const int symmetry = options_.augment ? random.below(8) : 0;
        const bool mirrorX = symmetry & 1, mirrorY = symmetry & 2, transpose = symmetry & 4;
        const size_t plane = size_t(s.width) * size_t(s.height);
        for (int t = 0; t < K; ++t) {
            const int k = start + t;
            SequenceFrame& f = batch.frames[size_t(t)];
            f.fresh[size_t(n)] = t == 0 || s.cut[size_t(k)];
            float jx = s.jitter[size_t(2 * k)], jy = s.jitter[size_t(2 * k + 1)];
            if (mirrorX) jx = -jx;
            if (mirrorY) jy = -jy;
            if (transpose) std::swap(jx, jy);
            f.jitter[size_t(2 * n)] = jx, f.jitter[size_t(2 * n + 1)] = jy;
            for (int v = 0; v < P; ++v)
                for (int u = 0; u < P; ++u) {
                    // Output pixel (u, v) of the crop comes from source pixel (sx, sy).
                    int a = transpose ? v : u, b = transpose ? u : v;
                    if (mirrorX) a = P - 1 - a;
                    if (mirrorY) b = P - 1 - b;
                    const size_t from = size_t(y0 + b) * size_t(s.width) + size_t(x0 + a);
                    const int64_t to = int64_t(v) * P + u;
                    for (int c = 0; c < 3; ++c) {
                        f.colour.data()[(int64_t(n) * 3 + c) * P * P + to] =
                            s.colour[(size_t(k) * 3 + size_t(c)) * plane + from];
                        f.truth.data()[(int64_t(n) * 3 + c) * P * P + to] =
                            s.truth[(size_t(k) * 3 + size_t(c)) * plane + from];
                    }
                    float mx = s.motion[(size_t(k) * 2) * plane + from],
                          my = s.motion[(size_t(k) * 2 + 1) * plane + from];
                    if (mirrorX) mx = -mx;
                    if (mirrorY) my = -my;
                    if (transpose) std::swap(mx, my);
                    if (f.fresh[size_t(n)]) mx = my = 0;
                    f.motion.data()[(int64_t(n) * 2) * P * P + to] = mx;
                    f.motion.data()[(int64_t(n) * 2 + 1) * P * P + to] = my;
                    if (options_.depth) {
                        f.depth.data()[int64_t(n) * P * P + to] = s.depth[(size_t(k) * 2) * plane + from];
                        f.previousDepth.data()[int64_t(n) * P * P + to] =
                            s.depth[(size_t(k) * 2 + 1) * plane + from];
                    }
                }
        }
    }
    return batch;
}

SequenceBatch SequenceSampler::whole(int i) const {
    const Sequence& s = sequences_.at(size_t(i));
    const int64_t W = s.width, H = s.height, plane = W * H;
    SequenceBatch batch;
    batch.items.push_back(s.index);
    for (int k = 0; k < s.length; ++k) {
        SequenceFrame f;
        f.colour = nn::Tensor({1, 3, H, W}), f.truth = nn::Tensor({1, 3, H, W}),
        f.motion = nn::Tensor({1, 2, H, W});
        if (options_.depth) {
            f.depth = nn::Tensor({1, 1, H, W}), f.previousDepth = nn::Tensor({1, 1, H, W});
            std::copy_n(s.depth.begin() + k * 2 * plane, plane, f.depth.data());
            std::copy_n(s.depth.begin() + (k * 2 + 1) * plane, plane, f.previousDepth.data());
        }
        std::copy_n(s.colour.begin() + k * 3 * plane, 3 * plane, f.colour.data());
        std::copy_n(s.truth.begin() + k * 3 * plane, 3 * plane, f.truth.data());
        f.fresh.push_back(k == 0 || s.cut[size_t(k)]);
        if (!f.fresh[0]) std::copy_n(s.motion.begin() + k * 2 * plane, 2 * plane, f.motion.data());
        f.jitter = {s.jitter[size_t(2 * k)], s.jitter[size_t(2 * k + 1)]};
        batch.frames.push_back(std::move(f));
    }
    return batch;
}

}  // namespace dejag::data

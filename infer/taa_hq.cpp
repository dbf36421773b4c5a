#include "infer/taa_hq.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>

#include "base/error.h"
#include "base/thread_pool.h"
#include "infer/taa_hq_kernels.h"

namespace dejag::infer {

std::vector<std::pair<float, float>> parseJitterList(const std::string& text) {
    std::vector<std::pair<float, float>> list;
    std::istringstream in(text);
    std::string entry;
    while (in >> entry) {
        const size_t comma = entry.find(',');
        size_t used1 = 0, used2 = 0;
        float x = 0, y = 0;
        bool ok = comma != std::string::npos;
        try {
            if (ok) {
                x = std::stof(entry.substr(0, comma), &used1);
                y = std::stof(entry.substr(comma + 1), &used2);
            }
        } catch (const std::exception&) {
            ok = false;
        }
        if (!ok || used1 != comma || used2 != entry.size() - comma - 1 || !std::isfinite(x) ||
            !std::isfinite(y) || std::abs(x) > 8 || std::abs(y) > 8)
            throw Error("jitter list: '" + entry + "' is not X,Y (pixels, each within +-8)");
        list.push_back({x, y});
    }
    return list;
}

TaaHq::TaaHq(const TaaHqOptions& o) : options_(o) {
    if (!(o.clipGamma > 0 && o.clipGamma <= 8) || o.maxSamples < 1 || o.maxSamples > 4096 ||
        o.movingSamples < 1 || !(o.clippedSamples >= 0) || !(o.depthTolerance > 0) ||
        !(o.sharpen >= 0 && o.sharpen <= 1))
        throw Error("taa-hq: a parameter is out of range");
}

void TaaHq::apply(int W, int H, const float* colour, const float* motion, const float* depth,
                  const float* previousDepth, float jitterX, float jitterY, float* out) {
    if (W < 1 || H < 1 || !colour || !motion) throw Error("taa-hq needs colour and motion");
    if (size_t(W) * size_t(H) * 3 > size_t(INT32_MAX))
        throw Error("taa-hq: frame too large (" + std::to_string(W) + "x" + std::to_string(H) + ")");
    // Four bands per thread balance the load; each band recomputes a few rows of its neighbours.
    const int bands = std::min(H, 4 * threadCount());
    const bool fresh = W != width_ || H != height_;
    if (fresh) {
        width_ = W, height_ = H, frame_ = 0;
        stride_ = (size_t(W) + 15) / 16 * 16 + 16;  // full vectors at the end of a row stay inside it
        const size_t floats = 4 * stride_ * size_t(H) + kTaaHqHistoryTail;
        history_.assign(floats, 0.0f), nextHistory_.assign(floats, 0.0f);
    }
    if (fresh || bands != bands_) {
        bands_ = bands;
        scratch_.assign(taaHqScratchFloats(W) * size_t(bands), 0.0f);
    }
    if (!options_.jitterList.empty()) {
        const auto& j = options_.jitterList[size_t(frame_) % options_.jitterList.size()];
        jitterX = j.first, jitterY = j.second;
    }
    ++frame_;
    TaaHqBandInputs in;
    in.width = W, in.height = H;
    in.colour = colour, in.motion = motion;
    in.depth = depth, in.previousDepth = depth ? previousDepth : nullptr;
    in.history = history_.data(), in.nextHistory = nextHistory_.data();
    in.stride = stride_, in.planeFloats = stride_ * size_t(H);
    in.out = out;
    // The sample inside pixel p's box is pixel p + shift's: its position from its own centre is -jitter
    // (a jitter beyond the frame's size shifts no further than its border).
    in.shiftX = std::clamp(-int(std::floor(-jitterX + 0.5f)), -W, W);
    in.shiftY = std::clamp(-int(std::floor(-jitterY + 0.5f)), -H, H);
    in.fresh = fresh, in.catmullRom = options_.catmullRom, in.staticLock = options_.staticLock;
    in.clipGamma = options_.clipGamma, in.maxWeight = float(options_.maxSamples);
    in.movingMaxWeight = float(std::min(options_.movingSamples, options_.maxSamples));
    in.clippedWeight = options_.clippedSamples, in.depthTolerance = options_.depthTolerance;
    in.sharpen = options_.sharpen;
    const size_t scratchFloats = taaHqScratchFloats(W);
    parallelFor(0, bands, 1, [&](int64_t first, int64_t last) {
        for (int64_t b = first; b < last; ++b) {
            const int y0 = int(int64_t(H) * b / bands), y1 = int(int64_t(H) * (b + 1) / bands);
            DEJAG_SIMD_CALL(taaHqBand, in, y0, y1, scratch_.data() + size_t(b) * scratchFloats);
        }
    });
    std::swap(history_, nextHistory_);
}

namespace {

class TaaHqFilter final : public Filter {
  public:
    explicit TaaHqFilter(const TaaHqOptions& options) : Filter("taa-hq"), taa_(options) {}
    BufferSet needs() const override { return unsigned(Buffer::Motion); }
    BufferSet uses() const override {
        return Buffer::Motion | Buffer::Depth | Buffer::PreviousDepth | Buffer::Jitter;
    }
    bool temporal() const override { return true; }
    void reset() override { taa_.reset(); }

  private:
    void process(const Frame& frame, float* out) override {
        const float* depth = frame.depth && frame.previousDepth ? frame.depth : nullptr;
        const float* previous = depth ? frame.previousDepth : nullptr;
        const float jx = frame.hasJitter ? frame.jitter[0] : 0.0f,
                    jy = frame.hasJitter ? frame.jitter[1] : 0.0f;
        // R G B alone; the other channels pass through.
        taa_.apply(frame.width, frame.height, rgb_.rgb(frame), frame.motion, depth, previous, jx, jy,
                   rgb_.result(frame, out));
        rgb_.finish(frame, out);
    }
    TaaHq taa_;
    RgbScratch rgb_;
};

}  // namespace

TaaHqOptions taaHqOptions(const MethodParameters& p) {
    TaaHqOptions o;
    o.clipGamma = float(p.number("clip-gamma", 1e-3, 8));
    o.maxSamples = p.integer("max-samples", 1, 4096);
    o.movingSamples = p.integer("moving-samples", 1, 4096);
    o.clippedSamples = float(p.number("clipped-samples", 0, 4096));
    o.depthTolerance = float(p.number("depth-tolerance", 1e-4, 10));
    o.sharpen = float(p.number("sharpen", 0, 1));
    o.staticLock = p.flag("static-lock");
    const std::string filter = p.text("history-filter");
    if (filter != "catmull-rom" && filter != "bilinear")
        throw Error("taa-hq: history-filter is catmull-rom or bilinear, not '" + filter + "'");
    o.catmullRom = filter == "catmull-rom";
    if (const std::string j = p.text("jitter"); j != "frames") {
        o.jitterList = parseJitterList(j);
        if (o.jitterList.empty()) throw Error("taa-hq: the jitter list is empty (use 'frames' or X,Y pairs)");
    }
    return o;
}

MethodSpec taaHqMethod() {
    const TaaHqOptions d;
    MethodSpec spec;
    spec.name = "taa-hq";
    spec.summary =
        "a converging TAA (docs/taa-hq.md): the in-pixel sample at its jittered position accumulated per "
        "pixel, Catmull-Rom history, YCoCg variance clipping, depth disocclusion, sharpen on the output only";
    spec.parameters = {
        {"clip-gamma", "1.25", "variance clipping: mean +- gamma sigma of the 3x3 neighbourhood, (0, 8]"},
        {"max-samples", "32",
         "the accumulated weight's cap (the current frame's share is at least its inverse)"},
        {"moving-samples", "6",
         "the accumulated weight's cap where something moved in the pixel's 3x3 (at most max-samples)"},
        {"clipped-samples", "4", "the weight a history that was clipped keeps at most"},
        {"depth-tolerance", "0.05", "relative depth change that rejects the history (a disocclusion)"},
        {"sharpen", "0", "sharpen of the output only, 0 (off) to 1; the history stays unsharpened"},
        {"history-filter", "catmull-rom", "history resampling: catmull-rom (deringed) or bilinear"},
        {"static-lock", "true",
         "no clipping where nothing moved in the 3x3, now or where the history comes from (a still view "
         "converges to its mean)"},
        {"jitter", "frames",
         "each frame's jitter: 'frames' (render.json's, zero without one) or a cycled list 'X,Y X,Y ...' "
         "(image shift in pixels, +y down)"},
    };
    spec.needs = unsigned(Buffer::Motion);
    spec.optional = Buffer::Depth | Buffer::PreviousDepth | Buffer::Jitter;
    spec.temporal = true;
    spec.make = [](MethodParameters& p) -> std::unique_ptr<Filter> {
        return std::make_unique<TaaHqFilter>(taaHqOptions(p));
    };
    return spec;
}

}  // namespace dejag::infer

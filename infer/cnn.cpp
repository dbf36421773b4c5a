#include "infer/cnn.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdlib>
#include <utility>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "infer/cnn_kernels.h"

namespace dejag::infer {

struct CnnFilter::Impl {
    nn::FrameNetwork network;  // how the model meets the frame (nn/frame_network.h)
    CnnOptions options;
    int tile = 0;
    std::vector<uint8_t> tileActive;
    int tilesProcessed = 0, tileCount = 0;
    double passedPixels = 0, processedPixels = 0;

    Impl(nn::Model m, const CnnOptions& o) : network(std::move(m), o.precision), options(o) {}
};

CnnFilter::CnnFilter(nn::Model model, const CnnOptions& options) {
    if (options.tileSize < 16 || options.tileSize > 4096) throw Error("tile size must be in 16..4096");
    if (!(options.gateThreshold >= 0) || !std::isfinite(options.gateThreshold))
        throw Error("the gate threshold must be a finite number >= 0");
    if (!(options.passSpan >= 0) || !std::isfinite(options.passSpan))
        throw Error("the pass-through span must be a finite number >= 0");
    impl_ = std::make_unique<Impl>(std::move(model), options);
    const int a = impl_->network.alignment();
    impl_->tile = (options.tileSize + a - 1) / a * a;
    nn::checkWeightsForFrames(impl_->network.model());
}

nn::InferencePrecision cnnPrecision(const std::string& name) {
    if (name == "fp32") return nn::InferencePrecision::Float32;
    if (name == "bf16") {
        if (!bf16Available())
            throw Error(
                "--precision bf16 needs a CPU with AVX-512 BF16 (this one, or the SIMD level forced, has "
                "none)");
        return nn::InferencePrecision::BFloat16;
    }
    if (name == "auto")
        return bf16Available() ? nn::InferencePrecision::BFloat16 : nn::InferencePrecision::Float32;
    throw Error("--precision '" + name + "' is not one of fp32, bf16, auto");
}

const char* precisionName(nn::InferencePrecision precision) {
    return precision == nn::InferencePrecision::BFloat16 ? "bf16" : "fp32";
}

CnnFilter::~CnnFilter() = default;
CnnFilter::CnnFilter(CnnFilter&&) noexcept = default;
CnnFilter& CnnFilter::operator=(CnnFilter&&) noexcept = default;

const nn::Model& CnnFilter::model() const {
    return impl_->network.model();
}
const CnnOptions& CnnFilter::options() const {
    return impl_->options;
}
int CnnFilter::halo() const {
    return impl_->network.halo();
}
int CnnFilter::alignment() const {
    return impl_->network.alignment();
}
double CnnFilter::passedThroughFraction() const {
    return impl_->processedPixels > 0 ? impl_->passedPixels / impl_->processedPixels : 0.0;
}

double CnnFilter::processedFraction() const {
    return impl_->tileCount ? double(impl_->tilesProcessed) / impl_->tileCount : 0.0;
}
int CnnFilter::tilesProcessed() const {
    return impl_->tilesProcessed;
}
int CnnFilter::tileCount() const {
    return impl_->tileCount;
}

void CnnFilter::apply(const float* in, float* out, int width, int height, int channels,
                      const CnnBuffers& buffers) {
    if (width < 1 || height < 1 || channels < 3)
        throw Error("the CNN filter needs an RGB frame of at least 1x1 pixel");
    Impl& m = *impl_;
    const int T = m.tile;
    const size_t C = size_t(channels);
    // The luma of a grey model's input is computed here (the gate computes what it needs of it itself,
    // and stops at a tile's first step, which on most frames comes early).
    m.network.beginFrame(in, width, height, channels, buffers.guide);

    const int tilesX = (width + T - 1) / T, tilesY = (height + T - 1) / T;
    m.tileCount = tilesX * tilesY;
    if (m.tileActive.size() < size_t(m.tileCount)) m.tileActive.resize(size_t(m.tileCount));
    // Gating: a tile (plus one pixel around it) with a luma step, an ID change or a depth jump. Each
    // tile's rows are scanned in kGateChunks parts in parallel, all of them stopping once one finds a step
    // (a frame in one tile would otherwise be scanned by one thread, the whole of it where it is flat).
    constexpr int kGateChunks = 8;
    for (int t = 0; t < m.tileCount; ++t) m.tileActive[size_t(t)] = !m.options.gate;
    if (m.options.gate)
        parallelFor(0, int64_t(m.tileCount) * kGateChunks, 1, [&](int64_t first, int64_t last) {
            for (int64_t item = first; item < last; ++item) {
                const int t = int(item / kGateChunks), part = int(item % kGateChunks);
                const int tx = t % tilesX, ty = t / tilesX;
                std::atomic_ref<uint8_t> active(m.tileActive[size_t(t)]);
                const int x0 = std::max(0, tx * T - 1), x1 = std::min(width - 1, (tx + 1) * T);
                const int y0 = std::max(0, ty * T - 1), y1 = std::min(height - 1, (ty + 1) * T);
                const int rows = y1 - y0 + 1;
                for (int y = y0 + rows * part / kGateChunks; y < y0 + rows * (part + 1) / kGateChunks; ++y) {
                    if (active.load(std::memory_order_relaxed)) break;
                    const size_t row = size_t(y) * size_t(width);
                    const size_t below = y + 1 < height ? row + size_t(width) : row;
                    bool step = DEJAG_SIMD_CALL(rowHasLumaStep, in + row * C, in + below * C, int(C), width,
                                                x0, x1, m.options.gateThreshold);
                    for (int x = x0; x <= x1 && !step && (buffers.ids || buffers.depth); ++x) {
                        const size_t p = row + size_t(x), r = x + 1 < width ? p + 1 : p,
                                     b = y + 1 < height ? p + size_t(width) : p;
                        if (buffers.ids &&
                            (buffers.ids[p] != buffers.ids[r] || buffers.ids[p] != buffers.ids[b]))
                            step = true;
                        if (const float* depth = buffers.depth) {
                            const float d = depth[p];
                            if (std::abs(d - depth[r]) > 0.05f * std::min(d, depth[r]) ||
                                std::abs(d - depth[b]) > 0.05f * std::min(d, depth[b]))
                                step = true;
                        }
                    }
                    if (step) {
                        active.store(1, std::memory_order_relaxed);
                        break;
                    }
                }
            }
        });

    // Skipped tiles are the input, bit for bit; processed tiles get R, G, B from the network below, so
    // only their other channels (alpha, ...) are copied here. (A 1080p frame in one processed tile
    // copies nothing: the whole-frame copy this replaced cost ~8 ms of one thread.)
    parallelFor(0, height, 8, [&](int64_t y0, int64_t y1) {
        for (int64_t y = y0; y < y1; ++y) {
            const int ty = int(y) / T;
            for (int tx = 0; tx < tilesX; ++tx) {
                const size_t x0 = size_t(tx) * size_t(T), x1 = std::min(size_t(width), x0 + size_t(T));
                const size_t row = size_t(y) * size_t(width);
                if (!m.tileActive[size_t(ty * tilesX + tx)]) {
                    std::copy(in + (row + x0) * C, in + (row + x1) * C, out + (row + x0) * C);
                } else if (C > 3) {
                    for (size_t x = x0; x < x1; ++x)
                        std::copy(in + (row + x) * C + 3, in + (row + x + 1) * C, out + (row + x) * C + 3);
                }
            }
        }
    });

    m.tilesProcessed = 0;
    m.passedPixels = m.processedPixels = 0;
    for (int t = 0; t < m.tileCount; ++t) {
        if (!m.tileActive[size_t(t)]) continue;
        ++m.tilesProcessed;
        const int tx = t % tilesX, ty = t / tilesX;
        const int cx0 = tx * T, cy0 = ty * T, cx1 = std::min(width, cx0 + T), cy1 = std::min(height, cy0 + T);
        const nn::FrameNetwork::RegionFigures f =
            m.network.runRegion(out, cx0, cy0, cx1, cy1, m.options.gate ? m.options.passSpan : 0.0f);
        m.processedPixels += f.madePixels, m.passedPixels += f.passedPixels;
    }
}

namespace {

class CnnMethodFilter final : public Filter {
  public:
    // inputMethod: the method the network was trained to run after ("": none), run here first.
    // guideMethod: the method whose result the network reads beside the frame ("": none).
    CnnMethodFilter(CnnFilter cnn, std::string model, std::string gate, const std::string& inputMethod,
                    const std::string& guideMethod)
        : Filter("cnn"), cnn_(std::move(cnn)) {
        figures_.settings = {{"model", std::move(model)},
                             {"gate", std::move(gate)},
                             {"precision", precisionName(cnn_.options().precision)}};
        if (!inputMethod.empty()) {
            input_ = makeFilter(inputMethod, {});
            figures_.settings.push_back({"input_method", inputMethod});
        }
        if (!guideMethod.empty()) {
            guide_ = makeFilter(guideMethod, {});
            figures_.settings.push_back({"guide_method", guideMethod});
        }
    }
    BufferSet needs() const override { return 0; }
    BufferSet uses() const override { return Buffer::Depth | Buffer::Ids; }

  private:
    void process(const Frame& frame, float* out) override {
        Frame through = frame;
        if (input_) {
            const size_t floats = size_t(frame.width) * size_t(frame.height) * size_t(frame.channels);
            if (inputFrame_.size() < floats) inputFrame_.resize(floats);
            input_->apply(frame, inputFrame_.data());
            through.colour = inputFrame_.data();
        }
        const float* guide = nullptr;
        if (guide_) {
            const size_t floats = size_t(frame.width) * size_t(frame.height) * size_t(frame.channels);
            if (guideFrame_.size() < floats) guideFrame_.resize(floats);
            guide_->apply(through, guideFrame_.data());
            guide = guideFrame_.data();
        }
        cnn_.apply(through.colour, out, frame.width, frame.height, frame.channels,
                   {frame.depth, frame.ids, guide});
        figures_.processedFraction = cnn_.processedFraction();
        figures_.extra = {{"tiles", double(cnn_.tileCount())},
                          {"tiles_processed", double(cnn_.tilesProcessed())},
                          {"passed_through_fraction", cnn_.passedThroughFraction()}};
    }
    CnnFilter cnn_;
    std::unique_ptr<Filter> input_, guide_;
    std::vector<float> inputFrame_, guideFrame_;
};

}  // namespace

MethodSpec cnnMethod() {
    const CnnOptions d;
    MethodSpec spec;
    spec.name = "cnn";
    spec.summary =
        "a trained network (models/*.safetensors, see models/*.md) run in tiles with a receptive-field "
        "halo, only where a luma step (or an id change or depth jump) can hold aliasing";
    spec.parameters = {
        {"model", "models/dejag-fast.safetensors", "the model file"},
        {"gate", "auto", "off | auto (0.04) | T: run the tiles whose luma steps exceed T in [0, 1]"},
        {"tile", std::to_string(d.tileSize), "tile side in pixels, 16..4096"},
        {"precision", "auto", "fp32 | bf16 (AVX-512 BF16 CPUs) | auto (bf16 where the CPU has it)"},
        {"pass-span", "0.0009765625",
         "gated, a kernel-predicting network passes through runs of pixels it could move by at most this (0: "
         "off)"},
    };
    spec.optional = Buffer::Depth | Buffer::Ids;
    spec.make = [](MethodParameters& p) -> std::unique_ptr<Filter> {
        CnnOptions options;
        options.tileSize = p.integer("tile", 16, 4096);
        options.passSpan = float(p.number("pass-span", 0, 1));
        const std::string precision = p.text("precision");
        options.precision = cnnPrecision(precision);  // its errors name --precision
        const std::string gate = p.text("gate");
        if (gate == "off") {
            options.gate = false;
        } else if (gate != "auto") {
            const std::string bad =
                p.origin("gate") + ": '" + gate + "' is not off, auto or a luma threshold in [0, 1]";
            char* end = nullptr;
            const double t = std::strtod(gate.c_str(), &end);
            if (gate.empty() || *end != '\0' || !(t >= 0 && t <= 1)) throw Error(bad);
            options.gateThreshold = float(t);
        }
        const std::string path = p.path("model");
        nn::Model model = nn::loadModel(path);
        const std::string inputMethod = model.architecture().value("input_method", "");
        const std::string guideMethod = model.architecture().value("guide_method", "");
        try {
            return std::make_unique<CnnMethodFilter>(CnnFilter(std::move(model), options), path, gate,
                                                     inputMethod, guideMethod);
        } catch (const Error& e) {
            throw Error("--model '" + path + "': " + e.what());
        }
    };
    return spec;
}

}  // namespace dejag::infer

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

ReceptiveField receptiveField(const nn::Model& model) {
    // Per node: the spacing of its pixels in input pixels (scale) and how far its pixels see (radius).
    const std::vector<nn::GraphNode> graph = model.graph();
    std::vector<double> scale(graph.size(), 1.0), radius(graph.size(), 0.0);
    double maxScale = 1.0;
    for (size_t i = 0; i < graph.size(); ++i) {
        const nn::GraphNode& n = graph[i];
        double s = 1.0, r = 0.0;
        for (size_t k = 0; k < n.inputs.size(); ++k) {
            const int in = n.inputs[k];
            const double inScale = in < 0 ? 1.0 : scale[size_t(in)],
                         inRadius = in < 0 ? 0.0 : radius[size_t(in)];
            if (k == 0) s = inScale;
            r = std::max(r, inRadius);
        }
        switch (n.op) {
            case nn::GraphOp::Conv2d:
                r += ((n.kernel - 1) * n.dilation / 2.0 + (n.stride - 1) + (n.samePadding ? 0 : n.padding)) *
                     s;
                s *= n.stride;
                break;
            case nn::GraphOp::ConvTranspose2d:
                r += ((n.kernel - 1) / 2.0 + 1) * s;
                s /= n.stride;
                break;
            case nn::GraphOp::MaxPool2d:
                r += (n.kernel - 1) * s;
                s *= n.stride;
                break;
            case nn::GraphOp::Upsample:
            case nn::GraphOp::PixelShuffle:
                r += s;
                s /= n.factor;
                break;
            case nn::GraphOp::KernelFilter:
                r += (n.kernel / 2) * s;
                break;
            default:
                break;
        }
        scale[i] = s, radius[i] = r;
        maxScale = std::max(maxScale, s);
    }
    return {int(std::ceil(radius[size_t(model.outputNode())])), int(std::lround(maxScale))};
}

struct CnnFilter::Impl {
    nn::Model model;
    CnnOptions options;
    ReceptiveField field;
    int halo = 0, tile = 0;
    // by (height, width) of a tile's input region
    std::map<std::pair<int, int>, std::unique_ptr<nn::InferencePlan>> plans;
    std::vector<float> luma;  // (H, W) luma of the frame
    std::vector<uint8_t> tileActive;
    int tilesProcessed = 0, tileCount = 0;
    double passedPixels = 0, processedPixels = 0;

    Impl(nn::Model m, const CnnOptions& o) : model(std::move(m)), options(o) {}

    nn::InferencePlan& planFor(int height, int width) {
        auto it = plans.find({height, width});
        if (it == plans.end()) {
            const nn::Shape shape{1, model.inputChannels(), height, width};
            it = plans
                     .emplace(std::make_pair(height, width),
                              std::make_unique<nn::InferencePlan>(model, shape, options.precision))
                     .first;
        }
        return *it->second;
    }
};

namespace {

// A tile's output rows into the frame: the core's columns of each row, clamped to [0, 1], R G B of an RGB
// network, or a grey network's luma change added to R, G and B.
struct FrameRows final : nn::OutputRowSink {
    const float* in = nullptr;  // the frame (interleaved, C channels)
    float* out = nullptr;
    const float* luma = nullptr;  // the frame's luma (grey networks)
    size_t C = 3, width = 0;
    int rx0 = 0, ry0 = 0, cx0 = 0, cx1 = 0;  // the region's origin, the core's columns (frame coordinates)
    bool grey = false;

    void row(int64_t, int64_t y, const float* const* channels) override {
        const size_t frameRow = size_t(ry0 + y) * width, first = size_t(cx0 - rx0);
        float* o = out + (frameRow + size_t(cx0)) * C;
        const int count = cx1 - cx0;
        if (grey) {
            const float* r = channels[0] + first;
            const float* s = in + (frameRow + size_t(cx0)) * C;
            const float* l = luma + frameRow + size_t(cx0);
            for (int i = 0; i < count; ++i, o += C, s += C) {
                const float change = r[i] - l[i];
                for (int c = 0; c < 3; ++c) o[c] = std::clamp(s[c] + change, 0.0f, 1.0f);
            }
        } else {
            DEJAG_SIMD_CALL(joinRgbRowClamped, channels[0] + first, channels[1] + first, channels[2] + first,
                            count, int(C), o);
        }
    }
    // A row the network passes through: the frame's, clamped as row() clamps (an RGB network's; a grey
    // network's rows are made).
    bool passRow(int64_t, int64_t y) override {
        if (grey) return false;
        const size_t at = (size_t(ry0 + y) * width + size_t(cx0)) * C;
        DEJAG_SIMD_CALL(clampRgbRow, in + at, int(C), cx1 - cx0, out + at);
        return true;
    }
};

// The rows of a tile's input region, as the network reads them: planes of R, G, B (or the luma of a grey
// network), rows and columns past the frame repeating its last ones.
struct RegionRows final : nn::InputRowSource {
    const float* in = nullptr;  // the frame (interleaved, C channels)
    const float* luma = nullptr;
    size_t C = 3, width = 0;
    int height = 0, rx0 = 0, ry0 = 0, RW = 0;  // the region's origin and width
    bool grey = false;

    void row(int64_t, int64_t y, float* const* channels) override {
        const size_t frameRow = size_t(std::min(int(ry0 + y), height - 1)) * width;
        const int inside = std::max(0, std::min(RW, int(width) - rx0));
        if (grey)
            std::copy_n(luma + frameRow + size_t(rx0), inside, channels[0]);
        else
            DEJAG_SIMD_CALL(splitRgbRow, in + (frameRow + size_t(rx0)) * C, int(C), inside, channels[0],
                            channels[1], channels[2]);
        for (int c = 0; c < (grey ? 1 : 3); ++c)
            std::fill(channels[c] + inside, channels[c] + RW, channels[c][inside - 1]);
    }
};

// What the filter will do with a model, checked before its first frame rather than in the middle of one:
// an output of the input's size for a frame the network can take (a super-resolution or downscaling graph
// is no anti-aliasing filter), finite weights, and, on a test pattern in [0, 1] (a hard edge, a ramp and a
// checkerboard, the content a filter meets), a finite output within kProbeBound of that range: weights
// that are finite but huge (1e38) give infinities or NaN there, as they would on every frame.
constexpr float kProbeBound = 4.0f;
void checkModelForFrames(const nn::Model& model, int stride) {
    const std::string name = "model '" + model.name() + "'";
    const int64_t side = (32 + stride - 1) / stride * stride, C = model.inputChannels();
    const nn::Shape out = model.outputShape({1, C, side, side});
    if (out[2] != side || out[3] != side)
        throw Error(name + " returns " + std::to_string(out[3]) + "x" + std::to_string(out[2]) +
                    " pixels for a " + std::to_string(side) + "x" + std::to_string(side) +
                    " frame; an anti-aliasing filter returns the size it is given");
    const float* weights = model.parameterData();
    for (int64_t i = 0; i < model.parameterCount(); ++i)
        if (!std::isfinite(weights[i])) throw Error(name + " has a non-finite weight");
    nn::Tensor probe({1, C, side, side});
    for (int64_t c = 0; c < C; ++c)
        for (int64_t y = 0; y < side; ++y)
            for (int64_t x = 0; x < side; ++x) {
                const float edge = x * 3 > y * 2 ? 1.0f : 0.0f, ramp = float(x + y) / float(2 * side),
                            checker = float((x + y) & 1);
                probe.at(0, c, y, x) = y < side / 3       ? edge
                                       : y < 2 * side / 3 ? ramp
                                                          : checker * (0.8f - 0.2f * c);
            }
    nn::InferencePlan plan(model, probe.shape());
    const nn::Tensor& result = plan.run(probe);
    for (int64_t i = 0; i < result.numel(); ++i) {
        const float v = result.data()[i];
        if (!std::isfinite(v) || v < -kProbeBound || v > 1 + kProbeBound)
            throw Error(
                name + " gives " +
                (std::isfinite(v) ? std::to_string(v) : std::string("a non-finite value")) +
                " on a test pattern in [0, 1]; its weights are unusable (a filter's output stays within " +
                std::to_string(int(kProbeBound)) + " of the input range)");
    }
}

}  // namespace

CnnFilter::CnnFilter(nn::Model model, const CnnOptions& options)
    : impl_(std::make_unique<Impl>(std::move(model), options)) {
    const int c = impl_->model.inputChannels();
    if ((c != 1 && c != 3) || impl_->model.outputChannels() != c)
        throw Error("the CNN filter needs a model taking and returning 1 (luma) or 3 (RGB) channels; '" +
                    impl_->model.name() + "' takes " + std::to_string(c) + " and returns " +
                    std::to_string(impl_->model.outputChannels()));
    if (options.tileSize < 16 || options.tileSize > 4096) throw Error("tile size must be in 16..4096");
    if (!(options.gateThreshold >= 0) || !std::isfinite(options.gateThreshold))
        throw Error("the gate threshold must be a finite number >= 0");
    if (!(options.passSpan >= 0) || !std::isfinite(options.passSpan))
        throw Error("the pass-through span must be a finite number >= 0");
    if (options.precision == nn::InferencePrecision::BFloat16 && !bf16Available())
        throw Error(
            "bf16 inference needs a CPU with AVX-512 BF16 (this one, or the SIMD level forced, has none)");
    impl_->field = receptiveField(impl_->model);
    const int a = impl_->field.stride;
    impl_->halo = (impl_->field.radius + a - 1) / a * a;  // the receptive field, rounded up to the stride
    impl_->tile = (options.tileSize + a - 1) / a * a;
    checkModelForFrames(impl_->model, a);
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
    return impl_->model;
}
const CnnOptions& CnnFilter::options() const {
    return impl_->options;
}
int CnnFilter::halo() const {
    return impl_->halo;
}
int CnnFilter::alignment() const {
    return impl_->field.stride;
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
    const int a = m.field.stride, T = m.tile, halo = m.halo;
    const size_t C = size_t(channels), pixels = size_t(width) * size_t(height);
    // The frame as the network sees it: padded by replication up to a multiple of the stride.
    const int PW = (width + a - 1) / a * a, PH = (height + a - 1) / a * a;
    const bool grey = m.model.inputChannels() == 1;
    auto lumaOf = [&](size_t p) {
        const float* v = in + p * C;
        return 0.21f * v[0] + 0.72f * v[1] + 0.07f * v[2];
    };
    // A grey model's input: the frame's luma (the gate computes what it needs of it itself, and stops
    // at a tile's first step, which on most frames comes early).
    if (grey) {
        if (m.luma.size() < pixels) m.luma.resize(pixels);
        parallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
            for (int64_t y = y0; y < y1; ++y)
                for (int x = 0; x < width; ++x)
                    m.luma[size_t(y) * size_t(width) + size_t(x)] =
                        lumaOf(size_t(y) * size_t(width) + size_t(x));
        });
    }

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
        // Input region: the core plus the halo, clipped to the padded frame (all multiples of the stride).
        const int rx0 = std::max(0, cx0 - halo), ry0 = std::max(0, cy0 - halo);
        const int rx1 = std::min(PW, (cx1 + a - 1) / a * a + halo),
                  ry1 = std::min(PH, (cy1 + a - 1) / a * a + halo);
        nn::InferencePlan& plan = m.planFor(ry1 - ry0, rx1 - rx0);
        const int RW = rx1 - rx0, RH = ry1 - ry0;
        RegionRows region;
        region.in = in, region.luma = m.luma.data(), region.C = C, region.width = size_t(width);
        region.height = height, region.rx0 = rx0, region.ry0 = ry0, region.RW = RW, region.grey = grey;
        FrameRows rows;
        rows.in = in, rows.out = out, rows.luma = m.luma.data(), rows.C = C, rows.width = size_t(width);
        rows.rx0 = rx0, rows.ry0 = ry0, rows.cx0 = cx0, rows.cx1 = cx1, rows.grey = grey;
        plan.setPassThrough(m.options.gate ? m.options.passSpan : 0.0f);
        if (plan.canStreamInput()) {
            // The frame's rows go straight into the first layer and the output stage, band by band.
            plan.runStreamed(region, rows, cy0 - ry0, cy1 - ry0);
        } else {
            parallelFor(0, RH, 8, [&](int64_t j0, int64_t j1) {
                float* planes[3];
                for (int64_t j = j0; j < j1; ++j) {
                    for (int c = 0; c < (grey ? 1 : 3); ++c) planes[c] = plan.inputRow(0, c, j);
                    region.row(0, j, planes);
                }
            });
            plan.runInPlace(rows, cy0 - ry0, cy1 - ry0);
        }
        const double made = double(cy1 - cy0) * double(RW);  // the rows made, halo columns included
        m.processedPixels += made, m.passedPixels += made * plan.passedThroughFraction();
    }
}

namespace {

class CnnMethodFilter final : public Filter {
  public:
    CnnMethodFilter(CnnFilter cnn, std::string model, std::string gate)
        : Filter("cnn"), cnn_(std::move(cnn)) {
        figures_.settings = {{"model", std::move(model)},
                             {"gate", std::move(gate)},
                             {"precision", precisionName(cnn_.options().precision)}};
    }
    BufferSet needs() const override { return 0; }
    BufferSet uses() const override { return Buffer::Depth | Buffer::Ids; }

  private:
    void process(const Frame& frame, float* out) override {
        cnn_.apply(frame.colour, out, frame.width, frame.height, frame.channels, {frame.depth, frame.ids});
        figures_.processedFraction = cnn_.processedFraction();
        figures_.extra = {{"tiles", double(cnn_.tileCount())},
                          {"tiles_processed", double(cnn_.tilesProcessed())},
                          {"passed_through_fraction", cnn_.passedThroughFraction()}};
    }
    CnnFilter cnn_;
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
        try {
            return std::make_unique<CnnMethodFilter>(CnnFilter(std::move(model), options), path, gate);
        } catch (const Error& e) {
            throw Error("--model '" + path + "': " + e.what());
        }
    };
    return spec;
}

}  // namespace dejag::infer

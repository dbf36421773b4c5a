#include "nn/frame_network.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "base/error.h"
#include "base/luma.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/frame_network_kernels.h"
#include "nn/ops.h"

namespace dejag::nn {

ReceptiveField receptiveField(const Model& model) {
    // Per node: the spacing of its pixels in input pixels (scale) and how far its pixels see (radius), as
    // each op's entry in the registry (nn/ops.h) moves them.
    const std::vector<GraphNode> graph = model.graph();
    std::vector<double> scale(graph.size(), 1.0), radius(graph.size(), 0.0);
    double maxScale = 1.0;
    for (size_t i = 0; i < graph.size(); ++i) {
        const GraphNode& n = graph[i];
        double s = 1.0, r = 0.0;
        for (size_t k = 0; k < n.inputs.size(); ++k) {
            const int in = n.inputs[k];
            const double inScale = in < 0 ? 1.0 : scale[size_t(in)],
                         inRadius = in < 0 ? 0.0 : radius[size_t(in)];
            if (k == 0) s = inScale;
            r = std::max(r, inRadius);
        }
        if (const OpDef& def = opDef(n.op); def.receptiveField) def.receptiveField(n, s, r);
        scale[i] = s, radius[i] = r;
        maxScale = std::max(maxScale, s);
    }
    const double reach = radius[size_t(model.outputNode())];
    if (!std::isfinite(reach)) return {0, int(std::lround(maxScale)), false};
    return {int(std::ceil(reach)), int(std::lround(maxScale))};
}

namespace {

// A region's output rows into the frame: the core's columns of each row, clamped to [0, 1], R G B of an
// RGB network, or a grey network's luma change added to R, G and B.
struct FrameRows final : OutputRowSink {
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

// The rows of a region, as the network reads them: planes of R, G, B (or the luma of a grey network),
// rows and columns past the frame repeating its last ones.
struct RegionRows final : InputRowSource {
    const float* in = nullptr;     // the frame (interleaved, C channels)
    const float* guide = nullptr;  // a guided network's guide (the frame's layout), as channels 3..5
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
        if (guide)
            DEJAG_SIMD_CALL(splitRgbRow, guide + (frameRow + size_t(rx0)) * C, int(C), inside, channels[3],
                            channels[4], channels[5]);
        for (int c = 0; c < (grey ? 1 : guide ? 6 : 3); ++c)
            std::fill(channels[c] + inside, channels[c] + RW, channels[c][inside - 1]);
    }
};

constexpr float kProbeBound = 4.0f;

}  // namespace

void checkWeightsForFrames(const Model& model) {
    const std::string name = "model '" + model.name() + "'";
    const int stride = receptiveField(model).stride;
    const int64_t side = (32 + stride - 1) / stride * stride, C = model.inputChannels();
    const float* weights = model.parameterData();
    for (int64_t i = 0; i < model.parameterCount(); ++i)
        if (!std::isfinite(weights[i])) throw Error(name + " has a non-finite weight");
    Tensor probe({1, C, side, side});
    for (int64_t c = 0; c < C; ++c)
        for (int64_t y = 0; y < side; ++y)
            for (int64_t x = 0; x < side; ++x) {
                const float edge = x * 3 > y * 2 ? 1.0f : 0.0f, ramp = float(x + y) / float(2 * side),
                            checker = float((x + y) & 1);
                probe.at(0, c, y, x) = y < side / 3       ? edge
                                       : y < 2 * side / 3 ? ramp
                                                          : checker * (0.8f - 0.2f * c);
            }
    InferencePlan plan(model, probe.shape());
    const Tensor& result = plan.run(probe);
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

struct FrameNetwork::Impl {
    std::unique_ptr<Model> owned;
    const Model& model;
    InferencePrecision precision;
    ReceptiveField field;
    int halo = 0;
    bool grey = false;
    std::string guideMethod;  // a guided network's (channels 3..5 are the guide)
    // by (height, width) of a region
    std::map<std::pair<int, int>, std::unique_ptr<InferencePlan>> plans;
    std::vector<float> luma;  // (H, W) luma of the frame (grey networks)
    const float* in = nullptr;
    const float* guide = nullptr;
    int width = 0, height = 0, channels = 3;

    Impl(std::unique_ptr<Model> m, InferencePrecision p) : owned(std::move(m)), model(*owned), precision(p) {}
    Impl(const Model& m, InferencePrecision p) : model(m), precision(p) {}
    void check();

    InferencePlan& planFor(int regionHeight, int regionWidth) {
        auto it = plans.find({regionHeight, regionWidth});
        if (it == plans.end()) {
            if (plans.size() >= 16) plans.clear();  // frames of ever new sizes: bounded memory
            const Shape shape{1, model.inputChannels(), regionHeight, regionWidth};
            it = plans
                     .emplace(std::make_pair(regionHeight, regionWidth),
                              std::make_unique<InferencePlan>(model, shape, precision))
                     .first;
        }
        return *it->second;
    }
};

FrameNetwork::FrameNetwork(Model model, InferencePrecision precision)
    : impl_(std::make_unique<Impl>(std::make_unique<Model>(std::move(model)), precision)) {
    impl_->check();
}

FrameNetwork::FrameNetwork(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {
    impl_->check();
}

FrameNetwork FrameNetwork::borrowing(const Model& model, InferencePrecision precision) {
    return FrameNetwork(std::make_unique<Impl>(model, precision));
}

void FrameNetwork::Impl::check() {
    const Model& m = model;
    const int c = m.inputChannels();
    guideMethod = m.architecture().value("guide_method", "");
    if (!guideMethod.empty() && (c != 6 || m.outputChannels() != 3))
        throw Error("model '" + m.name() +
                    "' names a guide method, so it must take 6 channels (the frame's "
                    "R G B and the guide's) and return 3; it takes " +
                    std::to_string(c) + " and returns " + std::to_string(m.outputChannels()));
    if (guideMethod.empty() && ((c != 1 && c != 3) || m.outputChannels() != c))
        throw Error("a network filter needs a model taking and returning 1 (luma) or 3 (RGB) channels; '" +
                    m.name() + "' takes " + std::to_string(c) + " and returns " +
                    std::to_string(m.outputChannels()) +
                    (c == 6 ? " (a guided model names its guide method in its architecture)" : ""));
    if (precision == InferencePrecision::BFloat16 && !bf16Available())
        throw Error(
            "bf16 inference needs a CPU with AVX-512 BF16 (this one, or the SIMD level forced, has none)");
    grey = c == 1;
    field = receptiveField(m);
    if (!field.bounded)
        throw Error("model '" + m.name() +
                    "' warps by motion: what it sees has no bound, and a frame filter works in tiles");
    const int a = field.stride;
    halo = (field.radius + a - 1) / a * a;
    const int64_t side = (32 + a - 1) / a * a;
    const Shape out = m.outputShape({1, c, side, side});
    if (out[2] != side || out[3] != side)
        throw Error("model '" + m.name() + "' returns " + std::to_string(out[3]) + "x" +
                    std::to_string(out[2]) + " pixels for a " + std::to_string(side) + "x" +
                    std::to_string(side) + " frame; an anti-aliasing filter returns the size it is given");
}

FrameNetwork::~FrameNetwork() = default;
FrameNetwork::FrameNetwork(FrameNetwork&&) noexcept = default;
FrameNetwork& FrameNetwork::operator=(FrameNetwork&&) noexcept = default;

const Model& FrameNetwork::model() const {
    return impl_->model;
}
bool FrameNetwork::grey() const {
    return impl_->grey;
}
const std::string& FrameNetwork::guideMethod() const {
    return impl_->guideMethod;
}
int FrameNetwork::halo() const {
    return impl_->halo;
}
int FrameNetwork::alignment() const {
    return impl_->field.stride;
}
InferencePrecision FrameNetwork::precision() const {
    return impl_->precision;
}

void FrameNetwork::beginFrame(const float* in, int width, int height, int channels, const float* guide) {
    if (width < 1 || height < 1 || channels < 3 || !in)
        throw Error("a network filter needs an RGB frame of at least 1x1 pixel");
    Impl& m = *impl_;
    if (!m.guideMethod.empty() && !guide)
        throw Error("model '" + m.model.name() + "' reads " + m.guideMethod +
                    "'s result beside the frame, and none was given");
    m.in = in, m.width = width, m.height = height, m.channels = channels;
    m.guide = m.guideMethod.empty() ? nullptr : guide;
    if (!m.grey) return;
    // A grey model's input: the frame's luma.
    const size_t pixels = size_t(width) * size_t(height), C = size_t(channels);
    if (m.luma.size() < pixels) m.luma.resize(pixels);
    parallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
        for (size_t p = size_t(y0) * size_t(width); p < size_t(y1) * size_t(width); ++p)
            m.luma[p] = luma(in + p * C);
    });
}

FrameNetwork::RegionFigures FrameNetwork::runRegion(float* out, int cx0, int cy0, int cx1, int cy1,
                                                    float passSpan) {
    Impl& m = *impl_;
    const int a = m.field.stride, halo = m.halo, width = m.width, height = m.height;
    const bool grey = m.grey;
    const size_t C = size_t(m.channels);
    // The frame as the network sees it: padded by replication up to a multiple of the stride.
    const int PW = (width + a - 1) / a * a, PH = (height + a - 1) / a * a;
    // Input region: the core plus the halo, clipped to the padded frame (all multiples of the stride).
    const int rx0 = std::max(0, cx0 - halo), ry0 = std::max(0, cy0 - halo);
    const int rx1 = std::min(PW, (cx1 + a - 1) / a * a + halo),
              ry1 = std::min(PH, (cy1 + a - 1) / a * a + halo);
    InferencePlan& plan = m.planFor(ry1 - ry0, rx1 - rx0);
    const int RW = rx1 - rx0, RH = ry1 - ry0;
    RegionRows region;
    region.in = m.in, region.guide = m.guide, region.luma = m.luma.data(), region.C = C;
    region.width = size_t(width);
    region.height = height, region.rx0 = rx0, region.ry0 = ry0, region.RW = RW, region.grey = grey;
    FrameRows rows;
    rows.in = m.in, rows.out = out, rows.luma = m.luma.data(), rows.C = C, rows.width = size_t(width);
    rows.rx0 = rx0, rows.ry0 = ry0, rows.cx0 = cx0, rows.cx1 = cx1, rows.grey = grey;
    plan.setPassThrough(passSpan);
    if (plan.canStreamInput()) {
        // The frame's rows go straight into the first layer and the output stage, band by band.
        plan.runStreamed(region, rows, cy0 - ry0, cy1 - ry0);
    } else {
        parallelFor(0, RH, 8, [&](int64_t j0, int64_t j1) {
            float* planes[6];
            const int planeCount = grey ? 1 : m.guide ? 6 : 3;
            for (int64_t j = j0; j < j1; ++j) {
                for (int c = 0; c < planeCount; ++c) planes[c] = plan.inputRow(0, c, j);
                region.row(0, j, planes);
            }
        });
        plan.runInPlace(rows, cy0 - ry0, cy1 - ry0);
    }
    RegionFigures figures;
    figures.madePixels = double(cy1 - cy0) * double(RW);  // the rows made, halo columns included
    figures.passedPixels = figures.madePixels * plan.passedThroughFraction();
    return figures;
}

void FrameNetwork::run(const float* in, float* out, int width, int height, int channels, const float* guide) {
    beginFrame(in, width, height, channels, guide);
    const size_t C = size_t(channels);
    if (C > 3)
        parallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
            for (size_t p = size_t(y0) * size_t(width); p < size_t(y1) * size_t(width); ++p)
                std::copy(in + p * C + 3, in + (p + 1) * C, out + p * C + 3);
        });
    runRegion(out, 0, 0, width, height, 0);
}

}  // namespace dejag::nn

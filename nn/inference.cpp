#include "nn/inference.h"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstring>
#include <limits>
#include <optional>
#include <type_traits>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/fast_conv.h"
#include "nn/kernel_filter_kernels.h"
#include "nn/ops.h"
#include "nn/plan_passes.h"
#include "nn/shuffle_kernels.h"

namespace dejag::nn {
namespace {

// ---- Ops on the blocked layout (nn/blocked.h); each writes the interior of its output. ----------------

// Zeroes the border of every plane (regions of the arena are reused, so a border may hold old data).
// elementBytes: 4 for float, 2 for a bf16 activation.
void zeroBorder(float* data, const BlockedShape& s, size_t elementBytes = sizeof(float)) {
    if (s.border == 0) return;
    char* bytes = reinterpret_cast<char*>(data);
    parallelFor(0, s.batch * s.channelBlocks(), 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const int64_t n = plane / s.channelBlocks(), cb = plane % s.channelBlocks();
            for (int64_t y = -s.border; y < s.height + s.border; ++y) {
                char* row = bytes + size_t(s.offset(n, cb, y, -s.border)) * elementBytes;
                if (y < 0 || y >= s.height) {
                    std::memset(row, 0, size_t(s.rowStride()) * elementBytes);
                } else {
                    std::memset(row, 0, size_t(s.border * s.block) * elementBytes);
                    std::memset(row + size_t((s.border + s.width) * s.block) * elementBytes, 0,
                                size_t(s.border * s.block) * elementBytes);
                }
            }
        }
    });
}

// A value read from / written to a float or bf16 activation.
inline float loadElement(const float* p) {
    return *p;
}
inline float loadElement(const uint16_t* p) {
    return fromBf16(*p);
}
inline void storeElement(float* p, float v) {
    *p = v;
}
inline void storeElement(uint16_t* p, float v) {
    *p = toBf16(v);
}

// Calls body(n, cb, y) for every interior row of every plane, in parallel.
template <class F>
void forEachRow(const BlockedShape& s, const F& body) {
    parallelFor(0, s.batch * s.channelBlocks() * s.height, 0, [&](int64_t first, int64_t last) {
        for (int64_t i = first; i < last; ++i) {
            const int64_t y = i % s.height, plane = i / s.height;
            body(plane / s.channelBlocks(), plane % s.channelBlocks(), y);
        }
    });
}

void blockedMaxPool(float* out, const BlockedShape& os, const float* in, const BlockedShape& is,
                    const MaxPool2dDesc& d) {
    const int B = os.block;
    forEachRow(os, [&](int64_t n, int64_t cb, int64_t y) {
        float* o = out + os.offset(n, cb, y, 0);
        for (int64_t x = 0; x < os.width; ++x, o += B) {
            for (int l = 0; l < B; ++l) o[l] = -std::numeric_limits<float>::infinity();
            for (int ky = 0; ky < d.kernel; ++ky) {
                const int64_t iy = y * d.stride - d.padding + ky;
                if (iy < 0 || iy >= is.height) continue;
                for (int kx = 0; kx < d.kernel; ++kx) {
                    const int64_t ix = x * d.stride - d.padding + kx;
                    if (ix < 0 || ix >= is.width) continue;
                    const float* p = in + is.offset(n, cb, iy, ix);
                    for (int l = 0; l < B; ++l) o[l] = std::max(o[l], p[l]);
                }
            }
        }
    });
}

void blockedActivation(float* out, const BlockedShape& os, const float* in, const BlockedShape& is,
                       const ActivationDesc& a) {
    forEachRow(os, [&](int64_t n, int64_t cb, int64_t y) {
        activationForward(out + os.offset(n, cb, y, 0), in + is.offset(n, cb, y, 0), os.width * os.block, a);
    });
}

void blockedAdd(float* out, const BlockedShape& os, const float* a, const BlockedShape& as, const float* b,
                const BlockedShape& bs) {
    forEachRow(os, [&](int64_t n, int64_t cb, int64_t y) {
        float* o = out + os.offset(n, cb, y, 0);
        const float* p = a + as.offset(n, cb, y, 0);
        const float* q = b + bs.offset(n, cb, y, 0);
        for (int64_t i = 0; i < os.width * os.block; ++i) o[i] = p[i] + q[i];
    });
}

// Generic element access for the reshuffling ops (concat, upsampling, pixel shuffle).
inline float& element(float* data, const BlockedShape& s, int64_t n, int64_t c, int64_t y, int64_t x) {
    return data[s.offset(n, c / s.block, y, x) + c % s.block];
}
inline float element(const float* data, const BlockedShape& s, int64_t n, int64_t c, int64_t y, int64_t x) {
    return data[s.offset(n, c / s.block, y, x) + c % s.block];
}

// `lanes` floats of each of `width` pixels (`step` floats apart on both sides) from src, or zeros if src is
// null: a fixed-size copy per pixel for the usual run lengths.
void copyLanes(float* out, const float* src, int lanes, int64_t width, int64_t step) {
    auto copy = [&]<int N>() {
        for (int64_t x = 0; x < width; ++x) std::memcpy(out + x * step, src + x * step, N * sizeof(float));
    };
    if (!src) {
        for (int64_t x = 0; x < width; ++x) std::memset(out + x * step, 0, size_t(lanes) * sizeof(float));
    } else if (lanes == 16) {
        copy.template operator()<16>();
    } else if (lanes == 8) {
        copy.template operator()<8>();
    } else if (lanes == 4) {
        copy.template operator()<4>();
    } else {
        for (int64_t x = 0; x < width; ++x)
            for (int l = 0; l < lanes; ++l) out[x * step + l] = src[x * step + l];
    }
}

// The kernel filter (nn/layers.h) between blocked tensors, a pixel at a time.
// With a history (hs), the last weight takes the history's own pixel.
void blockedKernelFilter(float* out, const BlockedShape& os, const float* in, const BlockedShape& is,
                         const float* logits, const BlockedShape& ls, const KernelFilterDesc& d,
                         const float* history = nullptr, const BlockedShape* hs = nullptr) {
    const int r = d.kernel / 2, taps = d.kernel * d.kernel, count = int(d.weights());
    parallelFor(0, os.batch * os.height, 0, [&](int64_t first, int64_t last) {
        float w[50];
        for (int64_t row = first; row < last; ++row) {
            const int64_t n = row / os.height, y = row % os.height;
            for (int64_t x = 0; x < os.width; ++x) {
                for (int j = 0; j < count; ++j) w[j] = element(logits, ls, n, j, y, x);
                kernelFilterWeights(w, w, d);
                for (int64_t c = 0; c < os.channelBlocks() * os.block; ++c) {
                    float value = 0;
                    if (c < os.channels)
                        for (int dy = -r, j = 0; dy <= r; ++dy)
                            for (int dx = -r; dx <= r; ++dx, ++j)
                                value += w[j] * element(in, is, n, c,
                                                        std::clamp<int64_t>(y + dy, 0, is.height - 1),
                                                        std::clamp<int64_t>(x + dx, 0, is.width - 1));
                    if (history && c < os.channels) value += w[taps] * element(history, *hs, n, c, y, x);
                    element(out, os, n, c, y, x) = value;
                }
            }
        }
    });
}

// The accumulate blend (nn/layers.h) between blocked tensors, a pixel at a time.
void blockedAccumulate(float* out, const BlockedShape& os, const float* in, const BlockedShape& is,
                       const float* logits, const BlockedShape& ls, const float* history,
                       const BlockedShape& hs, int kernel, float maxCount, bool clip) {
    const int r = kernel / 2, taps = kernel * kernel;
    const int64_t C = is.channels;
    parallelFor(0, os.batch * os.height, 0, [&](int64_t first, int64_t last) {
        float w[50], spatial[64], sample[64], hist[64], shown[64], kept[64];
        for (int64_t row = first; row < last; ++row) {
            const int64_t n = row / os.height, y = row % os.height;
            for (int64_t x = 0; x < os.width; ++x) {
                float largest = -INFINITY, sum = 0;
                for (int j = 0; j < taps; ++j)
                    largest = std::max(largest, w[j] = element(logits, ls, n, j, y, x));
                for (int j = 0; j < taps; ++j) sum += (w[j] = std::exp(w[j] - largest));
                for (int j = 0; j < taps; ++j) w[j] /= sum;
                for (int64_t c = 0; c < C; ++c) {
                    float value = 0, low = INFINITY, high = -INFINITY;
                    for (int dy = -r, j = 0; dy <= r; ++dy)
                        for (int dx = -r; dx <= r; ++dx, ++j) {
                            const float tap =
                                element(in, is, n, c, std::clamp<int64_t>(y + dy, 0, is.height - 1),
                                        std::clamp<int64_t>(x + dx, 0, is.width - 1));
                            value += w[j] * tap, low = std::min(low, tap), high = std::max(high, tap);
                        }
                    spatial[c] = value;
                    sample[c] = element(in, is, n, c, y, x);
                    hist[c] = element(history, hs, n, c, y, x);
                    if (clip) hist[c] = std::clamp(hist[c], srgbDecode(low), srgbDecode(high));
                }
                const float s =
                    accumulatePixel(shown, kept, spatial, sample, hist, C, element(logits, ls, n, taps, y, x),
                                    element(history, hs, n, C, y, x), maxCount);
                for (int64_t c = 0; c < os.channelBlocks() * os.block; ++c)
                    element(out, os, n, c, y, x) = c < C       ? shown[c]
                                                   : c < 2 * C ? kept[c - C]
                                                               : (c == 2 * C ? s : 0.0f);
            }
        }
    });
}

template <class F>
void forEachOutputElement(const BlockedShape& os, const F& body) {
    parallelFor(0, os.batch * os.channels * os.height, 0, [&](int64_t first, int64_t last) {
        for (int64_t i = first; i < last; ++i) {
            const int64_t y = i % os.height, c = (i / os.height) % os.channels,
                          n = i / (os.height * os.channels);
            for (int64_t x = 0; x < os.width; ++x) body(n, c, y, x);
        }
    });
}

}  // namespace

// ---- The plan ---------------------------------------------------------------------------------------

struct InferencePlan::Impl {
    // A node's step: the passes' decisions (plan::NodePlan), its shape, place and packed convolution.
    struct Step : plan::NodePlan {
        GraphNode node;
        BlockedShape shape;               // this node's output
        int64_t offset = 0;               // into the arena (floats)
        std::optional<BlockedConv> conv;  // conv2d, conv_transpose2d
        MaxPool2dDesc pool;               // maxpool2d
        bool sigmoidAfterConv = false;
    };
    InferencePrecision precision = InferencePrecision::Float32;
    int bf16Activations = 0;
    Shape inputShape, outputShape;
    BlockedShape inputBlocked;
    int64_t inputOffset = 0;
    std::vector<Step> steps;
    int outputStep = -1;
    // The residual output stage: when the output is `add(input, pixel_shuffle(x))` and nothing else
    // reads the shuffle, the plan writes input + shuffle(x) straight into the planar output from x —
    // no shuffled tensor, no blocked sum, no conversion (for dejag-fast at 1080p: 500 MB of memory
    // traffic less per frame). x's step index, or -1.
    int residualSource = -1;
    int residualFactor = 1;
    // The kernel filter output stage: when the output is `kernel_filter(input, pixel_shuffle(x))` (a
    // kernel-predicting network) and nothing else reads the shuffle, each output row's logits are
    // gathered from x into a scratch row and the row is filtered from the caller's planar input straight
    // into the planar output. x's step index, or -1.
    int kernelSource = -1;
    int kernelGuideFrom = -1;  // a guided kpn's: the input channel its guide starts at (the history's rows)
    int kernelFactor = 1;
    KernelFilterDesc kernelFilter;
    // ... and when x is a 1x1 convolution read by nothing else (a KPN's head), that convolution is fused
    // too: each row's logits are computed from the convolution's input (kernelFeatures, the step index),
    // so the logit tensor is never stored (for dejag-fast at 1080p: 36 floats per half-resolution pixel,
    // 75 MB written and read back per frame). Its weights by row phase: [factor][taps][factor][inputs].
    int kernelFeatures = -1;
    int kernelFeatureChannels = 0;
    std::vector<float> kernelHeadWeights, kernelHeadBias;
    static constexpr int kRowParts = 16;  // the output stages' row ranges, each with its own scratch
    static constexpr int kKernelMaxChannels = plan::kKernelMaxChannels;
    Tensor kernelScratch;                   // [parts][kernel^2][W]
    Tensor rowScratch;                      // [parts][C][W]: output rows on their way to a sink (runInPlace)
    std::vector<const float*> rowPointers;  // [parts][C]: the rows handed to a sink
    Tensor staged;  // the input written through inputRow() when the plan holds it blocked

    // Pass-through (setPassThrough): the span, per part a row's flags per group of kPassGroup columns,
    // and per part the groups passed in the last run.
    float passSpan = 0.0f;
    int64_t passGroupsPerRow = 0, passGroupsTotal = 0;
    std::vector<uint8_t> passGroups;
    std::vector<int64_t> passCounts;
    // Streamed input (runStreamed): band buffers for the convolutions reading the input, one per chunk
    // of bands, and per output part a ring of the input rows the output stage reads.
    bool streamInput = false;
    Tensor bandBuffers;  // [chunks][band floats]
    std::vector<float*> bandPointers;
    int ringSlots = 1;
    Tensor inputRing;               // [parts][ringSlots][C][W]
    std::vector<int64_t> ringRows;  // [parts][ringSlots]: the input row each slot holds (-1: none)

    // Pass-through marks for the whole run (markFlat), when the head is fused and there is one image:
    // flatRows [H][groups], and per source row of the head's features the groups whose features some
    // unpassed output pixel needs (keepFeatures [H / factor][groups]: the layer making them skips the
    // rest).
    bool flatMarked = false;
    std::vector<uint8_t> flatRows, keepFeatures;
    // ... and the pixel shuffle into the features' layer's concatenation (keepShuffle, its rows by groups of
    // kPassGroup / 2 columns) and the convolution it shuffles (keepShuffleSource, groups of kPassGroup / 4),
    // when those feed nothing else; keepRadius: the features' layer's reach into the concatenation.
    int keepShuffleStep = -1, keepShuffleSourceStep = -1, keepRadius = 1;
    std::vector<uint8_t> keepShuffle, keepShuffleSource;
    // A streamed input is marked from its bands (no read of the frame for the marks alone): as the
    // first convolution's bands are filled, each input row's ranges per group (kernelRowRanges: rowLow
    // and rowHigh [H][groups][C], rowBad [H][groups]; rowRanged [H], claimed by the first band to hold
    // the row), then the marks from them once that convolution has run (markFlatFromRanges).
    bool rangesWanted = false;
    int64_t markBegin = 0, markEnd = 0;
    std::vector<float> rowLow, rowHigh;
    std::vector<uint8_t> rowBad, rowRanged;

    // Row y of input channel c for output part `part`: the caller's planes, the arena's planar input, or
    // (streamed) the part's ring of rows.
    const float* inputRowAt(int64_t part, int64_t n, int64_t c, int64_t y, const float* planes,
                            InputRowSource* streamed);
    void markFlat(const float* planes, InputRowSource* streamed, int64_t rowBegin, int64_t rowEnd);
    void markFlatFromRanges(InputRowSource& source);
    // The keep masks from flatRows, for output rows [rowBegin, rowEnd).
    void markKeeps(int64_t rowBegin, int64_t rowEnd);
    // streamed: the input's source (null: the input is in the arena).
    void runSteps(InputRowSource* streamed);
    void finish(const float* planes, OutputRowSink* sink, int64_t rowBegin, int64_t rowEnd,
                InputRowSource* streamed);
    // The constructor's steps after the passes (nn/plan_passes.h).
    void useOutputStages(const std::optional<plan::ResidualOutput>& residual,
                         std::optional<plan::KernelOutput>& kernel);
    void packConv(const plan::PlanGraph& g, Step& step, const float* weight, int inputBlock);
    void shapeActivations(const plan::PlanGraph& g, bool planarInput);
    void assignPrecision(const plan::PlanGraph& g);
    void planArena(const plan::PlanGraph& g);
    void planOutputStages(const plan::PlanGraph& g);
    void planStreaming(const plan::PlanGraph& g, bool planarInput,
                       const std::optional<plan::ResidualOutput>& residual,
                       const std::optional<plan::KernelOutput>& kernel);
    Tensor arena;
    Tensor output;
    size_t unpackedBytes = 0;
    int64_t macs = 0;
    int block = 1;

    std::vector<char> bf16Buffer;  // per node: its buffer holds bf16 (empty for Float32)
    bool isBf16(int buffer) const { return buffer >= 0 && !bf16Buffer.empty() && bf16Buffer[size_t(buffer)]; }

    float* data(int index) { return arena.data() + (index < 0 ? inputOffset : steps[size_t(index)].offset); }
    const BlockedShape& shape(int index) const {
        return index < 0 ? inputBlocked : steps[size_t(index)].shape;
    }
};

InferencePlan::InferencePlan(const Model& model, const Shape& inputShape, InferencePrecision precision)
    : impl_(std::make_unique<Impl>()) {
    Impl& m = *impl_;
    if (precision == InferencePrecision::BFloat16 && !bf16Available())
        throw Error("inference: bf16 needs a CPU with AVX-512 BF16 and the avx512 SIMD level");
    m.precision = precision;
    const plan::PlanGraph g(model, inputShape);
    m.inputShape = inputShape;
    m.outputStep = g.output;
    m.outputShape = g.shapeOf(g.output);
    m.block = simdFloatLanes(activeSimdLevel());

    // The output stages, then the layout of the input.
    const std::optional<plan::ResidualOutput> residual = plan::fuseResidualOutput(g);
    std::optional<plan::KernelOutput> kernel = plan::fuseKernelOutput(g);
    if (kernel) plan::fuseKernelHead(g, *kernel);
    const bool planarInput = plan::planarInput(g, residual, kernel);
    m.useOutputStages(residual, kernel);

    // Every step, its convolution packed; the convolutions' kernels say how wide a border every
    // activation needs.
    for (int i = 0; i < g.size(); ++i) {
        Impl::Step step;
        step.node = g.node(i);
        if (g.isConvolution(i)) {
            m.packConv(g, step, g.params + step.node.weightOffset,
                       planarInput && step.node.inputs[0] < 0 ? 1 : 0);
            m.macs += step.conv->macs();
        } else if (step.node.op == GraphOp::MaxPool2d) {
            step.pool = step.node.poolDesc(g.shapeOf(step.node.inputs[0]));
        }
        m.steps.push_back(std::move(step));
    }
    for (const plan::ConcatInPlace& c : plan::concatInPlace(g)) {
        m.steps[size_t(c.conv)].concatBuffer = m.steps[size_t(c.shuffle)].concatBuffer = c.concat;
        m.steps[size_t(c.shuffle)].laneOffset = c.laneOffset;
        m.steps[size_t(c.concat)].concatInPlace = true;
        for (int r = 0; r < g.size(); ++r)  // its readers' weights in the lanes' order
            if (std::find(g.node(r).inputs.begin(), g.node(r).inputs.end(), c.concat) !=
                g.node(r).inputs.end())
                m.packConv(g, m.steps[size_t(r)], plan::permutedWeights(g, c, r).data(), 0);
    }
    for (const plan::PoolFusion& p : plan::fusePooling(g)) {
        m.steps[size_t(p.conv)].conv->fuseMaxPool2x2();
        m.steps[size_t(p.conv)].pooledInto = p.pool;
        m.steps[size_t(p.pool)].fusedIntoConv = true;
    }
    for (int node :
         {residual ? residual->add : -1, residual ? residual->shuffle : -1, kernel ? kernel->filter : -1,
          kernel ? kernel->shuffle : -1, kernel && kernel->features >= 0 ? kernel->source : -1,
          kernel ? kernel->frameSlice : -1, kernel ? kernel->guideSlice : -1})
        if (node >= 0) m.steps[size_t(node)].fusedIntoOutput = true;
    m.shapeActivations(g, planarInput);
    if (precision == InferencePrecision::BFloat16) m.assignPrecision(g);
    m.planArena(g);
    m.planOutputStages(g);
    m.planStreaming(g, planarInput, residual, kernel);
}

// The output stages' fields from the passes' decisions.
void InferencePlan::Impl::useOutputStages(const std::optional<plan::ResidualOutput>& residual,
                                          std::optional<plan::KernelOutput>& kernel) {
    if (residual) residualSource = residual->source, residualFactor = residual->factor;
    if (!kernel) return;
    kernelSource = kernel->source, kernelFactor = kernel->factor;
    kernelFilter = kernel->desc;
    kernelGuideFrom = kernel->guideFrom;
    kernelScratch = Tensor({kRowParts, kernelFilter.weights(), inputShape[3]});
    kernelFeatures = kernel->features, kernelFeatureChannels = kernel->featureChannels;
    kernelHeadWeights = std::move(kernel->headWeights);
    kernelHeadBias = std::move(kernel->headBias);
}

// A step's convolution packed from `weight` (the model's, or permuted for a concatenation in place).
void InferencePlan::Impl::packConv(const plan::PlanGraph& g, Step& step, const float* weight,
                                   int inputBlock) {
    const GraphNode& n = step.node;
    const Shape& in = g.shapeOf(n.inputs[0]);
    const float* bias = n.biasOffset >= 0 ? g.params + n.biasOffset : nullptr;
    ActivationDesc fused = n.activation;
    step.sigmoidAfterConv = fused.kind == Activation::Sigmoid;  // not fused: applied afterwards
    if (step.sigmoidAfterConv) fused.kind = Activation::None;
    if (n.op == GraphOp::Conv2d)
        step.conv.emplace(n.convDesc(in), weight, bias, fused, inputBlock);
    else
        step.conv.emplace(n.convTransposeDesc(in), weight, bias, fused, inputBlock);
}

// Every activation's blocked shape, with the border the widest convolution needs.
void InferencePlan::Impl::shapeActivations(const plan::PlanGraph& g, bool planarInput) {
    int border = 0;
    for (const Step& step : steps)
        if (step.conv) border = std::max(border, step.conv->requiredInputBorder());
    auto blockedOf = [&](const Shape& s) { return BlockedShape{s[0], s[1], s[2], s[3], block, border}; };
    inputBlocked = blockedOf(inputShape);
    if (planarInput) inputBlocked.block = 1;
    for (int i = 0; i < g.size(); ++i) steps[size_t(i)].shape = blockedOf(g.shapeOf(i));
    // A network's last layer with 1-4 outputs, read by nothing but the conversion to planes, writes them
    // compactly (4 floats per pixel for 3 channels instead of a vector of 16).
    if (Step& last = steps[size_t(outputStep)];
        last.conv && last.conv->compactOutputBlock() > 0 && g.readers(outputStep) == 0) {
        last.conv->useCompactOutput();
        last.shape.block = last.conv->outputShape(border).block;
    }
}

// bf16 activations (plan::assignPrecision): the input, the output and the output stages' sources stay
// float.
void InferencePlan::Impl::assignPrecision(const plan::PlanGraph& g) {
    std::vector<plan::NodePlan> nodes(steps.begin(), steps.end());
    std::vector<plan::NodeKernel> kernels(steps.size());
    for (size_t i = 0; i < steps.size(); ++i)
        if (const Step& step = steps[i]; step.conv)
            kernels[i] = {step.conv->canWriteBf16() && !step.sigmoidAfterConv, step.conv->canReadBf16()};
    plan::Precision p =
        plan::assignPrecision(g, nodes, kernels, {outputStep, residualSource, kernelSource, kernelFeatures});
    for (size_t i = 0; i < steps.size(); ++i) {
        Step& step = steps[i];
        step.inBf16 = nodes[i].inBf16, step.outBf16 = nodes[i].outBf16;
        if (step.conv && step.inBf16) step.conv->useBf16Input();
    }
    bf16Activations = p.bf16Activations;
    bf16Buffer = std::move(p.bf16Buffer);
}

// The arena (plan::placeFirstFit): a tensor lives from its producer to its last consumer; a bf16 buffer
// takes half the floats.
void InferencePlan::Impl::planArena(const plan::PlanGraph& g) {
    std::vector<int64_t> floats(steps.size() + 1);
    floats[0] = inputBlocked.floatCount();
    for (size_t i = 0; i < steps.size(); ++i)
        floats[i + 1] = isBf16(int(i)) ? (steps[i].shape.floatCount() + 1) / 2 : steps[i].shape.floatCount();
    const std::vector<plan::NodePlan> nodes(steps.begin(), steps.end());
    const plan::ArenaTensors tensors = plan::arenaTensors(
        g, nodes, floats, {outputStep, residualSource, kernelFeatures >= 0 ? kernelFeatures : kernelSource});
    const plan::ArenaPlan arenaPlan = plan::placeFirstFit(tensors.tensors);
    for (size_t t = 0; t < tensors.buffer.size(); ++t) {
        const int buffer = tensors.buffer[t];
        const int64_t offset = arenaPlan.offsets[t];
        if (buffer < 0) {
            inputOffset = offset;
            continue;
        }
        steps[size_t(buffer)].offset = offset;
        for (Step& step :
             steps)  // the concatenation's inputs write into its buffer, a pooled conv its pooling's
            if (step.concatBuffer == buffer || step.pooledInto == buffer) step.offset = offset;
    }
    unpackedBytes = size_t(arenaPlan.unpackedFloats) * sizeof(float);
    arena = Tensor({std::max<int64_t>(arenaPlan.floats, 16)});
}
// The output and the output stages' scratch: the rows on their way to a sink, the pass-through groups and
// the marks for the whole run.
void InferencePlan::Impl::planOutputStages(const plan::PlanGraph& g) {
    output = Tensor(outputShape);
    if (residualSource >= 0 || kernelSource >= 0)
        rowScratch = Tensor({kRowParts, outputShape[1], outputShape[3]});
    rowPointers.resize(size_t(kRowParts * outputShape[1]));
    if (inputBlocked.block != 1) staged = Tensor(inputShape);
    if (kernelSource >= 0 && kernelFeatures >= 0 && inputShape[0] == 1 && kPassGroup % kernelFactor == 0) {
        const int64_t groups = (inputShape[3] + kPassGroup - 1) / kPassGroup;
        flatRows.assign(size_t(inputShape[2] * groups), 0);
        keepFeatures.assign(size_t((inputShape[2] + kernelFactor - 1) / kernelFactor * groups), 1);
        // Further back (a U-Net's last level): when the features' layer reads a concatenation in place
        // whose other part is a factor-2 pixel shuffle of a convolution read by nothing else, that shuffle
        // and that convolution are needed only around the kept features too.
        const GraphNode& features = g.node(kernelFeatures);
        const int cat = features.inputs.empty() ? -1 : features.inputs[0];
        if (features.op == GraphOp::Conv2d && cat >= 0 && steps[size_t(cat)].concatInPlace &&
            g.readers(cat) == 1 && kernelFactor == 2)
            for (int i = 0; i < g.size(); ++i) {
                const GraphNode& n = g.node(i);
                if (n.op != GraphOp::PixelShuffle || steps[size_t(i)].concatBuffer != cat || n.factor != 2)
                    continue;
                const int source = n.inputs[0];
                if (source < 0 || g.opOf(source) != GraphOp::Conv2d || g.readers(source) != 1) continue;
                keepShuffleStep = i, keepShuffleSourceStep = source;
                keepRadius = int(std::max(features.kernel / 2, 1) * features.dilation);
                keepShuffle.assign(size_t(g.shapeOf(cat)[2] * groups), 1);
                keepShuffleSource.assign(size_t(g.shapeOf(source)[2] * groups), 1);
            }
    }
    if (kernelSource >= 0) {
        passGroupsPerRow = (inputShape[3] + kPassGroup - 1) / kPassGroup;
        passGroups.assign(size_t(kRowParts * passGroupsPerRow), 0);
        passCounts.assign(size_t(kRowParts), 0);
    }
}

// A streamed input (runStreamed): one image, planar, read only by single-pass convolutions (given it in
// bands) and the output stage (given it in rows).
void InferencePlan::Impl::planStreaming(const plan::PlanGraph& g, bool planarInput,
                                        const std::optional<plan::ResidualOutput>& residual,
                                        const std::optional<plan::KernelOutput>& kernel) {
    streamInput = planarInput && inputShape[0] == 1 && inputShape[1] <= 16;
    int64_t bandFloats = 0;
    for (int i = 0; i < g.size(); ++i)
        for (int source : g.node(i).inputs) {
            if (source >= 0 || (residual && i == residual->add) ||
                (kernel && (i == kernel->filter || i == kernel->frameSlice || i == kernel->guideSlice)))
                continue;
            const Step& step = steps[size_t(i)];
            if (g.opOf(i) == GraphOp::Conv2d && step.conv && step.conv->canBandInput())
                bandFloats = std::max(bandFloats, step.conv->bandShape(inputBlocked).floatCount());
            else
                streamInput = false;
        }
    if (!streamInput) return;
    const int chunks = std::max(1, threadCount());
    bandBuffers = Tensor({chunks, (bandFloats + 15) / 16 * 16});
    for (int k = 0; k < chunks; ++k) bandPointers.push_back(bandBuffers.data() + k * bandBuffers.shape()[1]);
    ringSlots = kernelSource >= 0 ? kernelFilter.kernel : 1;
    inputRing = Tensor({kRowParts, ringSlots, inputShape[1], inputShape[3]});
    ringRows.assign(size_t(kRowParts * ringSlots), -1);
    if (!flatRows.empty()) {
        const int64_t H = inputShape[2], G = passGroupsPerRow, C = inputShape[1];
        rowLow.assign(size_t(H * G * C), 0.0f);
        rowHigh.assign(size_t(H * G * C), 0.0f);
        rowBad.assign(size_t(H * G), 0);
        rowRanged.assign(size_t(H), 0);
    }
}

InferencePlan::InferencePlan(InferencePlan&&) noexcept = default;
InferencePlan& InferencePlan::operator=(InferencePlan&&) noexcept = default;
InferencePlan::~InferencePlan() = default;

const Shape& InferencePlan::inputShape() const {
    return impl_->inputShape;
}
const Shape& InferencePlan::outputShape() const {
    return impl_->outputShape;
}
size_t InferencePlan::arenaBytes() const {
    return impl_->arena.byteSize();
}
size_t InferencePlan::unpackedBytes() const {
    return impl_->unpackedBytes;
}
int64_t InferencePlan::macs() const {
    return impl_->macs;
}

InferencePrecision InferencePlan::precision() const {
    return impl_->precision;
}

int InferencePlan::bf16Activations() const {
    return impl_->bf16Activations;
}

const Tensor& InferencePlan::run(const Tensor& input) {
    if (const int64_t bad = input.findNonFinite(); bad >= 0)
        throw Error("the model input has a non-finite value at element " + std::to_string(bad));
    return runUnchecked(input);
}

const Tensor& InferencePlan::runUnchecked(const Tensor& input) {
    Impl& m = *impl_;
    input.requireShape(m.inputShape, "inference input");
    if (m.block != simdFloatLanes(activeSimdLevel()))
        throw Error("inference: the SIMD level changed since planning");
    zeroBorder(m.data(-1), m.inputBlocked);
    toBlocked(m.data(-1), input.data(), m.inputBlocked);
    m.markFlat(input.data(), nullptr, 0, m.outputShape[2]);
    m.runSteps(nullptr);
    m.finish(input.data(), nullptr, 0, m.outputShape[2], nullptr);
    return m.output;
}

float* InferencePlan::inputRow(int64_t n, int64_t c, int64_t y) {
    Impl& m = *impl_;
    const Shape& s = m.inputShape;
    if (n < 0 || n >= s[0] || c < 0 || c >= s[1] || y < 0 || y >= s[2])
        throw Error("inference: input row out of range");
    if (m.inputBlocked.block == 1) return m.data(-1) + m.inputBlocked.offset(n, c, y, 0);
    return m.staged.data() + ((n * s[1] + c) * s[2] + y) * s[3];
}

void InferencePlan::runInPlace(OutputRowSink& sink, int64_t rowBegin, int64_t rowEnd) {
    Impl& m = *impl_;
    if (m.block != simdFloatLanes(activeSimdLevel()))
        throw Error("inference: the SIMD level changed since planning");
    rowBegin = std::max<int64_t>(0, rowBegin), rowEnd = std::min(rowEnd, m.outputShape[2]);
    zeroBorder(m.data(-1), m.inputBlocked);  // the interior is the caller's rows
    if (m.inputBlocked.block != 1) toBlocked(m.data(-1), m.staged.data(), m.inputBlocked);
    const float* planes = m.inputBlocked.block == 1 ? nullptr : m.staged.data();
    m.markFlat(planes, nullptr, rowBegin, rowEnd);
    m.runSteps(nullptr);
    m.finish(planes, &sink, rowBegin, rowEnd, nullptr);
}

void InferencePlan::setPassThrough(float span) {
    impl_->passSpan = impl_->kernelSource >= 0 && span > 0 ? span : 0.0f;
}

double InferencePlan::passedThroughFraction() const {
    const Impl& m = *impl_;
    int64_t passed = 0;
    for (int64_t count : m.passCounts) passed += count;
    return m.passGroupsTotal > 0 ? double(passed) / double(m.passGroupsTotal) : 0.0;
}

bool InferencePlan::canStreamInput() const {
    return impl_->streamInput;
}

void InferencePlan::runStreamed(InputRowSource& source, OutputRowSink& sink, int64_t rowBegin,
                                int64_t rowEnd) {
    Impl& m = *impl_;
    if (!m.streamInput) throw Error("inference: this plan cannot stream its input (canStreamInput())");
    if (m.block != simdFloatLanes(activeSimdLevel()))
        throw Error("inference: the SIMD level changed since planning");
    rowBegin = std::max<int64_t>(0, rowBegin), rowEnd = std::min(rowEnd, m.outputShape[2]);
    if (m.passSpan > 0 && !m.rowLow.empty()) {
        // Marked from the first convolution's bands (runSteps).
        m.flatMarked = false;
        m.rangesWanted = true, m.markBegin = rowBegin, m.markEnd = rowEnd;
        std::fill(m.rowRanged.begin(), m.rowRanged.end(), uint8_t(0));
    } else {
        m.markFlat(nullptr, &source, rowBegin, rowEnd);
    }
    m.runSteps(&source);
    if (m.rangesWanted) m.markFlatFromRanges(source);  // no convolution read the input
    m.finish(nullptr, &sink, rowBegin, rowEnd, &source);
}

namespace {

// A convolution's input band from a streamed source (rows outside the image are zero), with each row's
// ranges for the pass-through marks while it is in the cache (when `ranged` is set).
struct BandFromSource final : BlockedConv::BandInput {
    InputRowSource* source = nullptr;
    int64_t channels = 0, height = 0, width = 0;
    uint8_t* ranged = nullptr;  // per row: 1 once a band has taken its ranges
    float *low = nullptr, *high = nullptr;
    uint8_t* bad = nullptr;
    int64_t groups = 0;
    int radius = 0;
    void fill(int64_t firstRow, int64_t rows, float* band, const BlockedShape& shape) override {
        float* row[16];
        for (int64_t y = firstRow; y < firstRow + rows; ++y) {
            for (int64_t c = 0; c < channels; ++c) row[c] = band + shape.offset(0, c, y - firstRow, 0);
            if (y < 0 || y >= height) {
                for (int64_t c = 0; c < channels; ++c) std::fill_n(row[c], width, 0.0f);
            } else {
                source->row(0, y, row);
                // Bands overlap by a row or two: the first to hold a row takes its ranges.
                if (ranged &&
                    std::atomic_ref<uint8_t>(ranged[y]).exchange(1, std::memory_order_relaxed) == 0) {
                    const size_t at = size_t(y * groups);
                    DEJAG_SIMD_CALL(kernelRowRanges, row, int(channels), width, radius,
                                    low + at * size_t(channels), high + at * size_t(channels), bad + at);
                }
            }
        }
    }
};

}  // namespace

void InferencePlan::Impl::runSteps(InputRowSource* streamed) {
    Impl& m = *this;
    BandFromSource band;
    band.source = streamed;
    band.channels = inputShape[1], band.height = inputShape[2], band.width = inputShape[3];
    if (streamed && m.rangesWanted) {
        band.ranged = m.rowRanged.data(), band.low = m.rowLow.data(), band.high = m.rowHigh.data();
        band.bad = m.rowBad.data(), band.groups = m.passGroupsPerRow, band.radius = m.kernelFilter.kernel / 2;
    }
    for (size_t i = 0; i < m.steps.size(); ++i) {
        Impl::Step& step = m.steps[i];
        if (step.fusedIntoConv || step.fusedIntoOutput || step.concatInPlace) continue;
        const GraphNode& n = step.node;
        const bool intoConcat = n.op == GraphOp::PixelShuffle && step.concatBuffer >= 0;
        const int target = step.pooledInto >= 0 ? step.pooledInto : intoConcat ? step.concatBuffer : int(i);
        float* out = m.data(target);
        const BlockedShape& os = m.shape(target);
        const float* in = m.data(n.inputs[0]);
        const BlockedShape& is = m.shape(n.inputs[0]);
        zeroBorder(out, os, step.outBf16 ? sizeof(uint16_t) : sizeof(float));
        switch (n.op) {
            case GraphOp::Conv2d:
            case GraphOp::ConvTranspose2d:
                if (int(i) == m.kernelFeatures && m.flatMarked) {
                    const BlockedConv::ColumnKeep keep{m.keepFeatures.data(), m.passGroupsPerRow,
                                                       kPassGroup / m.kernelFactor};
                    step.conv->forward(out, os, in, is, step.inBf16, step.outBf16, &keep);
                } else if (int(i) == m.keepShuffleSourceStep && m.flatMarked) {
                    const BlockedConv::ColumnKeep keep{m.keepShuffleSource.data(), m.passGroupsPerRow,
                                                       kPassGroup / 4};
                    step.conv->forward(out, os, in, is, step.inBf16, step.outBf16, &keep);
                } else if (streamed && n.inputs[0] < 0) {
                    step.conv->forwardBanded(out, os, is, band, bandPointers.data(), int(bandPointers.size()),
                                             step.outBf16);
                    if (m.rangesWanted) {  // every row the convolution read has its ranges: the marks
                        m.markFlatFromRanges(*streamed);
                        band.ranged = nullptr;
                    }
                } else
                    step.conv->forward(out, os, in, is, step.inBf16, step.outBf16);
                if (step.sigmoidAfterConv) blockedActivation(out, os, out, os, n.activation);
                break;
            case GraphOp::MaxPool2d:
                blockedMaxPool(out, os, in, is, step.pool);
                break;
            case GraphOp::Activation:
                blockedActivation(out, os, in, is, n.activation);
                break;
            case GraphOp::Add:
                blockedAdd(out, os, in, is, m.data(n.inputs[1]), m.shape(n.inputs[1]));
                break;
            case GraphOp::Concat: {
                // Row by row: a whole output block that is a whole source block is one copy; otherwise
                // each lane is copied from its source channel (lanes past the channel count are zeroed).
                const int B = os.block;
                forEachRow(os, [&](int64_t b, int64_t ob, int64_t y) {
                    float* o = out + os.offset(b, ob, y, 0);
                    const float* sources[64];
                    int whole = -1;  // a source whose block feeds this output block entirely
                    for (int l = 0; l < B; ++l) {
                        int64_t channel = ob * B + l;
                        sources[l] = nullptr;
                        if (channel >= os.channels) continue;
                        for (int source : n.inputs) {
                            const BlockedShape& ss = m.shape(source);
                            if (channel < ss.channels) {
                                sources[l] = m.data(source) + ss.offset(b, channel / B, y, 0) + channel % B;
                                if (l == 0 && channel % B == 0 && channel + B <= ss.channels &&
                                    ob * B + B <= os.channels)
                                    whole = source;
                                break;
                            }
                            channel -= ss.channels;
                        }
                    }
                    if (whole >= 0) {
                        std::memcpy(o, sources[0], size_t(os.width * B) * sizeof(float));
                        return;
                    }
                    // Runs of lanes that come from consecutive lanes of one source block (or are past
                    // the channel count): each is a short copy (or clear) per pixel.
                    for (int l = 0; l < B;) {
                        int run = 1;
                        while (l + run < B && (sources[l] ? sources[l + run] == sources[l] + run
                                                          : sources[l + run] == nullptr))
                            ++run;
                        copyLanes(o + l, sources[l], run, os.width, B);
                        l += run;
                    }
                });
                break;
            }
            case GraphOp::Upsample: {
                const int64_t f = n.factor;
                if (!n.bilinear) {
                    forEachOutputElement(os, [&](int64_t b, int64_t c, int64_t y, int64_t x) {
                        element(out, os, b, c, y, x) = element(in, is, b, c, y / f, x / f);
                    });
                } else {
                    forEachOutputElement(os, [&](int64_t b, int64_t c, int64_t y, int64_t x) {
                        // PyTorch align_corners=False, as the reference kernel.
                        const double sy = std::max(0.0, (double(y) + 0.5) / double(f) - 0.5);
                        const double sx = std::max(0.0, (double(x) + 0.5) / double(f) - 0.5);
                        const int64_t y0 = std::min<int64_t>(int64_t(sy), is.height - 1),
                                      y1 = std::min(y0 + 1, is.height - 1);
                        const int64_t x0 = std::min<int64_t>(int64_t(sx), is.width - 1),
                                      x1 = std::min(x0 + 1, is.width - 1);
                        const float ly = float(sy - double(y0)), lx = float(sx - double(x0));
                        element(out, os, b, c, y, x) = (1 - ly) * ((1 - lx) * element(in, is, b, c, y0, x0) +
                                                                   lx * element(in, is, b, c, y0, x1)) +
                                                       ly * ((1 - lx) * element(in, is, b, c, y1, x0) +
                                                             lx * element(in, is, b, c, y1, x1));
                    });
                }
                break;
            }
            case GraphOp::PixelShuffle: {
                // out(c, y, x) = in((c f + y % f) f + x % f, y / f, x / f), row by row, a pixel's lanes
                // written together (lanes past the channel count are zeroed). Into a concatenation in
                // place, channel c goes to lane `laneOffset` + c and the lanes before are left alone.
                const int64_t f = n.factor, first = step.laneOffset;
                const int64_t end = first + n.outChannels;  // lanes [first, end) are the shuffle's
                const int B = os.block;
                forEachRow(os, [&](int64_t b, int64_t ob, int64_t y) {
                    if (ob * B + B <= first) return;  // the conv input's blocks
                    const int from = int(std::max<int64_t>(0, first - ob * B));
                    const int valid = int(std::clamp<int64_t>(end - ob * B, from, B));
                    // Per column phase j = x % f, each lane's offset from the source row's pixel 0.
                    int64_t offset[16][16];  // factors and lanes up to 16
                    for (int64_t j = 0; j < f; ++j)
                        for (int l = from; l < valid; ++l) {
                            const int64_t k = ((ob * B + l - first) * f + y % f) * f + j;
                            offset[j][l] = is.offset(b, k / is.block, y / f, 0) - is.offset(b, 0, y / f, 0) +
                                           k % is.block;
                        }
                    // Float or bf16 on either side (a shuffle into a bf16 concatenation in place).
                    auto shuffleRow = [&](const auto* source, auto* destination) {
                        using In = std::remove_cv_t<std::remove_pointer_t<decltype(source)>>;
                        using Out = std::remove_pointer_t<decltype(destination)>;
                        for (int64_t x = 0; x < os.width; ++x) {
                            const int64_t* lane = offset[x % f];
                            const In* pixel = source + (x / f) * is.block;
                            Out* dst = destination + x * B;
                            if constexpr (std::is_same_v<In, Out>) {  // bits copied (no rounding)
                                for (int l = from; l < valid; ++l) dst[l] = pixel[lane[l]];
                                for (int l = valid; l < B; ++l) dst[l] = Out(0);
                            } else {
                                for (int l = from; l < valid; ++l)
                                    storeElement(dst + l, loadElement(pixel + lane[l]));
                                for (int l = valid; l < B; ++l) storeElement(dst + l, 0.0f);
                            }
                        }
                    };
                    const int64_t rowOffset = is.offset(b, 0, y / f, 0), outOffset = os.offset(b, ob, y, 0);
                    auto* in16 = reinterpret_cast<const uint16_t*>(in) + rowOffset;
                    auto* out16 = reinterpret_cast<uint16_t*>(out) + outOffset;
                    // By SIMD permutes where each phase's lanes come from at most two source blocks.
                    if (step.inBf16 == step.outBf16 && is.block == B && f <= 16) {
                        ShuffleRowArgs args;
                        args.source = step.inBf16 ? static_cast<const void*>(in16)
                                                  : static_cast<const void*>(in + rowOffset);
                        args.out =
                            step.outBf16 ? static_cast<void*>(out16) : static_cast<void*>(out + outOffset);
                        args.blockStride = is.planeStride(), args.width = os.width, args.factor = int(f);
                        args.bf16 = step.inBf16, args.from = from, args.valid = valid;
                        bool twoBlocks = true;
                        for (int64_t j = 0; j < f && twoBlocks; ++j) {
                            int64_t blocks[2] = {-1, -1};
                            for (int l = from; l < valid; ++l) {
                                const int64_t sourceBlock = offset[j][l] / is.planeStride(),
                                              within = offset[j][l] % is.planeStride();
                                const int slot = blocks[0] < 0 || blocks[0] == sourceBlock   ? 0
                                                 : blocks[1] < 0 || blocks[1] == sourceBlock ? 1
                                                                                             : 2;
                                if (slot == 2) {
                                    twoBlocks = false;
                                    break;
                                }
                                blocks[slot] = sourceBlock;
                                args.lane[j][l] = int32_t(within + slot * B);
                            }
                            args.firstBlock[j] = std::max<int64_t>(blocks[0], 0);
                            args.secondBlock[j] = blocks[1] < 0 ? args.firstBlock[j] : blocks[1];
                        }
                        if (twoBlocks && int(i) == m.keepShuffleStep && m.flatMarked && f == 2) {
                            // Only the runs of kept groups (kPassGroup / 2 columns, whole source pixels).
                            const uint8_t* keep = m.keepShuffle.data() + y * m.passGroupsPerRow;
                            const int64_t group = kPassGroup / 2, size = step.inBf16 ? 2 : 4;
                            const auto* sourceRow = static_cast<const char*>(args.source);
                            auto* outRow = static_cast<char*>(args.out);
                            bool done = true;
                            for (int64_t g = 0; g * group < os.width && done;) {
                                while (g * group < os.width && !keep[g]) ++g;
                                const int64_t start = g;
                                while (g * group < os.width && keep[g]) ++g;
                                if (start == g) break;
                                const int64_t x0 = start * group, x1 = std::min(os.width, g * group);
                                args.source = sourceRow + (x0 / 2) * is.block * size;
                                args.out = outRow + x0 * B * size;
                                args.width = x1 - x0;
                                done = DEJAG_SIMD_CALL(shuffleRow, args);
                            }
                            if (done) return;
                            args.source = sourceRow, args.out = outRow, args.width = os.width;
                        }
                        if (twoBlocks && DEJAG_SIMD_CALL(shuffleRow, args)) return;
                    }
                    if (step.inBf16)
                        step.outBf16 ? shuffleRow(in16, out16) : shuffleRow(in16, out + outOffset);
                    else
                        step.outBf16 ? shuffleRow(in + rowOffset, out16)
                                     : shuffleRow(in + rowOffset, out + outOffset);
                });
                break;
            }
            case GraphOp::KernelFilter: {
                const bool history = n.inputs.size() > 2;
                blockedKernelFilter(out, os, in, is, m.data(n.inputs[1]), m.shape(n.inputs[1]),
                                    n.kernelFilterDesc({is.batch, is.channels, is.height, is.width}, history),
                                    history ? m.data(n.inputs[2]) : nullptr,
                                    history ? &m.shape(n.inputs[2]) : nullptr);
                break;
            }
            case GraphOp::Slice:
                blockedSlice(out, os, in, is, n.sliceFrom);
                break;
            case GraphOp::Warp:
                blockedWarp(out, os, in, is, m.data(n.inputs[1]), m.shape(n.inputs[1]), n.warpFilter);
                break;
            case GraphOp::Accumulate:
                blockedAccumulate(out, os, in, is, m.data(n.inputs[1]), m.shape(n.inputs[1]),
                                  m.data(n.inputs[2]), m.shape(n.inputs[2]), n.kernel, n.maxCount, n.clip);
                break;
            case GraphOp::Count:
                break;
        }
    }
}

const float* InferencePlan::Impl::inputRowAt(int64_t part, int64_t n, int64_t c, int64_t y,
                                             const float* planes, InputRowSource* streamed) {
    const int64_t C = inputShape[1], H = inputShape[2], W = inputShape[3];
    if (!streamed)
        return planes ? planes + ((n * C + c) * H + y) * W : data(-1) + inputBlocked.offset(n, c, y, 0);
    const int64_t slot = y % ringSlots;
    float* rows = inputRing.data() + (part * ringSlots + slot) * C * W;
    if (int64_t& held = ringRows[size_t(part * ringSlots + slot)]; held != y) {
        float* channels[16];
        for (int64_t k = 0; k < C; ++k) channels[k] = rows + k * W;
        streamed->row(n, y, channels);
        held = y;
    }
    return rows + c * W;
}

// Marks the groups the output stage will pass through before any layer runs, so that the layer making
// the fused head's features computes only the columns an unpassed pixel needs.
void InferencePlan::Impl::markFlat(const float* planes, InputRowSource* streamed, int64_t rowBegin,
                                   int64_t rowEnd) {
    flatMarked = passSpan > 0 && !flatRows.empty();
    if (!flatMarked) return;
    const int64_t C = inputShape[1], H = inputShape[2], W = inputShape[3], G = passGroupsPerRow;
    const int k = kernelFilter.kernel, r = k / 2;
    rowBegin = std::max<int64_t>(0, rowBegin), rowEnd = std::min(rowEnd, H);
    if (streamed) std::fill(ringRows.begin(), ringRows.end(), int64_t(-1));
    const int64_t span = std::max<int64_t>(0, rowEnd - rowBegin);
    parallelFor(0, kRowParts, 1, [&](int64_t first, int64_t last) {
        for (int64_t part = first; part < last; ++part)
            for (int64_t y = rowBegin + span * part / kRowParts; y < rowBegin + span * (part + 1) / kRowParts;
                 ++y) {
                const float* in[kKernelMaxChannels * 7];
                KernelFilterRowArgs args;
                args.in = in, args.width = W, args.channels = int(C), args.kernel = k;
                for (int64_t c = 0; c < C; ++c)
                    for (int dy = -r; dy <= r; ++dy)
                        in[c * k + dy + r] =
                            inputRowAt(part, 0, c, std::clamp<int64_t>(y + dy, 0, H - 1), planes, streamed);
                DEJAG_SIMD_CALL(kernelFlatGroups, args, passSpan, flatRows.data() + y * G);
            }
    });
    markKeeps(rowBegin, rowEnd);
}

// The marks of output rows [markBegin, markEnd) from the rows' ranges: a group is flat in row y when
// rows y - r ... y + r (clamped) are not bad and in every channel the greatest of their highs minus the
// least of their lows is at most the span — the floats kernelFlatGroups() would compare. Rows no band
// held (a first layer that skips rows, as a 1x1 of stride 2 does) are read from the source for it.
void InferencePlan::Impl::markFlatFromRanges(InputRowSource& source) {
    rangesWanted = false;
    const int64_t C = inputShape[1], H = inputShape[2], W = inputShape[3], G = passGroupsPerRow;
    const int r = kernelFilter.kernel / 2;
    const int64_t rowBegin = markBegin, rowEnd = markEnd;
    for (int64_t y = std::max<int64_t>(0, rowBegin - r); y < std::min(H, rowEnd + r); ++y) {
        if (rowRanged[size_t(y)]) continue;
        float* channels[16];
        for (int64_t c = 0; c < C; ++c) channels[c] = rowScratch.data() + c * W;
        source.row(0, y, channels);
        DEJAG_SIMD_CALL(kernelRowRanges, channels, int(C), W, r, rowLow.data() + y * G * C,
                        rowHigh.data() + y * G * C, rowBad.data() + y * G);
        rowRanged[size_t(y)] = 1;
    }
    parallelFor(rowBegin, rowEnd, 32, [&](int64_t y0, int64_t y1) {
        for (int64_t y = y0; y < y1; ++y) {
            const int64_t top = std::max<int64_t>(0, y - r), bottom = std::min(H - 1, y + r);
            for (int64_t g = 0; g < G; ++g) {
                bool isFlat = true;
                for (int64_t yy = top; yy <= bottom && isFlat; ++yy) isFlat = !rowBad[size_t(yy * G + g)];
                for (int64_t c = 0; c < C && isFlat; ++c) {
                    float low = rowLow[size_t((top * G + g) * C + c)],
                          high = rowHigh[size_t((top * G + g) * C + c)];
                    for (int64_t yy = top + 1; yy <= bottom; ++yy) {
                        low = std::min(low, rowLow[size_t((yy * G + g) * C + c)]);
                        high = std::max(high, rowHigh[size_t((yy * G + g) * C + c)]);
                    }
                    isFlat = high - low <= passSpan;
                }
                flatRows[size_t(y * G + g)] = isFlat;
            }
        }
    });
    flatMarked = true;
    markKeeps(rowBegin, rowEnd);
}

void InferencePlan::Impl::markKeeps(int64_t rowBegin, int64_t rowEnd) {
    const int64_t H = inputShape[2], G = passGroupsPerRow;
    // A feature row's group is needed when an output row it feeds, inside [rowBegin, rowEnd), is not
    // passed there.
    const int64_t f = kernelFactor;
    for (int64_t s = 0; s * f < H; ++s)
        for (int64_t g = 0; g < G; ++g) {
            uint8_t keep = 0;
            for (int64_t y = s * f; y < std::min(H, s * f + f); ++y)
                keep |= y >= rowBegin && y < rowEnd && !flatRows[size_t(y * G + g)];
            keepFeatures[size_t(s * G + g)] = keep;
        }
    if (keepShuffleStep < 0) return;
    // The concatenation's rows and groups within the features' layer's reach of a kept one (a group
    // each side covers a reach up to a group), then the shuffled convolution's rows under them.
    const int64_t featureRows = int64_t(keepFeatures.size()) / G, catRows = int64_t(keepShuffle.size()) / G;
    for (int64_t y = 0; y < catRows; ++y)
        for (int64_t g = 0; g < G; ++g) {
            uint8_t keep = 0;
            for (int64_t yy = std::max<int64_t>(0, y - keepRadius);
                 yy <= std::min(featureRows - 1, y + keepRadius); ++yy)
                for (int64_t gg = std::max<int64_t>(0, g - 1); gg <= std::min(G - 1, g + 1); ++gg)
                    keep |= keepFeatures[size_t(yy * G + gg)];
            keepShuffle[size_t(y * G + g)] = keep;
        }
    for (int64_t q = 0; q < int64_t(keepShuffleSource.size()) / G; ++q)
        for (int64_t g = 0; g < G; ++g)
            keepShuffleSource[size_t(q * G + g)] =
                keepShuffle[size_t(std::min(catRows - 1, 2 * q) * G + g)] |
                keepShuffle[size_t(std::min(catRows - 1, 2 * q + 1) * G + g)];
}

// The output stages: rows [rowBegin, rowEnd) of every image into the output tensor, or to `sink` (through
// a part's scratch rows when the stage makes them). `planes`: the input as contiguous planes (the caller's
// tensor), or null to read the arena's planar copy.
void InferencePlan::Impl::finish(const float* planes, OutputRowSink* sink, int64_t rowBegin, int64_t rowEnd,
                                 InputRowSource* streamed) {
    Impl& m = *this;
    const int64_t C = m.outputShape[1], H = m.outputShape[2], W = m.outputShape[3];
    // Input row y of channel c: the caller's planes, the arena's, or (streamed) the part's ring, where
    // the rows of consecutive output rows stay until overwritten.
    if (streamed) std::fill(m.ringRows.begin(), m.ringRows.end(), int64_t(-1));
    std::fill(m.passCounts.begin(), m.passCounts.end(), int64_t(0));
    m.passGroupsTotal =
        m.passSpan > 0 ? m.outputShape[0] * std::max<int64_t>(0, rowEnd - rowBegin) * m.passGroupsPerRow : 0;
    auto inputRow = [&](int64_t part, int64_t n, int64_t c, int64_t y) {
        return m.inputRowAt(part, n, c, y, planes, streamed);
    };
    // Output row of channel c: the output tensor's, or the part's scratch row.
    auto outputRow = [&](int64_t part, int64_t n, int64_t c, int64_t y) -> float* {
        return sink ? m.rowScratch.data() + (part * C + c) * W : m.output.data() + ((n * C + c) * H + y) * W;
    };
    const int64_t span = rowEnd - rowBegin, rows = m.outputShape[0] * span;
    if (rows <= 0) return;
    // Calls body(part, n, y) for every output row, the rows cut into kRowParts ranges in parallel.
    auto forEachOutputRow = [&](const auto& body) {
        parallelFor(0, kRowParts, 1, [&](int64_t first, int64_t last) {
            for (int64_t part = first; part < last; ++part)
                for (int64_t row = rows * part / kRowParts; row < rows * (part + 1) / kRowParts; ++row)
                    body(part, row / span, rowBegin + row % span);
        });
    };
    auto deliver = [&](int64_t part, int64_t n, int64_t y, bool whole) {
        const float** channels = m.rowPointers.data() + part * C;
        for (int64_t c = 0; c < C; ++c)
            channels[c] = whole ? m.output.data() + ((n * C + c) * H + y) * W : outputRow(part, n, c, y);
        sink->row(n, y, channels);
    };
    if (m.residualSource >= 0) {
        // output(c, y, x) = input(c, y, x) + source((c f + y % f) f + x % f, y / f, x / f), row by row.
        const BlockedShape& ss = m.shape(m.residualSource);
        const float* source = m.data(m.residualSource);
        const int64_t f = m.residualFactor, B = ss.block;
        forEachOutputRow([&](int64_t part, int64_t n, int64_t y) {
            for (int64_t c = 0; c < C; ++c) {
                const float* subpixel[16];  // factors up to 16
                for (int64_t j = 0; j < f; ++j) {
                    const int64_t k = (c * f + y % f) * f + j;
                    subpixel[j] = source + ss.offset(n, k / ss.block, y / f, 0) + k % ss.block;
                }
                const float* in = inputRow(part, n, c, y);
                float* out = outputRow(part, n, c, y);
                if (f == 2) {
                    int64_t x = 0;
                    for (; x + 1 < W; x += 2) {
                        out[x] = in[x] + subpixel[0][(x / 2) * B];
                        out[x + 1] = in[x + 1] + subpixel[1][(x / 2) * B];
                    }
                    if (x < W) out[x] = in[x] + subpixel[0][(x / 2) * B];
                } else {
                    for (int64_t x = 0; x < W; ++x) out[x] = in[x] + subpixel[x % f][(x / f) * B];
                }
            }
            if (sink) deliver(part, n, y, false);
        });
        return;
    }
    if (m.kernelSource >= 0) {
        // Row by row: the logits of tap j at column x are channel (j f + y % f) f + x % f of the source
        // at (y / f, x / f); gathered into the part's scratch (or computed there from the fused head
        // convolution's input), then filtered (nn/kernel_filter_kernels.h).
        const BlockedShape& ss = m.shape(m.kernelSource);
        const float* source = m.data(m.kernelSource);
        const KernelFilterDesc& d = m.kernelFilter;
        const int64_t f = m.kernelFactor;
        const int k = d.kernel, r = k / 2, taps = int(d.weights());  // a guide's weight after the taps
        forEachOutputRow([&](int64_t part, int64_t n, int64_t y) {
            // A row passed through whole is copied by the sink from the frame, when it can: no input
            // rows, logits or filter for it.
            if (m.flatMarked && sink) {
                const uint8_t* flat = m.flatRows.data() + y * m.passGroupsPerRow;
                if (std::all_of(flat, flat + m.passGroupsPerRow,
                                [](uint8_t isFlat) { return isFlat != 0; }) &&
                    sink->passRow(n, y)) {
                    m.passCounts[size_t(part)] += m.passGroupsPerRow;
                    return;
                }
            }
            float* logits = m.kernelScratch.data() + part * taps * W;
            const float* in[kKernelMaxChannels * 7];
            float* out[kKernelMaxChannels];
            const float* guide[kKernelMaxChannels];
            KernelFilterRowArgs args;
            args.out = out, args.in = in, args.logits = logits;
            args.width = W, args.channels = int(C), args.kernel = k, args.centreBias = d.centreBias;
            // The input rows first: the pass-through test reads them before any logit is made.
            for (int64_t c = 0; c < C; ++c) {
                for (int dy = -r; dy <= r; ++dy)
                    in[c * k + dy + r] = inputRow(part, n, c, std::clamp<int64_t>(y + dy, 0, H - 1));
                out[c] = outputRow(part, n, c, y);
                if (m.kernelGuideFrom >= 0) guide[c] = inputRow(part, n, m.kernelGuideFrom + c, y);
            }
            if (m.kernelGuideFrom >= 0) args.history = guide;
            uint8_t* flat = nullptr;
            if (m.flatMarked) {  // marked before the layers ran
                flat = m.flatRows.data() + y * m.passGroupsPerRow;
                for (int64_t g = 0; g < m.passGroupsPerRow; ++g) m.passCounts[size_t(part)] += flat[g];
                args.flatGroups = flat;
            } else if (m.passSpan > 0) {
                flat = m.passGroups.data() + part * m.passGroupsPerRow;
                m.passCounts[size_t(part)] += DEJAG_SIMD_CALL(kernelFlatGroups, args, m.passSpan, flat);
                args.flatGroups = flat;
            }
            if (m.kernelFeatures >= 0) {
                const BlockedShape& fs = m.shape(m.kernelFeatures);
                KernelLogitsRowArgs head;
                head.blockStride = fs.planeStride(), head.block = fs.block;
                head.inChannels = m.kernelFeatureChannels, head.taps = taps, head.factor = int(f);
                head.width = W, head.logits = logits;
                const int64_t slot = (y % f) * taps * f;
                head.features = m.data(m.kernelFeatures) + fs.offset(n, 0, y / f, 0);
                head.weights = m.kernelHeadWeights.data() + slot * head.inChannels;
                head.bias = m.kernelHeadBias.data() + slot;
                head.flatGroups = flat;
                DEJAG_SIMD_CALL(kernelLogitsRow, head);
            } else {
                // Source pixel by source pixel: the lanes this row's taps and phases read, each an offset
                // from the pixel (a few KB of row, read once).
                int64_t lane[49][16];  // [tap][phase], factors up to 16
                for (int j = 0; j < taps; ++j)
                    for (int64_t phase = 0; phase < f; ++phase) {
                        const int64_t channel = (j * f + y % f) * f + phase;
                        lane[j][phase] = (channel / ss.block) * ss.planeStride() + channel % ss.block;
                    }
                const float* pixel = source + ss.offset(n, 0, y / f, 0);
                for (int64_t x0 = 0; x0 < W; x0 += f, pixel += ss.block) {
                    const int64_t phases = std::min<int64_t>(f, W - x0);
                    for (int j = 0; j < taps; ++j)
                        for (int64_t phase = 0; phase < phases; ++phase)
                            logits[j * W + x0 + phase] = pixel[lane[j][phase]];
                }
            }
            DEJAG_SIMD_CALL(kernelFilterRow, args);
            if (sink) deliver(part, n, y, false);
        });
        return;
    }
    const BlockedShape& os = m.steps[size_t(m.outputStep)].shape;
    if (sink &&
        sink->takesStridedRows()) {  // the rows as the arena holds them: lane c % block of block c / block
        const float* out = m.data(m.outputStep);
        forEachOutputRow([&](int64_t part, int64_t n, int64_t y) {
            const float** channels = m.rowPointers.data() + part * C;
            for (int64_t c = 0; c < C; ++c)
                channels[c] = out + os.offset(n, c / os.block, y, 0) + c % os.block;
            sink->rowStrided(n, y, channels, os.block);
        });
        return;
    }
    fromBlocked(m.output.data(), m.data(m.outputStep), os);
    if (sink) forEachOutputRow([&](int64_t part, int64_t n, int64_t y) { deliver(part, n, y, true); });
}

}  // namespace dejag::nn

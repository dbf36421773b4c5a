#include "nn/plan_passes.h"

#include <algorithm>

namespace dejag::nn::plan {

PlanGraph::PlanGraph(const Model& model, const Shape& inputShape)
    : nodes(model.graph()),
      shapes(model.nodeShapes(inputShape)),
      input(inputShape),
      output(model.outputNode()),
      params(model.parameterData()) {}

bool PlanGraph::isConvolution(int i) const {
    return i >= 0 && (opOf(i) == GraphOp::Conv2d || opOf(i) == GraphOp::ConvTranspose2d);
}

int PlanGraph::readers(int node) const {
    int count = 0;
    for (const GraphNode& n : nodes)
        for (int source : n.inputs) count += source == node;
    return count;
}

bool PlanGraph::readByConvolutionsOnly(int node, int except) const {
    for (int i = 0; i < size(); ++i)
        for (int source : nodes[size_t(i)].inputs)
            if (source == node && i != except && !isConvolution(i)) return false;
    return true;
}

std::optional<ResidualOutput> fuseResidualOutput(const PlanGraph& g) {
    const GraphNode& out = g.node(g.output);
    if (out.op != GraphOp::Add || out.inputs.size() != 2 || out.activation.kind != Activation::None)
        return std::nullopt;
    const int other = out.inputs[0] < 0 ? out.inputs[1] : out.inputs[1] < 0 ? out.inputs[0] : -1;
    if (other < 0 || g.opOf(other) != GraphOp::PixelShuffle || g.shapeOf(other) != g.input ||
        g.readers(other) != 1 || g.readers(g.output) != 0)
        return std::nullopt;
    return ResidualOutput{g.output, other, g.node(other).inputs[0], g.node(other).factor};
}

std::optional<KernelOutput> fuseKernelOutput(const PlanGraph& g) {
    const GraphNode& out = g.node(g.output);
    if (out.op != GraphOp::KernelFilter || out.inputs.size() < 2 || out.inputs[1] < 0) return std::nullopt;
    KernelOutput k;
    if (out.inputs.size() == 2) {
        if (out.inputs[0] >= 0 || g.input[1] > kKernelMaxChannels) return std::nullopt;
        k.desc = out.kernelFilterDesc(g.input);
    } else {
        // A guided kpn: the frame and the guide, channel slices of the input read by the filter alone.
        auto inputSlice = [&](int node, int64_t from, int64_t to) {
            return node >= 0 && g.opOf(node) == GraphOp::Slice && g.node(node).inputs[0] < 0 &&
                   g.node(node).sliceFrom == from && g.shapeOf(node)[1] == to - from && g.readers(node) == 1;
        };
        const int64_t C = g.shapeOf(out.inputs[0])[1];
        if (C > kKernelMaxChannels || g.input[1] != 2 * C || !inputSlice(out.inputs[0], 0, C) ||
            !inputSlice(out.inputs[2], C, 2 * C))
            return std::nullopt;
        k.frameSlice = out.inputs[0], k.guideSlice = out.inputs[2], k.guideFrom = int(C);
        k.desc = out.kernelFilterDesc(g.shapeOf(out.inputs[0]), true);
    }
    const int shuffle = out.inputs[1];
    if (g.opOf(shuffle) != GraphOp::PixelShuffle || g.node(shuffle).inputs[0] < 0 ||
        g.readers(shuffle) != 1 || g.readers(g.output) != 0)
        return std::nullopt;
    k.filter = g.output, k.shuffle = shuffle;
    k.source = g.node(shuffle).inputs[0];
    k.factor = g.node(shuffle).factor;
    return k;
}

void fuseKernelHead(const PlanGraph& g, KernelOutput& k) {
    const int head = k.source;
    if (head < 0 || g.opOf(head) != GraphOp::Conv2d || g.node(head).inputs[0] < 0 || g.readers(head) != 1)
        return;
    const GraphNode& n = g.node(head);
    const Shape& in = g.shapeOf(n.inputs[0]);
    const Conv2dDesc d = n.convDesc(in);
    const int64_t f = k.factor, taps = k.desc.weights();  // a guide's weight after the kernel's taps
    if (d.kernelHeight != 1 || d.kernelWidth != 1 || d.strideH != 1 || d.strideW != 1 || d.padTop != 0 ||
        d.padBottom != 0 || d.padLeft != 0 || d.padRight != 0 || n.activation.kind != Activation::None ||
        d.outChannels != taps * f * f || in[1] > 16)
        return;
    k.features = n.inputs[0];
    k.featureChannels = int(in[1]);
    const float* weight = g.params + n.weightOffset;  // (Cout, Cin, 1, 1)
    const float* bias = n.biasOffset >= 0 ? g.params + n.biasOffset : nullptr;
    k.headWeights.resize(size_t(f * taps * f * in[1]));
    k.headBias.resize(size_t(f * taps * f));
    // Logit channel of tap j, row phase py, column phase px: (j f + py) f + px (the shuffle's order).
    for (int64_t py = 0; py < f; ++py)
        for (int64_t j = 0; j < taps; ++j)
            for (int64_t px = 0; px < f; ++px) {
                const int64_t channel = (j * f + py) * f + px, slot = (py * taps + j) * f + px;
                k.headBias[size_t(slot)] = bias ? bias[channel] : 0.0f;
                std::copy_n(weight + channel * in[1], in[1], k.headWeights.data() + slot * in[1]);
            }
}

bool planarInput(const PlanGraph& g, const std::optional<ResidualOutput>& residual,
                 const std::optional<KernelOutput>& kernel) {
    if (g.input[1] > 16) return false;
    for (int i = 0; i < g.size(); ++i)
        for (int source : g.node(i).inputs)
            if (source < 0 && !g.isConvolution(i) && !(residual && i == residual->add) &&
                !(kernel && (i == kernel->filter || i == kernel->frameSlice || i == kernel->guideSlice)))
                return false;
    return true;
}

std::vector<ConcatInPlace> concatInPlace(const PlanGraph& g) {
    std::vector<ConcatInPlace> found;
    if (g.input[0] != 1) return found;
    std::vector<char> convTaken(size_t(g.size()), 0);
    for (int i = 0; i < g.size(); ++i) {
        const GraphNode& cat = g.node(i);
        if (cat.op != GraphOp::Concat || cat.inputs.size() != 2 || i == g.output || g.readers(i) == 0 ||
            !g.readByConvolutionsOnly(i))
            continue;
        const int a = cat.inputs[0], b = cat.inputs[1];
        if (a < 0 || b < 0) continue;
        const bool convFirst = g.opOf(a) == GraphOp::Conv2d;
        const int conv = convFirst ? a : b, shuffle = convFirst ? b : a;
        if (g.opOf(conv) != GraphOp::Conv2d || g.opOf(shuffle) != GraphOp::PixelShuffle || conv >= shuffle ||
            conv == g.output || g.readers(shuffle) != 1 || !g.readByConvolutionsOnly(conv, i) ||
            convTaken[size_t(conv)])
            continue;
        convTaken[size_t(conv)] = 1;
        const int64_t convChannels = g.shapeOf(conv)[1], shuffleChannels = g.shapeOf(shuffle)[1];
        ConcatInPlace c{i, conv, shuffle, int(convChannels), {}};
        c.lane.resize(size_t(convChannels + shuffleChannels));
        for (int64_t ch = 0; ch < int64_t(c.lane.size()); ++ch)
            c.lane[size_t(ch)] = convFirst              ? ch
                                 : ch < shuffleChannels ? convChannels + ch
                                                        : ch - shuffleChannels;
        found.push_back(std::move(c));
    }
    return found;
}

std::vector<float> permutedWeights(const PlanGraph& g, const ConcatInPlace& c, int reader) {
    const GraphNode& n = g.node(reader);
    const int64_t cin = int64_t(c.lane.size()), cout = n.outChannels, taps = int64_t(n.kernel) * n.kernel;
    const float* weight = g.params + n.weightOffset;
    const bool transposed = n.op == GraphOp::ConvTranspose2d;  // (Cin, Cout, k, k), else (Cout, Cin, k, k)
    std::vector<float> permuted(size_t(cin * cout * taps));
    for (int64_t o = 0; o < cout; ++o)
        for (int64_t ch = 0; ch < cin; ++ch) {
            const int64_t from = transposed ? ch * cout + o : o * cin + ch;
            const int64_t to = transposed ? c.lane[size_t(ch)] * cout + o : o * cin + c.lane[size_t(ch)];
            std::copy_n(weight + from * taps, taps, permuted.data() + to * taps);
        }
    return permuted;
}

std::vector<PoolFusion> fusePooling(const PlanGraph& g) {
    std::vector<PoolFusion> found;
    for (int i = 0; i < g.size(); ++i) {
        const GraphNode& pool = g.node(i);
        if (pool.op != GraphOp::MaxPool2d) continue;
        const int source = pool.inputs[0];
        const MaxPool2dDesc d = pool.poolDesc(g.shapeOf(source));
        if (d.kernel != 2 || d.stride != 2 || d.padding != 0) continue;
        if (source < 0 || source == g.output || g.opOf(source) != GraphOp::Conv2d || g.readers(source) != 1 ||
            g.shapeOf(source)[2] < 2 || g.shapeOf(source)[3] < 2)
            continue;
        found.push_back({source, i});
    }
    return found;
}

int bufferOf(const std::vector<NodePlan>& nodes, int node) {
    const NodePlan& n = nodes[size_t(node)];
    if (n.concatBuffer >= 0) return n.concatBuffer;
    if (n.pooledInto >= 0) return n.pooledInto;
    return node;
}

Precision assignPrecision(const PlanGraph& g, std::vector<NodePlan>& nodes,
                          const std::vector<NodeKernel>& kernels, const std::vector<int>& keepFloat) {
    const int count = g.size();
    std::vector<char> bf16(size_t(count), 1);
    auto keep = [&](int node) {
        if (node >= 0) bf16[size_t(bufferOf(nodes, node))] = 0;
    };
    for (int node : keepFloat) keep(node);
    for (int i = 0; i < count; ++i) {
        const NodePlan& n = nodes[size_t(i)];
        if (n.fusedIntoConv || n.concatInPlace) continue;  // written by their inputs' steps
        const bool shuffleInPlace = g.opOf(i) == GraphOp::PixelShuffle && n.concatBuffer >= 0;
        // Its output: bf16 only from a convolution that can round it, or a shuffle in place.
        if (n.fusedIntoOutput || !(kernels[size_t(i)].canWriteBf16 || shuffleInPlace)) keep(i);
        // Its inputs: bf16 only into a convolution that can read it, or a shuffle in place.
        const bool convReads = kernels[size_t(i)].canReadBf16 && !n.fusedIntoOutput;
        for (int source : g.node(i).inputs)
            if (!(convReads || shuffleInPlace)) keep(source);
    }
    Precision p;
    std::vector<int> written;  // distinct bf16 buffers
    for (int i = 0; i < count; ++i) {
        NodePlan& n = nodes[size_t(i)];
        if (n.fusedIntoConv || n.concatInPlace || n.fusedIntoOutput) continue;
        const int source = g.node(i).inputs.empty() ? -1 : g.node(i).inputs[0];
        n.inBf16 = source >= 0 && bf16[size_t(bufferOf(nodes, source))];
        n.outBf16 = bf16[size_t(bufferOf(nodes, i))];
        if (n.outBf16 && std::find(written.begin(), written.end(), bufferOf(nodes, i)) == written.end())
            written.push_back(bufferOf(nodes, i));
    }
    p.bf16Activations = int(written.size());
    p.bf16Buffer = std::move(bf16);
    return p;
}

ArenaPlan placeFirstFit(const std::vector<ArenaTensor>& tensors) {
    struct Region {
        int64_t offset, size;
        int dies;
    };
    std::vector<Region> live;
    ArenaPlan plan;
    for (const ArenaTensor& t : tensors) {
        live.erase(std::remove_if(live.begin(), live.end(), [&](const Region& r) { return r.dies < t.born; }),
                   live.end());
        std::sort(live.begin(), live.end(),
                  [](const Region& a, const Region& b) { return a.offset < b.offset; });
        const int64_t floats = (t.floats + 15) / 16 * 16;  // 64-byte aligned regions
        int64_t offset = 0;
        for (const Region& r : live) {
            if (r.offset - offset >= floats) break;
            offset = std::max(offset, r.offset + r.size);
        }
        live.push_back({offset, floats, t.dies});
        plan.offsets.push_back(offset);
        plan.floats = std::max(plan.floats, offset + floats);
        plan.unpackedFloats += floats;
    }
    return plan;
}

ArenaTensors arenaTensors(const PlanGraph& g, const std::vector<NodePlan>& nodes,
                          const std::vector<int64_t>& bufferFloats,
                          const std::vector<int>& readAfterLastStep) {
    const int count = g.size();
    std::vector<int> lastUse(size_t(count) + 1, -1);  // index 0: the model input, i + 1: node i
    for (int i = 0; i < count; ++i)
        for (int input : g.node(i).inputs)
            lastUse[size_t(input + 1)] = std::max(lastUse[size_t(input + 1)], i);
    for (int node : readAfterLastStep)
        if (node >= 0) lastUse[size_t(node + 1)] = count;
    for (int i = 0; i < count; ++i)  // what the output stage reads for the nodes fused into it (a guide's
        if (nodes[size_t(i)].fusedIntoOutput)  // slices read the input)
            for (int input : g.node(i).inputs) lastUse[size_t(input + 1)] = count;
    ArenaTensors a;
    a.tensors.push_back({bufferFloats[0], 0, lastUse[0]});
    a.buffer.push_back(-1);
    for (int i = 0; i < count; ++i) {  // a concatenation in place lives as long as its conv input's buffer
        const int cat = nodes[size_t(i)].concatBuffer;
        if (cat >= 0 && g.opOf(i) == GraphOp::Conv2d)
            lastUse[size_t(i + 1)] = std::max(lastUse[size_t(i + 1)], lastUse[size_t(cat + 1)]);
    }
    for (int i = 0; i < count; ++i) {
        const NodePlan& n = nodes[size_t(i)];
        if (n.fusedIntoConv || n.fusedIntoOutput || n.concatInPlace ||
            (n.concatBuffer >= 0 && g.opOf(i) == GraphOp::PixelShuffle))
            continue;  // placed with its convolution or its concatenation's conv input, or never stored
        const int buffer = bufferOf(nodes, i);
        // A concatenation's buffer lives as long as its conv input's; a pooling's as the pooling's.
        const int owner = n.concatBuffer >= 0 ? i : buffer;
        a.tensors.push_back({bufferFloats[size_t(buffer + 1)], i, lastUse[size_t(owner + 1)]});
        a.buffer.push_back(buffer);
    }
    return a;
}

}  // namespace dejag::nn::plan

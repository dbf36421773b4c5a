// dejag/nn: the inference plan's passes (nn/inference.h). The plan's constructor is their pipeline:
//
//   PlanGraph g(model, inputShape);
//   residual  = fuseResidualOutput(g)        add(input, pixel_shuffle(x)) computed from x by the output stage
//   kernel    = fuseKernelOutput(g)          kernel_filter(input, pixel_shuffle(x)) likewise
//               fuseKernelHead(g, kernel)    ... and x's 1x1 convolution, whose logits are never stored
//   planar    = planarInput(g, stages)       the input kept planar when only convolutions read it
//   concats   = concatInPlace(g)             concat(conv, shuffle) written in place by its inputs
//   pools     = fusePooling(g)               a 2x2 max pooling computed by its convolution
//   bf16      = assignPrecision(g, ...)      which buffers are bf16 (InferencePrecision::BFloat16)
//   offsets   = placeFirstFit(arenaTensors(...))   the arena
//
// Each pass decides from the graph alone (and, for precision, from what each convolution's kernel can
// read and write) and returns its decision; nothing here packs weights or touches memory, so each is
// tested on its own (tests/nn/plan_passes_test.cpp).
#pragma once

#include <cstdint>
#include <optional>
#include <vector>

#include "nn/layers.h"
#include "nn/model.h"

namespace dejag::nn::plan {

// The graph a plan is made from, with the questions every pass asks of it. Node -1 is the model input.
struct PlanGraph {
    PlanGraph(const Model& model, const Shape& inputShape);

    std::vector<GraphNode> nodes;
    std::vector<Shape> shapes;  // each node's output
    Shape input;
    int output = -1;
    const float* params = nullptr;

    int size() const { return int(nodes.size()); }
    const GraphNode& node(int i) const { return nodes[size_t(i)]; }
    const Shape& shapeOf(int i) const { return i < 0 ? input : shapes[size_t(i)]; }
    GraphOp opOf(int i) const { return nodes[size_t(i)].op; }
    bool isConvolution(int i) const;
    // How many inputs of the graph's nodes are `node`.
    int readers(int node) const;
    // Whether every node reading `node`, `except` aside, is a convolution.
    bool readByConvolutionsOnly(int node, int except = -1) const;
};

// What the passes decide for one node (the plan's steps carry it).
struct NodePlan {
    int pooledInto = -1;           // conv2d: the maxpool2d node whose output it writes (pooling fused)
    bool fusedIntoConv = false;    // maxpool2d: computed by its input's convolution
    bool fusedIntoOutput = false;  // computed by an output stage, never stored
    // Concatenation in place: the concat node whose buffer this conv2d or pixel_shuffle writes, the first
    // lane a shuffle writes there, and on the concat itself that its inputs compute it.
    int concatBuffer = -1;
    int laneOffset = 0;
    bool concatInPlace = false;
    bool inBf16 = false, outBf16 = false;  // reads its first input / writes its output as bf16
};

// ---- Fuse the residual output ----------------------------------------------------------------------
// The output is add(input, pixel_shuffle(x)) with nothing else reading the shuffle: the output stage
// writes input + shuffle(x) from x.
struct ResidualOutput {
    int add = -1, shuffle = -1;
    int source = -1;  // x
    int factor = 1;
};
std::optional<ResidualOutput> fuseResidualOutput(const PlanGraph& g);

// ---- Fuse the kernel output and its head -------------------------------------------------------------
// The output is kernel_filter(input, pixel_shuffle(x)) on an input of at most kKernelMaxChannels
// channels with nothing else reading the shuffle: each output row's logits are gathered from x. Or, a
// guided kpn's, kernel_filter(slice [0, C) of the input, pixel_shuffle(x), slice [C, 2C) of it) with
// nothing else reading the slices: the stage reads the guide's rows from the input's channels C...
inline constexpr int kKernelMaxChannels = 4;
struct KernelOutput {
    int filter = -1, shuffle = -1;
    int source = -1;  // x
    int factor = 1;
    KernelFilterDesc desc;
    int frameSlice = -1, guideSlice = -1;  // a guided kpn's slices (fused with the filter)
    int guideFrom = -1;                    // ... and the input channel its guide starts at
    // fuseKernelHead: x is a 1x1 convolution (no activation, taps * factor^2 outputs, at most 16
    // inputs) read by nothing else; the stage computes the logits from its input `features`. The
    // weights are ordered by row phase: [factor][taps][factor][featureChannels], the bias likewise.
    int features = -1;
    int featureChannels = 0;
    std::vector<float> headWeights, headBias;
};
std::optional<KernelOutput> fuseKernelOutput(const PlanGraph& g);
void fuseKernelHead(const PlanGraph& g, KernelOutput& kernel);

// ---- Keep the input planar ----------------------------------------------------------------------------
// True when the input has at most 16 channels and only convolutions and the fused output stages read it.
bool planarInput(const PlanGraph& g, const std::optional<ResidualOutput>& residual,
                 const std::optional<KernelOutput>& kernel);

// ---- Concatenate in place -------------------------------------------------------------------------------
// For one image: concat(conv, shuffle) or concat(shuffle, conv), read only by convolutions, where the
// conv (read by nothing else) comes before the shuffle (read by nothing else). The conv writes its
// channels at the start of the concat's buffer and the shuffle its channels from laneOffset on; `lane`
// maps each of the concat's channels to its physical lane, the order its readers' weights take
// (permutedWeights).
struct ConcatInPlace {
    int concat = -1, conv = -1, shuffle = -1;
    int laneOffset = 0;
    std::vector<int64_t> lane;
};
std::vector<ConcatInPlace> concatInPlace(const PlanGraph& g);
// The weights of `reader` (a convolution reading c.concat) with its input channels in c.lane's order.
std::vector<float> permutedWeights(const PlanGraph& g, const ConcatInPlace& c, int reader);

// ---- Fuse pooling -------------------------------------------------------------------------------------
// A 2x2 stride-2 unpadded max pooling of a conv2d (not the output, at least 2x2, read by nothing else).
struct PoolFusion {
    int conv = -1, pool = -1;
};
std::vector<PoolFusion> fusePooling(const PlanGraph& g);

// ---- Assign precision -------------------------------------------------------------------------------------
// What a node's kernel can do, for the precision pass.
struct NodeKernel {
    bool canWriteBf16 = false;  // its convolution rounds its output to bf16
    bool canReadBf16 = false;   // its convolution reads a bf16 input
};
struct Precision {
    std::vector<char> bf16Buffer;  // per node: its buffer holds bf16
    int bf16Activations = 0;       // distinct bf16 buffers
};
// A node's buffer: the concat it writes in place, the pooling it computes, or its own.
int bufferOf(const std::vector<NodePlan>& nodes, int node);
// A stored buffer is bf16 when everything writing it can round to bf16 (a convolution that can, a pixel
// shuffle into a concatenation in place) and everything reading it can take bf16; `keepFloat` (the
// output, the output stages' sources) stay float. Sets each node's inBf16/outBf16.
Precision assignPrecision(const PlanGraph& g, std::vector<NodePlan>& nodes,
                          const std::vector<NodeKernel>& kernels, const std::vector<int>& keepFloat);

// ---- Plan the arena ---------------------------------------------------------------------------------------
// A tensor to place: its size, the step that writes it (born) and the last step that reads it (dies).
struct ArenaTensor {
    int64_t floats = 0;
    int born = 0, dies = 0;
};
struct ArenaPlan {
    std::vector<int64_t> offsets;  // per tensor, in floats, 64-byte aligned
    int64_t floats = 0;            // the arena
    int64_t unpackedFloats = 0;    // every tensor a buffer of its own
};
// Placed in order, each at the lowest offset where it fits between the tensors still alive when it is
// born (a tensor dead before that step has its space reused).
ArenaPlan placeFirstFit(const std::vector<ArenaTensor>& tensors);
// The plan's tensors in the order they are placed: the input first (buffer -1), then each stored buffer
// when the step that writes it runs — a concatenation in place with its conv input, a fused pooling
// with its convolution. bufferFloats[i + 1]: the size of buffer i (-1: the input). A tensor dies after
// its last reader; those in `readAfterLastStep` (the output, the output stages' sources) live to the end.
struct ArenaTensors {
    std::vector<ArenaTensor> tensors;
    std::vector<int> buffer;  // per tensor: the node whose buffer it is, -1 the input
};
ArenaTensors arenaTensors(const PlanGraph& g, const std::vector<NodePlan>& nodes,
                          const std::vector<int64_t>& bufferFloats,
                          const std::vector<int>& readAfterLastStep);

}  // namespace dejag::nn::plan

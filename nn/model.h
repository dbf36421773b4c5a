// dejag/nn: a model is a named graph of layers described in JSON, with all parameters in one flat buffer.
//
// Architecture JSON (the node names are the weight file's keys: "conv1.weight", "conv1.bias"):
//   {"name": "seed2020", "input_channels": 1, "init": "glorot_uniform",
//    "input_colour": "luma ...", "normalisation": "[0, 1]",   (recorded in model files)
//    "nodes": [{"name": "conv1", "op": "conv2d", "inputs": ["input"], "out_channels": 32, "kernel": 5,
//               "padding": "same", "activation": "relu"}, ...],
//    "output": "up2"}
// Ops and their fields:
//   conv2d            out_channels, kernel, stride (1), padding ("same" | "valid" | n), dilation (1),
//                     bias (true), activation ("none"), init_scale (1)
//   conv_transpose2d  out_channels, kernel, stride (2), padding (0), output_padding (0), bias, activation
//   maxpool2d         kernel (2), stride (= kernel)
//   activation        activation, slope, low, high
//   add               two inputs of one shape (residual)
//   concat            inputs along channels
//   upsample          mode ("nearest" | "bilinear"), factor (2)
//   pixel_shuffle     factor (2)
//   kernel_filter     inputs [image, logits with kernel^2 channels] or [image, logits with kernel^2 + 1,
//                     history]; kernel (3), centre_bias (0): each pixel a softmax-weighted average of the
//                     image's kernel x kernel neighbourhood (and the history's own pixel)
//   slice             from (0), to (the input's channels): channels [from, to)
//   warp              inputs [image, motion (2 channels: x right, y down)]; filter ("bilinear" |
//                     "catmull-rom" | "bicubic"): the image read at each pixel minus its motion
// Nodes are listed in topological order: inputs name "input" or earlier nodes. A DAG, so skips work.
//
// forward() keeps what backward() needs; backward() zeroes the gradient buffer, then fills it.
#pragma once

#include <cstdint>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nn/layers.h"
#include "nn/tensor.h"

namespace dejag::nn {

struct ParameterInfo {
    std::string name;  // "conv1.weight"
    Shape shape;
    int64_t offset = 0;  // into the flat parameter buffer
    int64_t fanIn = 0, fanOut = 0;
    bool isBias = false;
    double initScale = 1.0;  // the node's "init_scale": initial weights times this (0.1 on a residual
                             // branch's last conv starts the network near the identity)
};

enum class GraphOp {
    Conv2d,
    ConvTranspose2d,
    MaxPool2d,
    Activation,
    Add,
    Concat,
    Upsample,
    PixelShuffle,
    KernelFilter,
    Slice,
    Warp,
    Accumulate,
    Count
};
const char* graphOpName(GraphOp op);

// One node of a model's graph, as parsed from its architecture (fields unused by an op keep defaults).
struct GraphNode {
    std::string name;
    GraphOp op = GraphOp::Conv2d;
    std::vector<int> inputs;  // indices of earlier nodes, -1 = the model input
    int inChannels = 0, outChannels = 0;
    int kernel = 3, stride = 1, dilation = 1, outputPadding = 0;  // conv2d, conv_transpose2d, maxpool2d
    bool samePadding = false;
    int padding = 0;
    bool bias = true;
    ActivationDesc activation{Activation::None};   // fused into convolutions; the op of "activation"
    bool bilinear = false;                         // upsample
    int factor = 2;                                // upsample, pixel_shuffle
    float centreBias = 0.0f;                       // kernel_filter
    int sliceFrom = 0, sliceTo = 0;                // slice: channels [from, to)
    WarpFilter warpFilter = WarpFilter::Bilinear;  // warp
    float maxCount = 32.0f;                        // accumulate
    bool clip = false;                             // accumulate: the history clamped to the neighbourhood
    int64_t weightOffset = -1, biasOffset = -1;    // into the flat parameter buffer

    // Layer descriptors for an input of shape (N, C, H, W).
    Conv2dDesc convDesc(const Shape& in) const;
    ConvTranspose2dDesc convTransposeDesc(const Shape& in) const;
    MaxPool2dDesc poolDesc(const Shape& in) const;
    ResampleDesc resampleDesc(const Shape& in) const;
    KernelFilterDesc kernelFilterDesc(const Shape& in, bool history = false) const;
    WarpDesc warpDesc(const Shape& in) const;
};

struct ModelOptions {
    int width = 16, depth = 3;  // the "fast" residual U-Net: first width (even), levels
    int channels = 3;
    int state = 1;            // temporal: channels a frame passes to the next besides its RGB
    float maxCount = 32.0f;   // accumulate: the most samples its history's mean holds
    bool depthInput = false;  // accumulate: the frame's depth and the previous frame's, warped, as inputs
    bool clip = false;        // accumulate: the history clamped to the frame's neighbourhood (AccumulateDesc)
    // kpn: a guide (another method's result on the frame, RGB) beside the frame as input channels 3..5;
    // each pixel's blend is its 3x3 kernel over the frame plus one weight on the guide's own pixel.
    bool guide = false;
};

class Model {
  public:
    // Throws dejag::Error naming the node and field at fault.
    static Model fromArchitecture(const nlohmann::json& architecture);
    // "seed2020": the reference network of docs/seed-cnn.md. "fast": the residual RGB family.
    static Model builtin(const std::string& name, const ModelOptions& options = {});
    static nlohmann::json builtinArchitecture(const std::string& name, const ModelOptions& options = {});

    Model(Model&&) noexcept;
    Model& operator=(Model&&) noexcept;
    ~Model();

    const nlohmann::json& architecture() const;
    const std::string& name() const;
    int inputChannels() const;
    int outputChannels() const;

    // The graph, in topological order, and the index of the output node.
    std::vector<GraphNode> graph() const;
    int outputNode() const;
    // Every node's output shape for an input shape (throws dejag::Error if the graph cannot take it).
    std::vector<Shape> nodeShapes(const Shape& inputShape) const;

    const std::vector<ParameterInfo>& parameters() const;
    const ParameterInfo& parameter(const std::string& name) const;
    int64_t parameterCount() const;
    float* parameterData();
    const float* parameterData() const;
    float* gradientData();
    const float* gradientData() const;

    // Convolutions run on the fast blocked kernels (default) or on the reference kernels of nn/layers.h,
    // the oracle the fast ones are tested against. Both give the same results to float rounding.
    void setFastKernels(bool fast);
    bool fastKernels() const;

    // Seeded initialisation: the architecture's "init" (glorot_uniform or he_normal) for weights, zero
    // biases.
    void initialize(uint64_t seed);

    // input (N, Cin, H, W). Throws dejag::Error on a wrong channel count, a size the graph cannot take,
    // or a NaN/Inf in the input. The returned tensor lives until the next forward().
    const Tensor& forward(const Tensor& input);
    // doutput: gradient of the loss w.r.t. the last forward's output. Fills gradientData(), and
    // inputGradient() when asked for (setInputGradient).
    void backward(const Tensor& doutput);
    // The gradient w.r.t. the last forward's input as well (off by default: a single frame's input needs
    // none; a recurrent network's input holds its previous output, through which training
    // backpropagates in time). Valid after backward() until the next forward().
    void setInputGradient(bool wanted);
    const Tensor& inputGradient() const;
    // Output shape for an input shape, without running.
    Shape outputShape(const Shape& inputShape) const;
    // Multiply-adds of one forward at this input size, total and per input pixel.
    int64_t macs(const Shape& inputShape) const;

  private:
    struct Impl;
    explicit Model(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

// Model files: safetensors with the parameters under their names and metadata
//   dejag.architecture  the architecture JSON
//   dejag.format        "dejag-model-1"
//   dejag.input_colour, dejag.normalisation   from the architecture
//   plus any caller metadata (dejag.provenance: the command and data that made it, ...).
void saveModel(const std::string& path, const Model& model,
               const std::map<std::string, std::string>& metadata = {});
// Validates the architecture, that every parameter is present with its exact shape, that nothing else is,
// and that every value is finite. Throws dejag::Error naming the file and the problem.
Model loadModel(const std::string& path, std::map<std::string, std::string>* metadata = nullptr);

// The model's forward pass in double precision on the reference kernels of nn/layers.h: the yardstick
// the float32 paths are measured against (accumulation error on large frames). input: (N, Cin, H, W).
std::vector<double> forwardInDouble(const Model& model, const std::vector<double>& input,
                                    const Shape& inputShape);

}  // namespace dejag::nn

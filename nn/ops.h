// dejag/nn: the op registry — everything the library knows of one graph op, declared once: how its node
// is read from the architecture JSON, its output shape, its multiply-adds, how it widens the receptive
// field, its reference forward (float and double) and backward, and its row in a model card. Each op is
// one file of nn/ops/ and one line of the table in nn/ops.cpp, whose order a compile-time check ties to
// GraphOp. Model (parsing, shapes, forward, backward, forwardInDouble, macs), the receptive field of
// nn/frame_network.h and the model card go through the table; the fast paths (the blocked convolutions of
// training, the inference plan of nn/inference.h) are the op's fast forward, tested against the reference.
//
// Adding an op: its file in nn/ops/ (an OpDef), a GraphOp value, its line in the table, and its cases
// in the op harness (tests/nn/ops_test.cpp).
#pragma once

#include <cstdint>
#include <functional>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "nn/model.h"

namespace dejag::nn {

// Bounds on an architecture, far above any image filter (dejag-fast: 64 channels, 3x3 kernels): a typo
// or a hostile file is one error line instead of an allocation of terabytes.
inline constexpr int kMaxChannels = 4096;
inline constexpr int kMaxKernel = 31;
inline constexpr int64_t kMaxParameters = int64_t(1) << 27;  // 512 MB of float weights

// What an op's parse sees besides its node's JSON object: the channels of each of its inputs, and the
// model's parameters, to which an op with weights appends its own.
struct OpParse {
    const nlohmann::json& json;
    std::vector<int> inputChannels;  // per input of the node
    std::vector<ParameterInfo>& parameters;
    int64_t& parameterCount;  // the flat buffer's size so far: the next parameter's offset
    // Reads "activation", "slope", "low", "high" into node.activation.
    void readActivation(GraphNode& node) const;
    // Appends a parameter of `count` values at the next offset; returns its offset.
    int64_t addParameter(ParameterInfo info, int64_t count) const;
};

// One node's forward: its inputs, weights and output (all (N, C, H, W), row-major).
template <class T>
struct OpForward {
    const GraphNode& node;
    const std::vector<Shape>& inShapes;
    const Shape& outShape;
    std::vector<const T*> inputs = {};
    const T* weight = nullptr;
    const T* bias = nullptr;
    T* output = nullptr;
    std::vector<int32_t>* indices = nullptr;  // maxpool2d's argmax, kept for the backward pass
};

// One node's backward: adds the gradients of its inputs (null: not needed) and writes its weights'.
template <class T>
struct OpBackward {
    const GraphNode& node;
    const std::vector<Shape>& inShapes;
    const Shape& outShape;
    std::vector<const T*> inputs = {};
    const T* weight = nullptr;
    const T* output = nullptr;
    const T* dOutput = nullptr;  // of a fused activation: the gradient before it
    std::vector<T*> dInputs = {};
    T* dWeight = nullptr;
    T* dBias = nullptr;
    const std::vector<int32_t>* indices = nullptr;
};

// The op's cells of a model card's architecture table (empty where it has no such field).
struct OpCard {
    std::string outChannels, kernel, stride, activation;
};

struct OpDef {
    GraphOp op;
    const char* name;                  // in the architecture JSON
    int minInputs = 1, maxInputs = 1;  // maxInputs 0: any number from minInputs
    // Its "activation" field is applied to its output after the op (convolutions); Model keeps the
    // values before it for the backward pass.
    bool fusesActivation = false;
    // Reads the op's fields (bounded) and appends its parameters; sets node.outChannels. Throws
    // dejag::Error without the node's name (the caller adds it).
    void (*parse)(GraphNode& node, const OpParse& parse) = nullptr;
    // The output shape for these input shapes; throws dejag::Error if they do not fit.
    Shape (*outputShape)(const GraphNode& node, const std::vector<Shape>& inputs) = nullptr;
    int64_t (*macs)(const GraphNode& node, const std::vector<Shape>& inputs) = nullptr;  // null: none
    // Moves (scale: input pixels per pixel of the output; radius: how far it sees, in input pixels) from
    // its first input's to its output's. Null: unchanged.
    void (*receptiveField)(const GraphNode& node, double& scale, double& radius) = nullptr;
    void (*forward)(const OpForward<float>& call) = nullptr;
    void (*forwardDouble)(const OpForward<double>& call) = nullptr;
    void (*backward)(const OpBackward<float>& call) = nullptr;
    void (*backwardDouble)(const OpBackward<double>& call) = nullptr;  // for the gradient checks
    OpCard (*card)(const GraphNode& node) = nullptr;
};

// The table, indexed by GraphOp.
const OpDef& opDef(GraphOp op);
// The op of that JSON name, or GraphOp::Count.
GraphOp opNamed(const std::string& name);

// The op definitions, one per file of nn/ops/.
OpDef conv2dOp();
OpDef convTranspose2dOp();
OpDef maxPool2dOp();
OpDef activationOp();
OpDef addOp();
OpDef concatOp();
OpDef upsampleOp();
OpDef pixelShuffleOp();
OpDef kernelFilterOp();
OpDef sliceOp();
OpDef warpOp();
OpDef accumulateOp();

}  // namespace dejag::nn

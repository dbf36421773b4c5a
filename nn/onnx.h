// dejag/nn: a model written as ONNX (opset 13), for the runtimes an engine already has.
//
// Every op of the JSON graph maps onto standard ONNX operators. The kernel filter and the accumulate
// blend, which have no operator of their own, are decomposed into Softmax, Pad (edge), Slice and
// arithmetic; the motion warp reads its taps with GatherElements, its weights being the filter's
// polynomials. So the file needs no custom domain. docs/onnx.md has the op table and the checks.
//
// The graph takes one input "input" (1, C, H, W) and gives one output "output", on the values the model
// sees in dejag (the architecture's input_colour and normalisation, recorded in the file's metadata with
// the architecture itself). H and W are symbolic ("height", "width") unless fixed.
#pragma once

#include <map>
#include <string>

#include "nn/model.h"

namespace dejag::nn {

struct OnnxOptions {
    int height = 0, width = 0;                    // 0, 0: symbolic; else fixed, and checked against the graph
    std::map<std::string, std::string> metadata;  // more metadata_props (key: value)
    std::string producerVersion;
};

// The serialised ModelProto. Throws dejag::Error naming the size the graph cannot take.
std::string exportOnnx(const Model& model, const OnnxOptions& options = {});

}  // namespace dejag::nn

// dejag/nn: a model written as ONNX (opset 13), for the runtimes an engine already has.
//
// Every single-frame op of the JSON graph maps onto standard ONNX operators; the kernel filter, which has
// no operator of its own, is decomposed into Softmax, Pad (edge), Slice, Mul and Add, so the file needs no
// custom domain. The recurrent ops (warp, accumulate) have none: a model holding one is refused with the
// node named. docs/onnx.md has the op table and the checks.
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

// The serialised ModelProto. Throws dejag::Error naming the node whose op has no ONNX form, or the size
// the graph cannot take.
std::string exportOnnx(const Model& model, const OnnxOptions& options = {});

}  // namespace dejag::nn

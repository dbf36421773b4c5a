// conv2d: out_channels, kernel, stride (1), padding ("same" | "valid" | n), dilation (1), bias (true),
// activation ("none"), init_scale (1). Fast forward: nn/fast_conv.h (training) and nn/inference.h.
#include "nn/layers.h"
#include "nn/ops/conv_common.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    conv2dForward(c.output, c.inputs[0], c.weight, c.bias, c.node.convDesc(c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    conv2dBackward(c.dInputs[0], c.dWeight, c.dBias, c.dOutput, c.inputs[0], c.weight,
                   c.node.convDesc(c.inShapes[0]));
}

}  // namespace

OpDef conv2dOp() {
    OpDef op{GraphOp::Conv2d, "conv2d"};
    op.fusesActivation = true;
    op.parse = [](GraphNode& n, const OpParse& p) { parseConvolution(n, p, false); };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        const Conv2dDesc d = n.convDesc(ins[0]);
        d.validate();
        return {ins[0][0], n.outChannels, d.outHeight(), d.outWidth()};
    };
    op.macs = [](const GraphNode& n, const std::vector<Shape>& ins) { return n.convDesc(ins[0]).macs(); };
    op.receptiveField = [](const GraphNode& n, double& scale, double& radius) {
        radius +=
            ((n.kernel - 1) * n.dilation / 2.0 + (n.stride - 1) + (n.samePadding ? 0 : n.padding)) * scale;
        scale *= n.stride;
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = convolutionCard;
    return op;
}

}  // namespace dejag::nn

// conv_transpose2d: out_channels, kernel, stride (2), padding (0), output_padding (0), bias, activation.
// Fast forward: nn/fast_conv.h (training) and nn/inference.h.
#include "nn/layers.h"
#include "nn/ops/conv_common.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    convTranspose2dForward(c.output, c.inputs[0], c.weight, c.bias, c.node.convTransposeDesc(c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    convTranspose2dBackward(c.dInputs[0], c.dWeight, c.dBias, c.dOutput, c.inputs[0], c.weight,
                            c.node.convTransposeDesc(c.inShapes[0]));
}

}  // namespace

OpDef convTranspose2dOp() {
    OpDef op{GraphOp::ConvTranspose2d, "conv_transpose2d"};
    op.fusesActivation = true;
    op.parse = [](GraphNode& n, const OpParse& p) { parseConvolution(n, p, true); };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        const ConvTranspose2dDesc d = n.convTransposeDesc(ins[0]);
        d.validate();
        return {ins[0][0], n.outChannels, d.outHeight(), d.outWidth()};
    };
    op.macs = [](const GraphNode& n, const std::vector<Shape>& ins) {
        return n.convTransposeDesc(ins[0]).macs();
    };
    op.receptiveField = [](const GraphNode& n, double& scale, double& radius) {
        radius += ((n.kernel - 1) / 2.0 + 1) * scale;
        scale /= n.stride;
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = convolutionCard;
    return op;
}

}  // namespace dejag::nn

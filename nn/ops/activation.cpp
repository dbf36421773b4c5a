// activation: activation, slope, low, high (nn/layers.h's ActivationDesc) on its input.
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    activationForward(c.output, c.inputs[0], shapeNumel(c.outShape), c.node.activation);
}

template <class T>
void backward(const OpBackward<T>& c) {
    if (c.dInputs[0])
        activationBackward(c.dInputs[0], c.dOutput, c.inputs[0], c.output, shapeNumel(c.outShape),
                           c.node.activation);
}

}  // namespace

OpDef activationOp() {
    OpDef op{GraphOp::Activation, "activation"};
    op.parse = [](GraphNode& n, const OpParse& p) {
        p.readActivation(n);
        n.outChannels = n.inChannels;
    };
    op.outputShape = [](const GraphNode&, const std::vector<Shape>& ins) { return ins[0]; };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode& n) -> OpCard { return {"", "", "", activationName(n.activation.kind)}; };
    return op;
}

}  // namespace dejag::nn

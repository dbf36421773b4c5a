// add: two inputs of one shape (a residual connection).
#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    addForward(c.output, c.inputs[0], c.inputs[1], shapeNumel(c.outShape));
}

template <class T>
void backward(const OpBackward<T>& c) {
    addBackward(c.dInputs[0], c.dInputs[1], c.dOutput, shapeNumel(c.outShape));
}

}  // namespace

OpDef addOp() {
    OpDef op{GraphOp::Add, "add"};
    op.minInputs = op.maxInputs = 2;
    op.parse = [](GraphNode& n, const OpParse& p) {
        if (p.inputChannels[1] != n.inChannels)
            throw Error("adds " + std::to_string(n.inChannels) + " and " +
                        std::to_string(p.inputChannels[1]) + " channels");
        n.outChannels = n.inChannels;
    };
    op.outputShape = [](const GraphNode&, const std::vector<Shape>& ins) -> Shape {
        if (ins[1] != ins[0])
            throw Error("adds " + shapeToString(ins[0]) + " and " + shapeToString(ins[1]) +
                        " (shapes differ)");
        return ins[0];
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode&) { return OpCard{}; };
    return op;
}

}  // namespace dejag::nn

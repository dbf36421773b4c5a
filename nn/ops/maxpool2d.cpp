// maxpool2d: kernel (2), stride (= kernel). Keeps the argmax of each output for the backward pass.
#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    std::vector<int32_t> local;
    std::vector<int32_t>& argmax = c.indices ? *c.indices : local;
    argmax.resize(size_t(shapeNumel(c.outShape)));
    maxPool2dForward(c.output, argmax.data(), c.inputs[0], c.node.poolDesc(c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    if (c.dInputs[0])
        maxPool2dBackward(c.dInputs[0], c.dOutput, c.indices->data(), c.node.poolDesc(c.inShapes[0]));
}

}  // namespace

OpDef maxPool2dOp() {
    OpDef op{GraphOp::MaxPool2d, "maxpool2d"};
    op.parse = [](GraphNode& n, const OpParse& p) {
        n.kernel = p.json.value("kernel", 2);
        n.stride = p.json.value("stride", n.kernel);
        n.outChannels = n.inChannels;
    };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        const MaxPool2dDesc d = n.poolDesc(ins[0]);
        d.validate();
        return {ins[0][0], ins[0][1], d.outHeight(), d.outWidth()};
    };
    op.receptiveField = [](const GraphNode& n, double& scale, double& radius) {
        radius += (n.kernel - 1) * scale;
        scale *= n.stride;
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode& n) -> OpCard {
        return {"", std::to_string(n.kernel) + "x" + std::to_string(n.kernel), std::to_string(n.stride), ""};
    };
    return op;
}

}  // namespace dejag::nn

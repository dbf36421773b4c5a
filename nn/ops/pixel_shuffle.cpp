// pixel_shuffle: factor (2): (N, C·f², H, W) to (N, C, H·f, W·f).
#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    pixelShuffleForward(c.output, c.inputs[0], c.node.resampleDesc(c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    if (c.dInputs[0]) pixelShuffleBackward(c.dInputs[0], c.dOutput, c.node.resampleDesc(c.inShapes[0]));
}

}  // namespace

OpDef pixelShuffleOp() {
    OpDef op{GraphOp::PixelShuffle, "pixel_shuffle"};
    op.parse = [](GraphNode& n, const OpParse& p) {
        n.factor = p.json.value("factor", 2);
        if (n.factor < 1 || n.factor > 16) throw Error("factor must be 1..16");
        if (n.inChannels % (n.factor * n.factor))
            throw Error(std::to_string(n.inChannels) + " channels are not a multiple of factor^2");
        n.outChannels = n.inChannels / (n.factor * n.factor);
    };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        return {ins[0][0], ins[0][1] / (n.factor * n.factor), ins[0][2] * n.factor, ins[0][3] * n.factor};
    };
    op.receptiveField = [](const GraphNode& n, double& scale, double& radius) {
        radius += scale;
        scale /= n.factor;
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode&) { return OpCard{}; };
    return op;
}

}  // namespace dejag::nn

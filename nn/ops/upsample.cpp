// upsample: mode ("nearest" | "bilinear"), factor (2).
#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    if (c.node.bilinear)
        upsampleBilinearForward(c.output, c.inputs[0], c.node.resampleDesc(c.inShapes[0]));
    else
        upsampleNearestForward(c.output, c.inputs[0], c.node.resampleDesc(c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    if (!c.dInputs[0]) return;
    if (c.node.bilinear)
        upsampleBilinearBackward(c.dInputs[0], c.dOutput, c.node.resampleDesc(c.inShapes[0]));
    else
        upsampleNearestBackward(c.dInputs[0], c.dOutput, c.node.resampleDesc(c.inShapes[0]));
}

}  // namespace

OpDef upsampleOp() {
    OpDef op{GraphOp::Upsample, "upsample"};
    op.parse = [](GraphNode& n, const OpParse& p) {
        const std::string mode = p.json.value("mode", "nearest");
        if (mode != "nearest" && mode != "bilinear") throw Error("upsample mode '" + mode + "'");
        n.bilinear = mode == "bilinear";
        n.factor = p.json.value("factor", 2);
        if (n.factor < 1 || n.factor > 16) throw Error("factor must be 1..16");
        n.outChannels = n.inChannels;
    };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        return {ins[0][0], ins[0][1], ins[0][2] * n.factor, ins[0][3] * n.factor};
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

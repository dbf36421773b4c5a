// warp: inputs [image, motion with 2 channels]; filter ("bilinear" | "catmull-rom" | "bicubic"): the image
// read at each pixel minus its motion (nn/layers.h), a recurrent network's history brought to where each
// pixel was.
#include <limits>

#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    warpForward(c.output, c.inputs[0], c.inputs[1], c.node.warpDesc(c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    warpBackward(c.dInputs[0], c.dInputs[1], c.dOutput, c.inputs[0], c.inputs[1],
                 c.node.warpDesc(c.inShapes[0]));
}

}  // namespace

OpDef warpOp() {
    OpDef op{GraphOp::Warp, "warp"};
    op.minInputs = op.maxInputs = 2;
    op.parse = [](GraphNode& n, const OpParse& p) {
        n.warpFilter = parseWarpFilter(p.json.value("filter", std::string("bilinear")));
        if (p.inputChannels[1] != 2)
            throw Error("the motion has " + std::to_string(p.inputChannels[1]) + " channels, not 2 (x, y)");
        n.outChannels = n.inChannels;
    };
    op.outputShape = [](const GraphNode&, const std::vector<Shape>& ins) -> Shape {
        const Shape want{ins[0][0], 2, ins[0][2], ins[0][3]};
        if (ins[1] != want)
            throw Error("warps " + shapeToString(ins[0]) + " by motion " + shapeToString(ins[1]) +
                        " (wanted " + shapeToString(want) + ")");
        return ins[0];
    };
    op.macs = [](const GraphNode& n, const std::vector<Shape>& ins) {
        const int64_t taps = n.warpFilter == WarpFilter::Bilinear ? 2 : 4;
        return shapeNumel(ins[0]) * taps * (taps + 1);
    };
    // It reads wherever the motion points: no radius bounds what it sees.
    op.receptiveField = [](const GraphNode&, double&, double& radius) {
        radius = std::numeric_limits<double>::infinity();
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode& n) -> OpCard {
        return {"", "", "", std::string("by motion, ") + warpFilterName(n.warpFilter)};
    };
    return op;
}

}  // namespace dejag::nn

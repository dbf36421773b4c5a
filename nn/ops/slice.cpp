// slice: channels [from, to) of its input ("from" 0, "to" the input's channels): a recurrent network takes
// its frame, its history and the motion in one input and splits them.
#include <algorithm>

#include "base/error.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    const int64_t plane = c.inShapes[0][2] * c.inShapes[0][3], in = c.inShapes[0][1], out = c.outShape[1];
    for (int64_t n = 0; n < c.outShape[0]; ++n) {
        const T* src = c.inputs[0] + (n * in + c.node.sliceFrom) * plane;
        std::copy(src, src + out * plane, c.output + n * out * plane);
    }
}

template <class T>
void backward(const OpBackward<T>& c) {
    if (!c.dInputs[0]) return;
    const int64_t plane = c.inShapes[0][2] * c.inShapes[0][3], in = c.inShapes[0][1], out = c.outShape[1];
    for (int64_t n = 0; n < c.outShape[0]; ++n) {
        T* d = c.dInputs[0] + (n * in + c.node.sliceFrom) * plane;
        const T* g = c.dOutput + n * out * plane;
        for (int64_t i = 0; i < out * plane; ++i) d[i] += g[i];
    }
}

}  // namespace

OpDef sliceOp() {
    OpDef op{GraphOp::Slice, "slice"};
    op.parse = [](GraphNode& n, const OpParse& p) {
        const int channels = p.inputChannels[0];
        n.sliceFrom = p.json.value("from", 0);
        n.sliceTo = p.json.value("to", channels);
        if (n.sliceFrom < 0 || n.sliceTo > channels || n.sliceFrom >= n.sliceTo)
            throw Error("takes channels [" + std::to_string(n.sliceFrom) + ", " + std::to_string(n.sliceTo) +
                        ") of an input of " + std::to_string(channels) +
                        " (wanted 0 <= from < to <= " + std::to_string(channels) + ")");
        n.outChannels = n.sliceTo - n.sliceFrom;
    };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        if (ins[0][1] < n.sliceTo)
            throw Error("takes channels up to " + std::to_string(n.sliceTo) + " of " + shapeToString(ins[0]));
        return {ins[0][0], n.sliceTo - n.sliceFrom, ins[0][2], ins[0][3]};
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode& n) -> OpCard {
        return {std::to_string(n.sliceTo - n.sliceFrom), "", "",
                "channels " + std::to_string(n.sliceFrom) + ".." + std::to_string(n.sliceTo - 1)};
    };
    return op;
}

}  // namespace dejag::nn

// concat: two or more inputs along the channels. The inference plan concatenates in place.
#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    std::vector<int64_t> channels;
    for (const Shape& s : c.inShapes) channels.push_back(s[1]);
    concatForward(c.output, c.inputs, channels, c.outShape[0], c.outShape[2] * c.outShape[3]);
}

template <class T>
void backward(const OpBackward<T>& c) {
    std::vector<int64_t> channels;
    for (const Shape& s : c.inShapes) channels.push_back(s[1]);
    concatBackward(c.dInputs, c.dOutput, channels, c.outShape[0], c.outShape[2] * c.outShape[3]);
}

}  // namespace

OpDef concatOp() {
    OpDef op{GraphOp::Concat, "concat"};
    op.minInputs = 2, op.maxInputs = 0;
    op.parse = [](GraphNode& n, const OpParse& p) {
        n.outChannels = 0;
        for (int c : p.inputChannels) n.outChannels += c;
    };
    op.outputShape = [](const GraphNode&, const std::vector<Shape>& ins) -> Shape {
        Shape out = ins[0];
        out[1] = 0;
        for (const Shape& s : ins) {
            if (s[0] != ins[0][0] || s[2] != ins[0][2] || s[3] != ins[0][3])
                throw Error("concatenates " + shapeToString(ins[0]) + " and " + shapeToString(s));
            out[1] += s[1];
        }
        return out;
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode&) { return OpCard{}; };
    return op;
}

}  // namespace dejag::nn

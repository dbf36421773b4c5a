// kernel_filter: inputs [image, logits with kernel² channels]; kernel (3), centre_bias (0): each pixel a
// softmax-weighted average of the image's kernel x kernel neighbourhood.
#include <cmath>

#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    kernelFilterForward(c.output, c.inputs[0], c.inputs[1], c.node.kernelFilterDesc(c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    kernelFilterBackward(c.dInputs[0], c.dInputs[1], c.dOutput, c.inputs[0], c.inputs[1],
                         c.node.kernelFilterDesc(c.inShapes[0]));
}

}  // namespace

OpDef kernelFilterOp() {
    OpDef op{GraphOp::KernelFilter, "kernel_filter"};
    op.minInputs = op.maxInputs = 2;
    op.parse = [](GraphNode& n, const OpParse& p) {
        n.kernel = p.json.value("kernel", 3);
        n.centreBias = p.json.value("centre_bias", 0.0f);
        if (n.kernel < 1 || n.kernel > 7 || n.kernel % 2 == 0) throw Error("kernel must be odd and 1..7");
        if (!std::isfinite(n.centreBias)) throw Error("centre_bias must be finite");
        if (p.inputChannels[1] != n.kernel * n.kernel)
            throw Error("the logits have " + std::to_string(p.inputChannels[1]) +
                        " channels, not kernel^2 = " + std::to_string(n.kernel * n.kernel));
        n.outChannels = n.inChannels;
    };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        const Shape want{ins[0][0], int64_t(n.kernel) * n.kernel, ins[0][2], ins[0][3]};
        if (ins[1] != want)
            throw Error("filters " + shapeToString(ins[0]) + " with logits " + shapeToString(ins[1]) +
                        " (wanted " + shapeToString(want) + ")");
        return ins[0];
    };
    op.macs = [](const GraphNode& n, const std::vector<Shape>& ins) {
        return shapeNumel(ins[0]) * n.kernel * n.kernel;
    };
    op.receptiveField = [](const GraphNode& n, double& scale, double& radius) {
        radius += (n.kernel / 2) * scale;
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode& n) -> OpCard {
        return {"", std::to_string(n.kernel) + "x" + std::to_string(n.kernel), "", "softmax weights"};
    };
    return op;
}

}  // namespace dejag::nn

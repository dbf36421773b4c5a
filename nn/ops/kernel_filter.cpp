// kernel_filter: inputs [image, logits with kernel² channels] or [image, logits with kernel² + 1 channels,
// history]; kernel (3), centre_bias (0): each pixel a softmax-weighted average of the image's kernel x kernel
// neighbourhood (and of the history's own pixel).
#include <cmath>

#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

template <class T>
void forward(const OpForward<T>& c) {
    const bool history = c.inputs.size() > 2;
    kernelFilterForward(c.output, c.inputs[0], c.inputs[1], c.node.kernelFilterDesc(c.inShapes[0], history),
                        history ? c.inputs[2] : nullptr);
}

template <class T>
void backward(const OpBackward<T>& c) {
    const bool history = c.inputs.size() > 2;
    kernelFilterBackward(c.dInputs[0], c.dInputs[1], c.dOutput, c.inputs[0], c.inputs[1],
                         c.node.kernelFilterDesc(c.inShapes[0], history), history ? c.dInputs[2] : nullptr,
                         history ? c.inputs[2] : nullptr);
}

}  // namespace

OpDef kernelFilterOp() {
    OpDef op{GraphOp::KernelFilter, "kernel_filter"};
    op.minInputs = 2, op.maxInputs = 3;
    op.parse = [](GraphNode& n, const OpParse& p) {
        n.kernel = p.json.value("kernel", 3);
        n.centreBias = p.json.value("centre_bias", 0.0f);
        if (n.kernel < 1 || n.kernel > 7 || n.kernel % 2 == 0) throw Error("kernel must be odd and 1..7");
        if (!std::isfinite(n.centreBias)) throw Error("centre_bias must be finite");
        const bool history = p.inputChannels.size() > 2;
        const int weights = n.kernel * n.kernel + (history ? 1 : 0);
        if (p.inputChannels[1] != weights)
            throw Error("the logits have " + std::to_string(p.inputChannels[1]) + " channels, not " +
                        (history ? "kernel^2 + 1 = " : "kernel^2 = ") + std::to_string(weights));
        if (history && p.inputChannels[2] != p.inputChannels[0])
            throw Error("the history has " + std::to_string(p.inputChannels[2]) + " channels, the image " +
                        std::to_string(p.inputChannels[0]));
        n.outChannels = n.inChannels;
    };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        const Shape want{ins[0][0], int64_t(n.kernel) * n.kernel + (ins.size() > 2 ? 1 : 0), ins[0][2],
                         ins[0][3]};
        if (ins[1] != want)
            throw Error("filters " + shapeToString(ins[0]) + " with logits " + shapeToString(ins[1]) +
                        " (wanted " + shapeToString(want) + ")");
        if (ins.size() > 2 && ins[2] != ins[0])
            throw Error("filters " + shapeToString(ins[0]) + " with a history " + shapeToString(ins[2]));
        return ins[0];
    };
    op.macs = [](const GraphNode& n, const std::vector<Shape>& ins) {
        return shapeNumel(ins[0]) * (n.kernel * n.kernel + (ins.size() > 2 ? 1 : 0));
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

// accumulate: inputs [image (C), logits with kernel^2 + 1 channels, history (C + 1: colour and confidence)];
// kernel (3), max_count (32), clip (false): a TAA's blend of the frame's filtered neighbourhood with the
// history's running mean of samples (nn/layers.h); the output is the colour shown, the colour kept and the
// next confidence (2 C + 1).
#include <cmath>

#include "base/error.h"
#include "nn/layers.h"
#include "nn/ops.h"

namespace dejag::nn {
namespace {

AccumulateDesc desc(const GraphNode& n, const Shape& image) {
    AccumulateDesc d;
    d.batch = image[0], d.channels = image[1], d.height = image[2], d.width = image[3];
    d.kernel = n.kernel, d.maxCount = n.maxCount, d.clip = n.clip;
    return d;
}

template <class T>
void forward(const OpForward<T>& c) {
    accumulateForward(c.output, c.inputs[0], c.inputs[1], c.inputs[2], desc(c.node, c.inShapes[0]));
}

template <class T>
void backward(const OpBackward<T>& c) {
    accumulateBackward(c.dInputs[0], c.dInputs[1], c.dInputs[2], c.dOutput, c.inputs[0], c.inputs[1],
                       c.inputs[2], desc(c.node, c.inShapes[0]));
}

}  // namespace

OpDef accumulateOp() {
    OpDef op{GraphOp::Accumulate, "accumulate"};
    op.minInputs = op.maxInputs = 3;
    op.parse = [](GraphNode& n, const OpParse& p) {
        n.kernel = p.json.value("kernel", 3);
        n.maxCount = p.json.value("max_count", 32.0f);
        n.clip = p.json.value("clip", false);
        if (n.kernel < 1 || n.kernel > 7 || n.kernel % 2 == 0) throw Error("kernel must be odd and 1..7");
        if (!std::isfinite(n.maxCount) || n.maxCount < 1.0f || n.maxCount > 1.0e6f)
            throw Error("max_count must be from 1 to 1e6");
        if (p.inputChannels[0] > 64) throw Error("the image has more than 64 channels");
        if (p.inputChannels[1] != n.kernel * n.kernel + 1)
            throw Error("the logits have " + std::to_string(p.inputChannels[1]) +
                        " channels, not kernel^2 + 1 = " + std::to_string(n.kernel * n.kernel + 1));
        if (p.inputChannels[2] != p.inputChannels[0] + 1)
            throw Error("the history has " + std::to_string(p.inputChannels[2]) +
                        " channels, not the image's and a confidence (" +
                        std::to_string(p.inputChannels[0] + 1) + ")");
        n.outChannels = 2 * n.inChannels + 1;
    };
    op.outputShape = [](const GraphNode& n, const std::vector<Shape>& ins) -> Shape {
        const Shape logits{ins[0][0], int64_t(n.kernel) * n.kernel + 1, ins[0][2], ins[0][3]};
        const Shape history{ins[0][0], ins[0][1] + 1, ins[0][2], ins[0][3]};
        if (ins[1] != logits || ins[2] != history)
            throw Error("blends " + shapeToString(ins[0]) + " with logits " + shapeToString(ins[1]) +
                        " and a history " + shapeToString(ins[2]) + " (wanted " + shapeToString(logits) +
                        " and " + shapeToString(history) + ")");
        return {ins[0][0], 2 * ins[0][1] + 1, ins[0][2], ins[0][3]};
    };
    op.macs = [](const GraphNode& n, const std::vector<Shape>& ins) {
        return shapeNumel(ins[0]) * (n.kernel * n.kernel + 1);
    };
    op.receptiveField = [](const GraphNode& n, double& scale, double& radius) {
        radius += (n.kernel / 2) * scale;
    };
    op.forward = forward<float>;
    op.forwardDouble = forward<double>;
    op.backward = backward<float>;
    op.backwardDouble = backward<double>;
    op.card = [](const GraphNode& n) -> OpCard {
        return {"", std::to_string(n.kernel) + "x" + std::to_string(n.kernel), "",
                "running mean, up to " + std::to_string(int(n.maxCount)) + " samples" +
                    (n.clip ? ", history clamped to the neighbourhood" : "")};
    };
    return op;
}

}  // namespace dejag::nn

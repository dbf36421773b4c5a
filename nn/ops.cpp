#include "nn/ops.h"

#include <array>
#include <stdexcept>

#include "base/error.h"

namespace dejag::nn {
namespace {

// The order of the table, checked at compile time against GraphOp: an op added to the enum without its
// line here (or in another place) does not compile.
constexpr std::array kOrder = {
    GraphOp::Conv2d,       GraphOp::ConvTranspose2d, GraphOp::MaxPool2d, GraphOp::Activation,
    GraphOp::Add,          GraphOp::Concat,          GraphOp::Upsample,  GraphOp::PixelShuffle,
    GraphOp::KernelFilter, GraphOp::Slice,           GraphOp::Warp,      GraphOp::Accumulate};
static_assert(kOrder.size() == size_t(GraphOp::Count), "every GraphOp needs its line in the op table");
constexpr bool inEnumOrder() {
    for (size_t i = 0; i < kOrder.size(); ++i)
        if (kOrder[i] != GraphOp(i)) return false;
    return true;
}
static_assert(inEnumOrder(), "the op table lists the ops in GraphOp's order");

std::vector<OpDef> makeTable() {
    std::vector<OpDef> table = {conv2dOp(),       convTranspose2dOp(), maxPool2dOp(), activationOp(),
                                addOp(),          concatOp(),          upsampleOp(),  pixelShuffleOp(),
                                kernelFilterOp(), sliceOp(),           warpOp(),      accumulateOp()};
    for (size_t i = 0; i < table.size(); ++i) {
        const OpDef& d = table[i];
        if (d.op != kOrder[i] || !d.name || !d.parse || !d.outputShape || !d.forward || !d.forwardDouble ||
            !d.backward || !d.backwardDouble || !d.card)
            throw std::logic_error(std::string("op table: entry ") + std::to_string(i) +
                                   " is out of order or lacks a function");
    }
    return table;
}

}  // namespace

const OpDef& opDef(GraphOp op) {
    static const std::vector<OpDef> table = makeTable();
    if (op >= GraphOp::Count) throw std::logic_error("opDef: not an op");
    return table[size_t(op)];
}

GraphOp opNamed(const std::string& name) {
    for (int i = 0; i < int(GraphOp::Count); ++i)
        if (name == opDef(GraphOp(i)).name) return GraphOp(i);
    return GraphOp::Count;
}

void OpParse::readActivation(GraphNode& n) const {
    n.activation.kind = parseActivation(json.value("activation", "none"));
    n.activation.slope = json.value("slope", 0.01f);
    n.activation.low = json.value("low", 0.0f);
    n.activation.high = json.value("high", 1.0f);
}

int64_t OpParse::addParameter(ParameterInfo info, int64_t count) const {
    info.offset = parameterCount;
    parameters.push_back(std::move(info));
    parameterCount += count;
    return parameters.back().offset;
}

}  // namespace dejag::nn

#include "nn/ops/conv_common.h"

#include <cmath>

#include "base/error.h"

namespace dejag::nn {

void parseConvolution(GraphNode& n, const OpParse& p, bool transposed) {
    const nlohmann::json& j = p.json;
    n.outChannels = j.at("out_channels").get<int>();
    n.kernel = j.at("kernel").get<int>();
    n.stride = j.value("stride", transposed ? 2 : 1);
    n.dilation = j.value("dilation", 1);
    n.bias = j.value("bias", true);
    if (j.contains("padding") && j["padding"].is_string()) {
        const std::string mode = j["padding"];
        if (mode == "same" && !transposed)
            n.samePadding = true;
        else if (mode != "valid")
            throw Error("padding '" + mode + "'");
    } else {
        n.padding = j.value("padding", 0);
    }
    n.outputPadding = j.value("output_padding", 0);
    p.readActivation(n);
    if (n.outChannels < 1 || n.kernel < 1 || n.stride < 1 || n.dilation < 1 || n.padding < 0)
        throw Error("out_channels, kernel, stride and dilation must be >= 1");
    const auto atMost = [&](const char* field, int value, int limit) {
        if (value > limit)
            throw Error(std::string(field) + " " + std::to_string(value) + " is above " +
                        std::to_string(limit));
    };
    atMost("out_channels", n.outChannels, kMaxChannels);
    atMost("kernel", n.kernel, kMaxKernel);
    atMost("stride", n.stride, kMaxKernel);
    atMost("dilation", n.dilation, kMaxKernel);
    atMost("padding", n.padding, kMaxKernel * kMaxKernel);
    if (n.outputPadding < 0 || (n.outputPadding > 0 && n.outputPadding >= n.stride))
        throw Error("output_padding must be >= 0 and below the stride");
    ParameterInfo w;
    w.name = n.name + ".weight";
    w.shape = transposed ? Shape{n.inChannels, n.outChannels, n.kernel, n.kernel}
                         : Shape{n.outChannels, n.inChannels, n.kernel, n.kernel};
    w.fanIn = int64_t(n.inChannels) * n.kernel * n.kernel;
    w.fanOut = int64_t(n.outChannels) * n.kernel * n.kernel;
    w.initScale = j.value("init_scale", 1.0);
    if (!(w.initScale >= 0) || !std::isfinite(w.initScale)) throw Error("init_scale must be finite and >= 0");
    n.weightOffset = p.addParameter(w, int64_t(n.inChannels) * n.outChannels * n.kernel * n.kernel);
    if (n.bias) {
        ParameterInfo b;
        b.name = n.name + ".bias";
        b.shape = {n.outChannels};
        b.isBias = true;
        n.biasOffset = p.addParameter(b, n.outChannels);
    }
}

OpCard convolutionCard(const GraphNode& n) {
    return {std::to_string(n.outChannels), std::to_string(n.kernel) + "x" + std::to_string(n.kernel),
            std::to_string(n.stride), activationName(n.activation.kind)};
}

}  // namespace dejag::nn

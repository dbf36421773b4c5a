// A graph holding every single-frame op, for the exporters' tests (ONNX, GLSL).
#pragma once

#include <nlohmann/json.hpp>
#include <string>

namespace dejag::nn {

// Every op with an ONNX and a GLSL form: strides, both paddings, a transposed conv, every activation (fused
// and as a node), pooling, both upsamplings, pixel shuffle, a slice, a skip, and the kernel filter with two
// and three inputs.
inline nlohmann::json everyExportableOp() {
    using nlohmann::json;
    json nodes = json::array();
    const auto conv = [&](const std::string& name, const std::string& input, int out, int kernel, int stride,
                          const std::string& activation) {
        nodes.push_back({{"name", name},
                         {"op", "conv2d"},
                         {"inputs", {input}},
                         {"out_channels", out},
                         {"kernel", kernel},
                         {"stride", stride},
                         {"padding", "same"},
                         {"activation", activation}});
    };
    conv("a", "input", 8, 3, 1, "leaky_relu");
    conv("down", "a", 12, 3, 2, "relu");
    nodes.push_back({{"name", "pool"}, {"op", "maxpool2d"}, {"inputs", {"a"}}, {"kernel", 2}});
    nodes.push_back({{"name", "cat"}, {"op", "concat"}, {"inputs", {"down", "pool"}}});
    nodes.push_back({{"name", "v"},
                     {"op", "conv2d"},
                     {"inputs", {"cat"}},
                     {"out_channels", 12},
                     {"kernel", 5},
                     {"padding", 2},
                     {"dilation", 1},
                     {"activation", "clamp"},
                     {"low", -0.2},
                     {"high", 0.8}});
    nodes.push_back({{"name", "up"},
                     {"op", "conv_transpose2d"},
                     {"inputs", {"v"}},
                     {"out_channels", 8},
                     {"kernel", 3},
                     {"stride", 2},
                     {"padding", 1},
                     {"output_padding", 1},
                     {"activation", "sigmoid"}});
    nodes.push_back({{"name", "skip"}, {"op", "add"}, {"inputs", {"up", "a"}}});
    nodes.push_back({{"name", "near"}, {"op", "upsample"}, {"inputs", {"v"}}, {"mode", "nearest"}});
    nodes.push_back({{"name", "bil"}, {"op", "upsample"}, {"inputs", {"v"}}, {"mode", "bilinear"}});
    conv("sub", "v", 8, 1, 1, "none");
    nodes.push_back({{"name", "shuf"}, {"op", "pixel_shuffle"}, {"inputs", {"sub"}}});
    nodes.push_back({{"name", "part"}, {"op", "slice"}, {"inputs", {"bil"}}, {"from", 2}, {"to", 5}});
    nodes.push_back({{"name", "clamped"},
                     {"op", "activation"},
                     {"inputs", {"near"}},
                     {"activation", "clamp"},
                     {"low", 0.1},
                     {"high", 0.5}});
    nodes.push_back({{"name", "all"}, {"op", "concat"}, {"inputs", {"skip", "clamped", "part", "shuf"}}});
    conv("taps", "all", 9, 3, 1, "none");
    nodes.push_back({{"name", "rgb"}, {"op", "slice"}, {"inputs", {"input"}}, {"from", 0}, {"to", 3}});
    nodes.push_back(
        {{"name", "kf"}, {"op", "kernel_filter"}, {"inputs", {"rgb", "taps"}}, {"centre_bias", 1.5}});
    conv("taps2", "all", 10, 1, 1, "none");
    nodes.push_back(
        {{"name", "out"}, {"op", "kernel_filter"}, {"inputs", {"kf", "taps2", "rgb"}}, {"centre_bias", 2.0}});
    return {{"name", "every_exportable_op"}, {"input_channels", 4}, {"nodes", nodes}, {"output", "out"}};
}

}  // namespace dejag::nn

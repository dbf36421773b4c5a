// ONNX export: see nn/onnx.h. The protobuf wire format is written directly (varints, tags and nested
// messages); the field numbers are those of onnx.proto, named below where they are used.
#include "nn/onnx.h"

#include <cstdint>
#include <cstring>
#include <string>
#include <vector>

#include "base/error.h"

namespace dejag::nn {
namespace {

// ---- Protobuf wire format
// ----------------------------------------------------------------------------------

class Message {
  public:
    void varint(int field, uint64_t value) {
        key(field, 0);
        raw(value);
    }
    void sint(int field, int64_t value) {
        varint(field, uint64_t(value));
    }  // int64 / int32: two's complement
    void fixed32(int field, float value) {
        key(field, 5);
        uint32_t bits;
        std::memcpy(&bits, &value, 4);
        for (int i = 0; i < 4; ++i) bytes_.push_back(char((bits >> (8 * i)) & 0xff));
    }
    void bytes(int field, const std::string& value) {
        key(field, 2);
        raw(value.size());
        bytes_ += value;
    }
    void message(int field, const Message& m) { bytes(field, m.bytes_); }
    const std::string& data() const { return bytes_; }

  private:
    void key(int field, int wire) { raw(uint64_t(field) << 3 | uint64_t(wire)); }
    void raw(uint64_t v) {
        while (v >= 0x80) {
            bytes_.push_back(char((v & 0x7f) | 0x80));
            v >>= 7;
        }
        bytes_.push_back(char(v));
    }
    std::string bytes_;
};

// onnx.proto: TensorProto.DataType
constexpr int kFloat = 1, kInt64 = 7;
// AttributeProto.AttributeType
constexpr int kAttrFloat = 1, kAttrInt = 2, kAttrString = 3, kAttrInts = 7;

// TensorProto: dims 1, data_type 2, name 8, raw_data 9 (little-endian, as this machine stores them).
Message tensor(const std::string& name, const std::vector<int64_t>& dims, const float* values, size_t count) {
    Message t;
    for (int64_t d : dims) t.sint(1, d);
    t.varint(2, kFloat);
    t.bytes(8, name);
    t.bytes(9, std::string(reinterpret_cast<const char*>(values), count * sizeof(float)));
    return t;
}
Message tensor(const std::string& name, const std::vector<int64_t>& values) {
    Message t;
    t.sint(1, int64_t(values.size()));
    t.varint(2, kInt64);
    t.bytes(8, name);
    t.bytes(9, std::string(reinterpret_cast<const char*>(values.data()), values.size() * sizeof(int64_t)));
    return t;
}

// AttributeProto: name 1, f 2, i 3, s 4, ints 8, type 20.
Message attribute(const std::string& name, int64_t value) {
    Message a;
    a.bytes(1, name);
    a.sint(3, value);
    a.varint(20, kAttrInt);
    return a;
}
Message attribute(const std::string& name, float value) {
    Message a;
    a.bytes(1, name);
    a.fixed32(2, value);
    a.varint(20, kAttrFloat);
    return a;
}
Message attribute(const std::string& name, const std::string& value) {
    Message a;
    a.bytes(1, name);
    a.bytes(4, value);
    a.varint(20, kAttrString);
    return a;
}
Message attribute(const std::string& name, const std::vector<int64_t>& values) {
    Message a;
    a.bytes(1, name);
    for (int64_t v : values) a.sint(8, v);
    a.varint(20, kAttrInts);
    return a;
}

// ValueInfoProto (name 1, type 2) of a float tensor (TypeProto.tensor_type 1: elem_type 1, shape 2;
// TensorShapeProto.dim 1: dim_value 1 or dim_param 2).
Message valueInfo(const std::string& name, const std::vector<std::string>& dims) {
    Message shape;
    for (const std::string& d : dims) {
        Message dim;
        if (!d.empty() && std::isdigit(static_cast<unsigned char>(d[0])))
            dim.sint(1, std::stoll(d));
        else
            dim.bytes(2, d);
        shape.message(1, dim);
    }
    Message tensorType;
    tensorType.varint(1, kFloat);
    tensorType.message(2, shape);
    Message type;
    type.message(1, tensorType);
    Message info;
    info.bytes(1, name);
    info.message(2, type);
    return info;
}

// ---- The graph --------------------------------------------------------------------------------------------

class GraphWriter {
  public:
    // NodeProto: input 1, output 2, name 3, op_type 4, attribute 5.
    std::string node(const std::string& op, const std::vector<std::string>& inputs, const std::string& output,
                     const std::vector<Message>& attributes = {}) {
        Message n;
        for (const std::string& i : inputs) n.bytes(1, i);
        n.bytes(2, output);
        n.bytes(3, output);
        n.bytes(4, op);
        for (const Message& a : attributes) n.message(5, a);
        graph_.message(1, n);
        return output;
    }
    // GraphProto: initializer 5.
    std::string constant(const std::string& name, const std::vector<int64_t>& values) {
        graph_.message(5, tensor(name, values));
        return name;
    }
    std::string constant(const std::string& name, const std::vector<int64_t>& dims, const float* values,
                         size_t count) {
        graph_.message(5, tensor(name, dims, values, count));
        return name;
    }
    std::string scalar(const std::string& name, float value) {
        graph_.message(5, tensor(name, {}, &value, 1));
        return name;
    }
    Message& graph() { return graph_; }

  private:
    Message graph_;
};

std::string activationNode(GraphWriter& g, const ActivationDesc& a, const std::string& in,
                           const std::string& out) {
    switch (a.kind) {
        case Activation::None:
            return in;
        case Activation::ReLU:
            return g.node("Relu", {in}, out);
        case Activation::LeakyReLU:
            return g.node("LeakyRelu", {in}, out, {attribute("alpha", a.slope)});
        case Activation::Sigmoid:
            return g.node("Sigmoid", {in}, out);
        case Activation::Clamp: {
            // low + relu(x - low) - relu(x - high): Clip with its bounds as inputs (opset 11 on) is not
            // read by every runtime (OpenCV 4.6 takes the attribute form only).
            const std::string low = g.scalar(out + ".low", a.low), high = g.scalar(out + ".high", a.high);
            const std::string above =
                g.node("Relu", {g.node("Sub", {in, low}, out + ".minus_low")}, out + ".above_low");
            const std::string over =
                g.node("Relu", {g.node("Sub", {in, high}, out + ".minus_high")}, out + ".above_high");
            return g.node("Add", {g.node("Sub", {above, over}, out + ".inside"), low}, out);
        }
    }
    throw Error("ONNX export: an activation without an ONNX form");
}

// A Slice of `axes` [start, end) (ends may be negative: from the end; INT64_MAX: to the end).
std::string slice(GraphWriter& g, const std::string& in, const std::string& out, std::vector<int64_t> starts,
                  std::vector<int64_t> ends, std::vector<int64_t> axes) {
    return g.node("Slice",
                  {in, g.constant(out + ".starts", starts), g.constant(out + ".ends", ends),
                   g.constant(out + ".axes", axes)},
                  out);
}

}  // namespace

std::string exportOnnx(const Model& model, const OnnxOptions& options) {
    static_assert(int(GraphOp::Count) == 12, "a new graph op needs its ONNX form here");
    const std::vector<GraphNode> nodes = model.graph();
    const bool fixed = options.height > 0 && options.width > 0;
    std::vector<Shape> shapes;
    // Every node's shape at the fixed size, or at a probe size for the channel counts alone.
    const Shape inputShape{1, model.inputChannels(), fixed ? options.height : 256,
                           fixed ? options.width : 256};
    try {
        shapes = model.nodeShapes(inputShape);
    } catch (const Error& e) {
        throw Error("model '" + model.name() + "' cannot take a " + std::to_string(inputShape[3]) + "x" +
                    std::to_string(inputShape[2]) + " input (" + e.what() + ")");
    }
    const std::vector<ParameterInfo>& parameters = model.parameters();
    const float* params = model.parameterData();

    GraphWriter g;
    const auto parameter = [&](int64_t offset) -> const ParameterInfo& {
        for (const ParameterInfo& p : parameters)
            if (p.offset == offset) return p;
        throw Error("ONNX export: no parameter at offset " + std::to_string(offset));
    };
    const auto initializer = [&](int64_t offset) {
        const ParameterInfo& p = parameter(offset);
        std::vector<int64_t> dims(p.shape.begin(), p.shape.end());
        size_t count = 1;
        for (int64_t d : dims) count *= size_t(d);
        return g.constant(p.name, dims, params + p.offset, count);
    };

    std::vector<std::string> names(nodes.size());
    const auto inputName = [&](int index) { return index < 0 ? std::string("input") : names[size_t(index)]; };
    for (size_t i = 0; i < nodes.size(); ++i) {
        const GraphNode& n = nodes[i];
        const std::string name = n.name;
        const std::string in = n.inputs.empty() ? std::string() : inputName(n.inputs[0]);
        switch (n.op) {
            case GraphOp::Conv2d:
            case GraphOp::ConvTranspose2d: {
                std::vector<std::string> inputs = {in, initializer(n.weightOffset)};
                if (n.bias && n.biasOffset >= 0) inputs.push_back(initializer(n.biasOffset));
                std::vector<Message> attributes = {
                    attribute("kernel_shape", std::vector<int64_t>{n.kernel, n.kernel}),
                    attribute("strides", std::vector<int64_t>{n.stride, n.stride}),
                    attribute("dilations", std::vector<int64_t>{n.dilation, n.dilation})};
                const bool conv = n.op == GraphOp::Conv2d;
                if (conv && n.samePadding && n.stride > 1 && !fixed) {
                    // Where "same" depends on the size (stride 2: 0 before and 1 after on an even side),
                    // ONNX's SAME_UPPER splits the padding as dejag does: the odd one at the end.
                    attributes.push_back(attribute("auto_pad", std::string("SAME_UPPER")));
                } else {
                    int top = n.padding, bottom = n.padding, left = n.padding, right = n.padding;
                    if (conv && n.samePadding) {
                        // From the size when fixed; size-free for stride 1 ((k - 1) d split, the odd one
                        // after).
                        const Shape inShape =
                            !fixed            ? Shape{1, 1, 64, 64}
                            : n.inputs[0] < 0 ? Shape{1, model.inputChannels(), options.height, options.width}
                                              : shapes[size_t(n.inputs[0])];
                        const Conv2dDesc d = n.convDesc(inShape);
                        top = d.padTop, bottom = d.padBottom, left = d.padLeft, right = d.padRight;
                    }
                    attributes.push_back(attribute("pads", std::vector<int64_t>{top, left, bottom, right}));
                }
                if (!conv) {
                    attributes.push_back(
                        attribute("output_padding", std::vector<int64_t>{n.outputPadding, n.outputPadding}));
                }
                const bool activated = n.activation.kind != Activation::None;
                const std::string convOut = activated ? name + ".linear" : name;
                g.node(conv ? "Conv" : "ConvTranspose", inputs, convOut, attributes);
                names[i] = activationNode(g, n.activation, convOut, name);
                break;
            }
            case GraphOp::MaxPool2d:
                names[i] = g.node("MaxPool", {in}, name,
                                  {attribute("kernel_shape", std::vector<int64_t>{n.kernel, n.kernel}),
                                   attribute("strides", std::vector<int64_t>{n.stride, n.stride})});
                break;
            case GraphOp::Activation:
                names[i] = activationNode(g, n.activation, in, name);
                break;
            case GraphOp::Add:
                names[i] = g.node("Add", {in, inputName(n.inputs[1])}, name);
                break;
            case GraphOp::Concat: {
                std::vector<std::string> inputs;
                for (int index : n.inputs) inputs.push_back(inputName(index));
                names[i] = g.node("Concat", inputs, name, {attribute("axis", int64_t(1))});
                break;
            }
            case GraphOp::Upsample: {
                const std::vector<float> scales = {1.0f, 1.0f, float(n.factor), float(n.factor)};
                std::vector<Message> attributes;
                if (n.bilinear) {
                    attributes = {attribute("mode", std::string("linear")),
                                  attribute("coordinate_transformation_mode", std::string("half_pixel"))};
                } else {
                    attributes = {attribute("mode", std::string("nearest")),
                                  attribute("coordinate_transformation_mode", std::string("asymmetric")),
                                  attribute("nearest_mode", std::string("floor"))};
                }
                names[i] = g.node("Resize",
                                  {in, g.constant(name + ".roi", {0}, nullptr, 0),
                                   g.constant(name + ".scales", {4}, scales.data(), 4)},
                                  name, attributes);
                break;
            }
            case GraphOp::PixelShuffle:
                // dejag's (and PyTorch's) channel order c f^2 + i f + j is DepthToSpace's CRD.
                names[i] = g.node(
                    "DepthToSpace", {in}, name,
                    {attribute("blocksize", int64_t(n.factor)), attribute("mode", std::string("CRD"))});
                break;
            case GraphOp::Slice:
                names[i] = slice(g, in, name, {n.sliceFrom}, {n.sliceTo}, {1});
                break;
            case GraphOp::KernelFilter: {
                // out = sum_j w_j tap_j (+ w_k2 third input), w = softmax over channels of the logits with
                // centreBias added to the centre's; taps are the input's edge-padded shifts.
                const int k = n.kernel, r = k / 2, taps = k * k;
                const bool third = n.inputs.size() > 2;
                const int weights = taps + (third ? 1 : 0);
                std::string logits = inputName(n.inputs[1]);
                if (n.centreBias != 0.0f) {
                    std::vector<float> bias(size_t(weights), 0.0f);
                    bias[size_t(taps / 2)] = n.centreBias;
                    logits = g.node("Add",
                                    {logits, g.constant(name + ".centre_bias", {1, weights, 1, 1},
                                                        bias.data(), bias.size())},
                                    name + ".logits");
                }
                const std::string w =
                    g.node("Softmax", {logits}, name + ".weights", {attribute("axis", int64_t(1))});
                const std::string padded =
                    r > 0 ? g.node("Pad", {in, g.constant(name + ".pads", {0, 0, r, r, 0, 0, r, r})},
                                   name + ".padded", {attribute("mode", std::string("edge"))})
                          : in;
                std::string sum;
                for (int j = 0; j < weights; ++j) {
                    const std::string tag = name + ".tap" + std::to_string(j);
                    std::string source;
                    if (j < taps) {
                        const int dy = j / k - r, dx = j % k - r;
                        // Rows [dy + r, dy + r + H) of the padded image: the end counted from its end.
                        const int64_t endY = dy - r == 0 ? INT64_MAX : dy - r,
                                      endX = dx - r == 0 ? INT64_MAX : dx - r;
                        source =
                            r > 0 ? slice(g, padded, tag, {dy + r, dx + r}, {endY, endX}, {2, 3}) : padded;
                    } else {
                        source = inputName(n.inputs[2]);
                    }
                    const std::string wj = slice(g, w, tag + ".w", {j}, {j + 1}, {1});
                    const std::string term = g.node("Mul", {source, wj}, tag + ".weighted");
                    sum = sum.empty() ? term
                                      : g.node("Add", {sum, term}, j + 1 == weights ? name : tag + ".sum");
                }
                names[i] = sum;
                break;
            }
            case GraphOp::Warp:
            case GraphOp::Accumulate:
            case GraphOp::Count:
                throw Error("model '" + model.name() + "': node '" + name + "' (" + graphOpName(n.op) +
                            ") has no ONNX form; ONNX export takes single-frame models");
        }
    }
    // The output under its own name.
    const std::string result = names[size_t(model.outputNode())];
    g.node("Identity", {result}, "output");

    Message& graph = g.graph();
    graph.bytes(2, model.name());  // GraphProto.name
    const std::string height = fixed ? std::to_string(options.height) : "height",
                      width = fixed ? std::to_string(options.width) : "width";
    graph.message(11, valueInfo("input", {"1", std::to_string(model.inputChannels()), height, width}));
    graph.message(12, valueInfo("output", {"1", std::to_string(model.outputChannels()), height, width}));

    // ModelProto: ir_version 1, producer_name 2, producer_version 3, graph 7, opset_import 8,
    // metadata_props 14 (StringStringEntryProto: key 1, value 2).
    Message onnx;
    onnx.varint(1, 8);
    onnx.bytes(2, "dejag");
    onnx.bytes(3, options.producerVersion);
    onnx.message(7, graph);
    Message opset;
    opset.bytes(1, "");
    opset.sint(2, 13);
    onnx.message(8, opset);
    std::map<std::string, std::string> metadata = options.metadata;
    metadata["dejag.architecture"] = model.architecture().dump();
    for (const char* key : {"input_colour", "normalisation"})
        if (model.architecture().contains(key) && model.architecture()[key].is_string())
            metadata[std::string("dejag.") + key] = model.architecture()[key].get<std::string>();
    for (const auto& [key, value] : metadata) {
        Message entry;
        entry.bytes(1, key);
        entry.bytes(2, value);
        onnx.message(14, entry);
    }
    return onnx.data();
}

}  // namespace dejag::nn

// ONNX export: see nn/onnx.h. The protobuf wire format is written directly (varints, tags and nested
// messages); the field numbers are those of onnx.proto, named below where they are used.
#include "nn/onnx.h"

#include <cmath>
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
    void append(const Message& m) { bytes_ += m.bytes_; }  // m's fields after these
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
Message tensor(const std::string& name, const std::vector<int64_t>& values, bool scalar = false) {
    Message t;
    if (!scalar) t.sint(1, int64_t(values.size()));
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
        nodes_.message(1, n);
        return output;
    }
    // GraphProto: initializer 5.
    std::string constant(const std::string& name, const std::vector<int64_t>& values) {
        initializers_.message(5, tensor(name, values));
        return name;
    }
    std::string constant(const std::string& name, const std::vector<int64_t>& dims, const float* values,
                         size_t count) {
        initializers_.message(5, tensor(name, dims, values, count));
        return name;
    }
    std::string scalar(const std::string& name, float value) {
        initializers_.message(5, tensor(name, {}, &value, 1));
        return name;
    }
    std::string scalarInt(const std::string& name, int64_t value) {
        initializers_.message(5, tensor(name, {value}, true));
        return name;
    }
    // GraphProto with its fields in field-number order (as protobuf's own serialisers write them, so
    // that the bytes are those of onnx.load(...).graph.SerializeToString()): node 1, name 2,
    // initializer 5, input 11, output 12.
    Message graph(const std::string& name, const Message& input, const Message& output) const {
        Message g;
        g.append(nodes_);
        g.bytes(2, name);
        g.append(initializers_);
        g.message(11, input);
        g.message(12, output);
        return g;
    }

  private:
    Message nodes_, initializers_;
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

// The k x k taps of `in` around each pixel, edge pixels repeated (Pad edge, then one Slice per tap), in
// the order dejag's kernel ops weigh them: row by row, dy and dx from -k/2 to k/2.
std::vector<std::string> edgeTaps(GraphWriter& g, const std::string& in, const std::string& name, int k) {
    const int r = k / 2;
    if (r == 0) return {in};
    const std::string padded = g.node("Pad", {in, g.constant(name + ".pads", {0, 0, r, r, 0, 0, r, r})},
                                      name + ".padded", {attribute("mode", std::string("edge"))});
    std::vector<std::string> taps;
    for (int j = 0; j < k * k; ++j) {
        const int dy = j / k - r, dx = j % k - r;
        // Rows [dy + r, dy + r + H) of the padded image: the end counted from its end.
        const int64_t endY = dy - r == 0 ? INT64_MAX : dy - r, endX = dx - r == 0 ? INT64_MAX : dx - r;
        taps.push_back(
            slice(g, padded, name + ".tap" + std::to_string(j), {dy + r, dx + r}, {endY, endX}, {2, 3}));
    }
    return taps;
}

// Elementwise arithmetic with constants, in forms every runtime reads: OpenCV 4.6 broadcasts a scalar in
// Add, Sub, Div and Pow, and in Mul only as the second operand, but not in Min, Max or Where; so
// constants are multiplied from the right, bounds are written with Relu and a piecewise curve with a mask
// (Greater, then Cast to float).
class Arithmetic {
  public:
    Arithmetic(GraphWriter& g, std::string prefix) : g_(g), prefix_(std::move(prefix)) {}
    std::string add(const std::string& a, const std::string& b) { return op("Add", a, b); }
    std::string sub(const std::string& a, const std::string& b) { return op("Sub", a, b); }
    std::string mul(const std::string& a, const std::string& b) { return op("Mul", a, b); }
    std::string div(const std::string& a, const std::string& b) { return op("Div", a, b); }
    // a^e of a >= 0, then a Relu (which changes nothing there): OpenCV 4.6 folds a Mul, Add or Sub by a
    // constant that follows a Pow into the power layer's scale and shift, which it applies before the
    // power.
    std::string pow(const std::string& a, float e) { return relu(op("Pow", a, constant(e))); }
    std::string relu(const std::string& a) { return g_.node("Relu", {a}, next()); }
    std::string constant(float v) { return g_.scalar(next(), v); }
    // min(a, high) = a - relu(a - high); max(a, low) = low + relu(a - low); clamp: both.
    std::string atMost(const std::string& a, float high) { return sub(a, relu(sub(a, constant(high)))); }
    std::string atLeast(const std::string& a, float low) {
        const std::string l = constant(low);
        return add(l, relu(sub(a, l)));
    }
    std::string clamp(const std::string& a, float low, float high) {
        const std::string l = constant(low);
        return sub(add(l, relu(sub(a, l))), relu(sub(a, constant(high))));
    }
    // below(a) where a <= threshold, else above(a): below + [a > threshold] (above - below).
    std::string piecewise(const std::string& a, float threshold, const std::string& below,
                          const std::string& above) {
        const std::string mask = g_.node("Cast", {g_.node("Greater", {a, constant(threshold)}, next())},
                                         next(), {attribute("to", int64_t(kFloat))});
        return add(below, mul(mask, sub(above, below)));
    }
    // The sRGB curves of nn/layers.h, on values clamped to [0, 1].
    std::string srgbDecode(const std::string& v) {
        const std::string x = clamp(v, 0.0f, 1.0f);
        return piecewise(x, 0.04045f, div(x, constant(12.92f)),
                         pow(div(add(x, constant(0.055f)), constant(1.055f)), 2.4f));
    }
    std::string srgbEncode(const std::string& v) {
        const std::string x = clamp(v, 0.0f, 1.0f);
        return piecewise(x, 0.0031308f, mul(x, constant(12.92f)),
                         sub(mul(pow(x, 1.0f / 2.4f), constant(1.055f)), constant(0.055f)));
    }
    // A name for the result of the next node, or the given one.
    std::string next() { return prefix_ + "." + std::to_string(count_++); }

  private:
    std::string op(const char* type, const std::string& a, const std::string& b) {
        return g_.node(type, {a, b}, next());
    }
    GraphWriter& g_;
    std::string prefix_;
    int count_ = 0;
};

// warp: image (1, C, H, W) read at (x - motion_x, y - motion_y) with the separable filter of nn/layers.h,
// each tap's index clamped to the image. The taps are read by GatherElements on the flattened planes (ONNX
// has no resampler with Catmull-Rom's kernel, and GridSample needs opset 16); their weights are the cubic
// convolution kernel's polynomials of the fraction; the size comes from the input's shape, so a symbolic
// size works.
std::string warpNode(GraphWriter& g, const std::string& image, const std::string& motion, WarpFilter filter,
                     const std::string& name) {
    Arithmetic a(g, name);
    const std::string shape = g.node("Shape", {image}, name + ".shape");
    const auto dimension = [&](int axis, const char* tag) {
        const std::string n = g.node("Gather", {shape, g.scalarInt(name + "." + tag + "_axis", axis)},
                                     name + "." + tag, {attribute("axis", int64_t(0))});
        const std::string f =
            g.node("Cast", {n}, name + "." + tag + "_float", {attribute("to", int64_t(kFloat))});
        return std::pair{n, f};
    };
    const auto [height, heightF] = dimension(2, "height");
    const auto [width, widthF] = dimension(3, "width");
    // Pixel indices along x as (1, 1, 1, W) and along y as (1, 1, H, 1).
    const auto indices = [&](const std::string& size, const char* tag, std::vector<int64_t> dims) {
        const std::string range = g.node(
            "Range",
            {g.scalarInt(name + "." + tag + "_start", 0), size, g.scalarInt(name + "." + tag + "_step", 1)},
            name + "." + tag + "_range");
        const std::string f =
            g.node("Cast", {range}, name + "." + tag + "_range_float", {attribute("to", int64_t(kFloat))});
        return g.node("Reshape", {f, g.constant(name + "." + tag + "_dims", dims)}, name + "." + tag + "_at");
    };
    const std::string xs = indices(width, "x", {1, 1, 1, -1}), ys = indices(height, "y", {1, 1, -1, 1});
    // Where each pixel reads (1, 1, H, W): NaN reads 0, a huge motion the border (as clampPlace does).
    const auto place = [&](const std::string& at, const std::string& size, int channel, const char* tag) {
        const std::string m = slice(g, motion, name + "." + tag + "_motion", {channel}, {channel + 1}, {1});
        std::string s = a.sub(at, m);
        const std::string zero = g.scalar(name + "." + tag + "_zero", 0.0f);
        s = g.node("Where", {g.node("IsNaN", {s}, name + "." + tag + "_nan"), zero, s},
                   name + "." + tag + "_s");
        const std::string limit = a.add(size, a.constant(2.0f));
        const std::string twice = a.mul(limit, a.constant(2.0f));
        const std::string low = g.node("Neg", {limit}, name + "." + tag + "_low");
        return g.node("Max", {g.node("Min", {s, twice}, a.next()), low}, a.next());
    };
    const std::string sx = place(xs, widthF, 0, "x"), sy = place(ys, heightF, 1, "y");
    // Each axis' taps: the first index and the weights, as nn/warp.cpp computes them.
    struct Axis {
        std::vector<std::string> index, weight;
    };
    const auto axisTaps = [&](const std::string& s, const std::string& sizeF, const char* tag) {
        Axis t;
        const std::string base = g.node("Floor", {s}, name + "." + tag + "_floor");
        const std::string f = a.sub(s, base);
        const std::string one = a.constant(1.0f);
        int first = 0;
        if (filter == WarpFilter::Bilinear) {
            t.weight = {a.sub(one, f), f};
        } else {
            const float k = filter == WarpFilter::CatmullRom ? -0.5f : -0.75f;
            first = -1;
            // near(t) = ((k + 2) t - (k + 3)) t t + 1; far(t) = ((k t - 5 k) t + 8 k) t - 4 k
            const auto nearW = [&](const std::string& x) {
                const std::string p = a.sub(a.mul(x, a.constant(k + 2)), a.constant(k + 3));
                return a.add(a.mul(a.mul(p, x), x), a.constant(1.0f));
            };
            const auto farW = [&](const std::string& x) {
                const std::string p = a.sub(a.mul(x, a.constant(k)), a.constant(5 * k));
                return a.sub(a.mul(a.add(a.mul(p, x), a.constant(8 * k)), x), a.constant(4 * k));
            };
            t.weight = {farW(a.add(one, f)), nearW(f), nearW(a.sub(one, f)),
                        farW(a.sub(a.constant(2.0f), f))};
        }
        const std::string last = a.sub(sizeF, one), zero = a.constant(0.0f);
        for (size_t i = 0; i < t.weight.size(); ++i) {
            const std::string at = a.add(base, a.constant(float(first + int(i))));
            const std::string inside = g.node("Max", {g.node("Min", {at, last}, a.next()), zero}, a.next());
            t.index.push_back(g.node("Cast", {inside}, a.next(), {attribute("to", int64_t(kInt64))}));
        }
        return t;
    };
    const Axis tx = axisTaps(sx, widthF, "x"), ty = axisTaps(sy, heightF, "y");
    // The planes flattened to (1, C, H W); each tap's flat index (y W + x) expanded over the channels.
    const std::string flatDims = g.constant(name + ".flat_dims", {0, 0, -1});
    const std::string flat = g.node("Reshape", {image, flatDims}, name + ".flat");
    const std::string flatShape = g.node("Shape", {flat}, name + ".flat_shape");
    std::string sum;
    for (size_t j = 0; j < ty.index.size(); ++j) {
        const std::string rowStart = g.node("Mul", {ty.index[j], width}, a.next());
        std::string row;
        for (size_t i = 0; i < tx.index.size(); ++i) {
            const std::string at = g.node("Add", {rowStart, tx.index[i]}, a.next());
            const std::string index =
                g.node("Expand", {g.node("Reshape", {at, flatDims}, a.next()), flatShape}, a.next());
            const std::string read = g.node(
                "Reshape",
                {g.node("GatherElements", {flat, index}, a.next(), {attribute("axis", int64_t(2))}), shape},
                a.next());
            const std::string term = a.mul(tx.weight[i], read);
            row = row.empty() ? term : a.add(row, term);
        }
        const std::string term = a.mul(ty.weight[j], row);
        sum = sum.empty() ? term : a.add(sum, term);
    }
    return g.node("Identity", {sum}, name);
}

// accumulate (nn/layers.h): image (1, C, H, W), logits (1, k^2 + 1, H, W), history (1, C + 1, H, W) to
// (1, 2 C + 1, H, W): the frame shown, the kept mean and the next confidence.
std::string accumulateNode(GraphWriter& g, const std::string& image, const std::string& logits,
                           const std::string& history, int channels, int k, float maxCount, bool clip,
                           const std::string& name) {
    Arithmetic a(g, name);
    const int taps = k * k;
    const std::string w = g.node("Softmax", {slice(g, logits, name + ".kernel_logits", {0}, {taps}, {1})},
                                 name + ".weights", {attribute("axis", int64_t(1))});
    const std::string trust = slice(g, logits, name + ".trust", {taps}, {taps + 1}, {1});
    const std::vector<std::string> read = edgeTaps(g, image, name, k);
    std::string spatial;
    for (int j = 0; j < taps; ++j) {
        const std::string term =
            a.mul(slice(g, w, name + ".w" + std::to_string(j), {j}, {j + 1}, {1}), read[size_t(j)]);
        spatial = spatial.empty() ? term : a.add(spatial, term);
    }
    std::string h = slice(g, history, name + ".history_colour", {0}, {channels}, {1});
    if (clip) {
        // Clamped to [D(min), D(max)] of the taps' samples (pairwise Min and Max of equal shapes).
        std::string low = read[0], high = read[0];
        for (int j = 1; j < taps; ++j) {
            low = g.node("Min", {low, read[size_t(j)]}, a.next());
            high = g.node("Max", {high, read[size_t(j)]}, a.next());
        }
        const std::string lo = a.srgbDecode(low), hi = a.srgbDecode(high);
        h = a.sub(a.add(lo, a.relu(a.sub(h, lo))), a.relu(a.sub(h, hi)));
    }
    const float maxConfidence = maxCount / (maxCount + 1.0f);
    const std::string s = a.clamp(slice(g, history, name + ".confidence", {channels}, {channels + 1}, {1}),
                                  0.0f, maxConfidence);
    const std::string one = a.constant(1.0f);
    const std::string n = a.div(s, a.sub(one, s));
    const std::string rho = a.atMost(a.mul(g.node("Sigmoid", {trust}, a.next()), a.constant(2.0f)), 1.0f);
    const std::string m = a.mul(rho, n);
    const std::string weight = a.div(m, a.add(one, m));
    const std::string filtered = a.srgbDecode(spatial), own = a.srgbDecode(image);
    const std::string shown = a.srgbEncode(a.add(filtered, a.mul(weight, a.sub(h, filtered))));
    const std::string kept = a.add(own, a.mul(weight, a.sub(h, own)));
    const std::string count = a.atMost(a.add(one, m), maxCount);
    const std::string next = a.div(count, a.add(count, one));
    return g.node("Concat", {shown, kept, next}, name, {attribute("axis", int64_t(1))});
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
        // The graph's output is "output" (an Identity below); a node of that name is renamed.
        const std::string name = n.name == "output" ? "output.node" : n.name;
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
                const int k = n.kernel, taps = k * k;
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
                const std::vector<std::string> read = edgeTaps(g, in, name, k);
                std::string sum;
                for (int j = 0; j < weights; ++j) {
                    const std::string tag = name + ".tap" + std::to_string(j);
                    const std::string source = j < taps ? read[size_t(j)] : inputName(n.inputs[2]);
                    const std::string wj = slice(g, w, tag + ".w", {j}, {j + 1}, {1});
                    const std::string term = g.node("Mul", {source, wj}, tag + ".weighted");
                    sum = sum.empty() ? term
                                      : g.node("Add", {sum, term}, j + 1 == weights ? name : tag + ".sum");
                }
                names[i] = sum;
                break;
            }
            case GraphOp::Warp:
                names[i] = warpNode(g, in, inputName(n.inputs[1]), n.warpFilter, name);
                break;
            case GraphOp::Accumulate: {
                const Shape& image = n.inputs[0] < 0 ? inputShape : shapes[size_t(n.inputs[0])];
                names[i] = accumulateNode(g, in, inputName(n.inputs[1]), inputName(n.inputs[2]),
                                          int(image[1]), n.kernel, n.maxCount, n.clip, name);
                break;
            }
            case GraphOp::Count:
                throw Error("model '" + model.name() + "': node '" + name + "' has no ONNX form");
        }
    }
    // The output under its own name.
    const std::string result = names[size_t(model.outputNode())];
    g.node("Identity", {result}, "output");

    const std::string height = fixed ? std::to_string(options.height) : "height",
                      width = fixed ? std::to_string(options.width) : "width";
    const Message graph =
        g.graph(model.name(), valueInfo("input", {"1", std::to_string(model.inputChannels()), height, width}),
                valueInfo("output", {"1", std::to_string(model.outputChannels()), height, width}));

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

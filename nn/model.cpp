#include "nn/model.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>

#include "base/error.h"
#include "nn/fast_conv.h"
#include "nn/init.h"
#include "nn/safetensors.h"

namespace dejag::nn {
namespace {

// Bounds on an architecture, far above any image filter (dejag-fast: 64 channels, 3x3 kernels): a typo
// or a hostile file is one error line instead of an allocation of terabytes.
constexpr int kMaxChannels = 4096;
constexpr int kMaxKernel = 31;
constexpr int64_t kMaxParameters = int64_t(1) << 27;  // 512 MB of float weights

using Op = GraphOp;

// A graph node plus what forward() keeps for backward().
struct Node : GraphNode {
    Tensor preActivation, output, gradient, preActivationGradient;  // (N, C, H, W) each
    std::vector<int32_t> argmax;                                    // maxpool2d
    // Fast kernels (conv2d, conv_transpose2d): the convolution packed for this forward and its input in
    // the blocked layout, kept for the weight gradient.
    std::optional<BlockedConv> fastConv;
    Tensor blockedInput, blockedOutput, blockedGradient, blockedInputGradient, inputGradient;
    BlockedShape blockedInputShape;
};

void ensureBlocked(Tensor& t, const BlockedShape& shape) {
    if (t.numel() != shape.floatCount()) t = allocateBlocked(shape);
}

Op parseOp(const std::string& name, const std::string& node) {
    for (int i = 0; i < int(Op::Count); ++i)
        if (name == graphOpName(Op(i))) return Op(i);
    throw Error("node '" + node + "': unknown op '" + name + "'");
}

void ensureShape(Tensor& t, const Shape& shape) {
    if (t.shape() != shape || t.data() == nullptr) t = Tensor(shape);
}

}  // namespace

struct Model::Impl {
    nlohmann::json architecture;
    std::string name;
    int inputChannels = 0;
    int outputNode = -1;
    std::vector<Node> nodes;
    std::vector<ParameterInfo> parameters;
    std::vector<float> params, grads;
    std::string init = "he_normal";
    bool fastKernels = true;
    const Tensor* lastInput = nullptr;
    Shape lastInputShape;

    // Output shape of node i given its input shapes (validating them).
    Shape nodeOutputShape(const Node& n, const std::vector<Shape>& ins) const {
        const Shape& in = ins[0];
        auto fail = [&](const std::string& what) { return Error("node '" + n.name + "': " + what); };
        try {
            switch (n.op) {
                case Op::Conv2d: {
                    const Conv2dDesc d = n.convDesc(in);
                    d.validate();
                    return {in[0], n.outChannels, d.outHeight(), d.outWidth()};
                }
                case Op::ConvTranspose2d: {
                    const ConvTranspose2dDesc d = n.convTransposeDesc(in);
                    d.validate();
                    return {in[0], n.outChannels, d.outHeight(), d.outWidth()};
                }
                case Op::MaxPool2d: {
                    const MaxPool2dDesc d = n.poolDesc(in);
                    d.validate();
                    return {in[0], in[1], d.outHeight(), d.outWidth()};
                }
                case Op::Activation:
                    return in;
                case Op::Add:
                    if (ins[1] != in)
                        throw fail("adds " + shapeToString(in) + " and " + shapeToString(ins[1]) +
                                   " (shapes differ)");
                    return in;
                case Op::Concat: {
                    Shape out = in;
                    out[1] = 0;
                    for (const Shape& s : ins) {
                        if (s[0] != in[0] || s[2] != in[2] || s[3] != in[3])
                            throw fail("concatenates " + shapeToString(in) + " and " + shapeToString(s));
                        out[1] += s[1];
                    }
                    return out;
                }
                case Op::Upsample:
                    return {in[0], in[1], in[2] * n.factor, in[3] * n.factor};
                case Op::PixelShuffle:
                    return {in[0], in[1] / (n.factor * n.factor), in[2] * n.factor, in[3] * n.factor};
                case Op::KernelFilter: {
                    const Shape want{in[0], int64_t(n.kernel) * n.kernel, in[2], in[3]};
                    if (ins[1] != want)
                        throw fail("filters " + shapeToString(in) + " with logits " + shapeToString(ins[1]) +
                                   " (wanted " + shapeToString(want) + ")");
                    return in;
                }
                case Op::Count:
                    break;
            }
        } catch (const Error& e) {
            const std::string message = e.what();
            if (message.rfind("node '", 0) == 0) throw;
            throw fail(message);
        }
        throw fail("bad op");
    }

    std::vector<Shape> inputShapes(const Node& n, const std::vector<Shape>& shapes,
                                   const Shape& input) const {
        std::vector<Shape> ins;
        for (int i : n.inputs) ins.push_back(i < 0 ? input : shapes[size_t(i)]);
        return ins;
    }

    const Tensor& inputTensor(int index) const {
        return index < 0 ? *lastInput : nodes[size_t(index)].output;
    }
};

const char* graphOpName(GraphOp op) {
    static constexpr const char* kNames[] = {"conv2d",       "conv_transpose2d", "maxpool2d", "activation",
                                             "add",          "concat",           "upsample",  "pixel_shuffle",
                                             "kernel_filter"};
    static_assert(sizeof(kNames) / sizeof(kNames[0]) == size_t(GraphOp::Count), "every op needs a name");
    return op < GraphOp::Count ? kNames[int(op)] : "unknown";
}

Conv2dDesc GraphNode::convDesc(const Shape& in) const {
    const GraphNode& n = *this;
    Conv2dDesc d;
    d.batch = in[0], d.inChannels = in[1], d.inHeight = in[2], d.inWidth = in[3];
    d.outChannels = n.outChannels, d.kernelHeight = d.kernelWidth = n.kernel;
    d.strideH = d.strideW = n.stride;
    d.dilationH = d.dilationW = n.dilation;
    d.bias = n.bias;
    if (n.samePadding)
        d.setSamePadding();
    else
        d.padTop = d.padBottom = d.padLeft = d.padRight = n.padding;
    return d;
}
ConvTranspose2dDesc GraphNode::convTransposeDesc(const Shape& in) const {
    const GraphNode& n = *this;
    ConvTranspose2dDesc d;
    d.batch = in[0], d.inChannels = in[1], d.inHeight = in[2], d.inWidth = in[3];
    d.outChannels = n.outChannels, d.kernelHeight = d.kernelWidth = n.kernel;
    d.strideH = d.strideW = n.stride;
    d.padH = d.padW = n.padding;
    d.outputPaddingH = d.outputPaddingW = n.outputPadding;
    d.dilationH = d.dilationW = n.dilation;
    d.bias = n.bias;
    return d;
}
MaxPool2dDesc GraphNode::poolDesc(const Shape& in) const {
    const GraphNode& n = *this;
    MaxPool2dDesc d;
    d.batch = in[0], d.channels = in[1], d.inHeight = in[2], d.inWidth = in[3];
    d.kernel = n.kernel, d.stride = n.stride;
    return d;
}
ResampleDesc GraphNode::resampleDesc(const Shape& in) const {
    return {in[0], in[1], in[2], in[3], factor};
}
KernelFilterDesc GraphNode::kernelFilterDesc(const Shape& in) const {
    return {in[0], in[1], in[2], in[3], kernel, centreBias};
}

Model::Model(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Model::Model(Model&&) noexcept = default;
Model& Model::operator=(Model&&) noexcept = default;
Model::~Model() = default;

Model Model::fromArchitecture(const nlohmann::json& a) {
    auto impl = std::make_unique<Impl>();
    impl->architecture = a;
    auto fail = [](const std::string& what) { return Error("architecture: " + what); };
    if (!a.is_object()) throw fail("not a JSON object");
    try {
        impl->name = a.value("name", "model");
        impl->inputChannels = a.at("input_channels").get<int>();
        impl->init = a.value("init", "he_normal");
        if (impl->init != "he_normal" && impl->init != "glorot_uniform")
            throw fail("init must be he_normal or glorot_uniform, not '" + impl->init + "'");
        if (impl->inputChannels < 1 || impl->inputChannels > 4096)
            throw fail("input_channels must be 1..4096");
        const auto& nodes = a.at("nodes");
        if (!nodes.is_array() || nodes.empty()) throw fail("nodes must be a non-empty array");
        std::map<std::string, int> indexOf;
        std::vector<int> channels;  // per node
        int64_t offset = 0;
        for (const auto& j : nodes) {
            Node n;
            n.name = j.at("name").get<std::string>();
            if (n.name.empty() || n.name == "input" || indexOf.count(n.name))
                throw fail("node name '" + n.name + "' is empty, reserved or repeated");
            n.op = parseOp(j.at("op").get<std::string>(), n.name);
            for (const auto& input : j.at("inputs")) {
                const std::string source = input.get<std::string>();
                if (source == "input")
                    n.inputs.push_back(-1);
                else if (indexOf.count(source))
                    n.inputs.push_back(indexOf[source]);
                else
                    throw Error("node '" + n.name + "': input '" + source +
                                "' is not 'input' or an earlier node");
            }
            const size_t wantInputs =
                (n.op == Op::Add || n.op == Op::KernelFilter) ? 2 : (n.op == Op::Concat ? 0 : 1);
            if ((wantInputs && n.inputs.size() != wantInputs) || (n.op == Op::Concat && n.inputs.size() < 2))
                throw Error("node '" + n.name + "': " + graphOpName(n.op) + " takes " +
                            (n.op == Op::Concat ? std::string("two or more inputs")
                                                : std::to_string(wantInputs) + " input(s)"));
            auto channelsOf = [&](int i) { return i < 0 ? impl->inputChannels : channels[size_t(i)]; };
            n.inChannels = channelsOf(n.inputs[0]);
            auto readActivation = [&](const nlohmann::json& src) {
                n.activation.kind = parseActivation(src.value("activation", "none"));
                n.activation.slope = src.value("slope", 0.01f);
                n.activation.low = src.value("low", 0.0f);
                n.activation.high = src.value("high", 1.0f);
            };
            switch (n.op) {
                case Op::Conv2d:
                case Op::ConvTranspose2d: {
                    n.outChannels = j.at("out_channels").get<int>();
                    n.kernel = j.at("kernel").get<int>();
                    n.stride = j.value("stride", n.op == Op::Conv2d ? 1 : 2);
                    n.dilation = j.value("dilation", 1);
                    n.bias = j.value("bias", true);
                    if (j.contains("padding") && j["padding"].is_string()) {
                        const std::string mode = j["padding"];
                        if (mode == "same" && n.op == Op::Conv2d)
                            n.samePadding = true;
                        else if (mode != "valid")
                            throw Error("node '" + n.name + "': padding '" + mode + "'");
                    } else {
                        n.padding = j.value("padding", 0);
                    }
                    n.outputPadding = j.value("output_padding", 0);
                    readActivation(j);
                    if (n.outChannels < 1 || n.kernel < 1 || n.stride < 1 || n.dilation < 1 || n.padding < 0)
                        throw Error("node '" + n.name +
                                    "': out_channels, kernel, stride and dilation must be >= 1");
                    // Bounds far above any image filter, so a typo is one line rather than an allocation
                    // of terabytes: channels, kernel, stride, dilation and padding.
                    const auto atMost = [&](const char* field, int value, int limit) {
                        if (value > limit)
                            throw Error("node '" + n.name + "': " + field + " " + std::to_string(value) +
                                        " is above " + std::to_string(limit));
                    };
                    atMost("out_channels", n.outChannels, kMaxChannels);
                    atMost("kernel", n.kernel, kMaxKernel);
                    atMost("stride", n.stride, kMaxKernel);
                    atMost("dilation", n.dilation, kMaxKernel);
                    atMost("padding", n.padding, kMaxKernel * kMaxKernel);
                    if (n.outputPadding < 0 || (n.outputPadding > 0 && n.outputPadding >= n.stride))
                        throw Error("node '" + n.name +
                                    "': output_padding must be >= 0 and below the stride");
                    const int64_t weights = int64_t(n.inChannels) * n.outChannels * n.kernel * n.kernel;
                    ParameterInfo w;
                    w.name = n.name + ".weight";
                    w.shape = n.op == Op::Conv2d ? Shape{n.outChannels, n.inChannels, n.kernel, n.kernel}
                                                 : Shape{n.inChannels, n.outChannels, n.kernel, n.kernel};
                    w.offset = n.weightOffset = offset;
                    w.fanIn = int64_t(n.inChannels) * n.kernel * n.kernel;
                    w.fanOut = int64_t(n.outChannels) * n.kernel * n.kernel;
                    w.initScale = j.value("init_scale", 1.0);
                    if (!(w.initScale >= 0) || !std::isfinite(w.initScale))
                        throw Error("node '" + n.name + "': init_scale must be finite and >= 0");
                    impl->parameters.push_back(w);
                    offset += weights;
                    if (n.bias) {
                        ParameterInfo b;
                        b.name = n.name + ".bias";
                        b.shape = {n.outChannels};
                        b.offset = n.biasOffset = offset;
                        b.isBias = true;
                        impl->parameters.push_back(b);
                        offset += n.outChannels;
                    }
                    break;
                }
                case Op::MaxPool2d:
                    n.kernel = j.value("kernel", 2);
                    n.stride = j.value("stride", n.kernel);
                    n.outChannels = n.inChannels;
                    break;
                case Op::Activation:
                    readActivation(j);
                    n.outChannels = n.inChannels;
                    break;
                case Op::Add:
                    if (channelsOf(n.inputs[1]) != n.inChannels)
                        throw Error("node '" + n.name + "': adds " + std::to_string(n.inChannels) + " and " +
                                    std::to_string(channelsOf(n.inputs[1])) + " channels");
                    n.outChannels = n.inChannels;
                    break;
                case Op::Concat:
                    n.outChannels = 0;
                    for (int i : n.inputs) n.outChannels += channelsOf(i);
                    break;
                case Op::Upsample: {
                    const std::string mode = j.value("mode", "nearest");
                    if (mode != "nearest" && mode != "bilinear")
                        throw Error("node '" + n.name + "': upsample mode '" + mode + "'");
                    n.bilinear = mode == "bilinear";
                    n.factor = j.value("factor", 2);
                    n.outChannels = n.inChannels;
                    break;
                }
                case Op::PixelShuffle:
                    n.factor = j.value("factor", 2);
                    if (n.factor < 1 || n.inChannels % (n.factor * n.factor))
                        throw Error("node '" + n.name + "': " + std::to_string(n.inChannels) +
                                    " channels are not a multiple of factor^2");
                    n.outChannels = n.inChannels / (n.factor * n.factor);
                    break;
                case Op::KernelFilter:
                    n.kernel = j.value("kernel", 3);
                    n.centreBias = j.value("centre_bias", 0.0f);
                    if (n.kernel < 1 || n.kernel > 7 || n.kernel % 2 == 0)
                        throw Error("node '" + n.name + "': kernel must be odd and 1..7");
                    if (!std::isfinite(n.centreBias))
                        throw Error("node '" + n.name + "': centre_bias must be finite");
                    if (channelsOf(n.inputs[1]) != n.kernel * n.kernel)
                        throw Error("node '" + n.name + "': the logits have " +
                                    std::to_string(channelsOf(n.inputs[1])) +
                                    " channels, not kernel^2 = " + std::to_string(n.kernel * n.kernel));
                    n.outChannels = n.inChannels;
                    break;
                case Op::Count:
                    break;
            }
            if ((n.op == Op::Upsample || n.op == Op::PixelShuffle) && (n.factor < 1 || n.factor > 16))
                throw Error("node '" + n.name + "': factor must be 1..16");
            if (n.outChannels > kMaxChannels)
                throw Error("node '" + n.name + "' has " + std::to_string(n.outChannels) +
                            " channels, above " + std::to_string(kMaxChannels));
            if (offset > kMaxParameters)
                throw Error("node '" + n.name + "' brings the model to " + std::to_string(offset) +
                            " parameters, above the " + std::to_string(kMaxParameters) + " dejag accepts");
            indexOf[n.name] = int(impl->nodes.size());
            channels.push_back(n.outChannels);
            impl->nodes.push_back(std::move(n));
        }
        const std::string output = a.value("output", impl->nodes.back().name);
        if (!indexOf.count(output)) throw fail("output '" + output + "' is not a node");
        impl->outputNode = indexOf[output];
        impl->params.assign(size_t(offset), 0.0f);
        impl->grads.assign(size_t(offset), 0.0f);
    } catch (const nlohmann::json::exception& e) {
        throw fail(std::string("bad field (") + e.what() + ")");
    }
    return Model(std::move(impl));
}

nlohmann::json Model::builtinArchitecture(const std::string& name, const ModelOptions& options) {
    using nlohmann::json;
    auto conv = [](const std::string& n, const std::string& in, int out, int k, const std::string& act,
                   int stride = 1) {
        return json{{"name", n},   {"op", "conv2d"},   {"inputs", {in}},    {"out_channels", out},
                    {"kernel", k}, {"stride", stride}, {"padding", "same"}, {"activation", act}};
    };
    if (name == "seed2020") {
        // docs/seed-cnn.md. Activations are not published: ReLU inside, sigmoid at the end (output in
        // (0, 1) like the [0, 1] luminance input). Transposed convs: 3x3, stride 2, padding 1,
        // output_padding 1, so each exactly doubles the size (H and W must be multiples of 4).
        json nodes = json::array();
        nodes.push_back(conv("conv1", "input", 32, 5, "relu"));
        nodes.push_back(conv("conv2", "conv1", 32, 3, "relu"));
        nodes.push_back({{"name", "pool1"}, {"op", "maxpool2d"}, {"inputs", {"conv2"}}, {"kernel", 2}});
        nodes.push_back(conv("conv3", "pool1", 64, 1, "relu"));
        nodes.push_back({{"name", "pool2"}, {"op", "maxpool2d"}, {"inputs", {"conv3"}}, {"kernel", 2}});
        nodes.push_back(conv("conv4", "pool2", 128, 3, "relu"));
        nodes.push_back({{"name", "up1"},
                         {"op", "conv_transpose2d"},
                         {"inputs", {"conv4"}},
                         {"out_channels", 64},
                         {"kernel", 3},
                         {"stride", 2},
                         {"padding", 1},
                         {"output_padding", 1},
                         {"activation", "relu"}});
        nodes.push_back({{"name", "up2"},
                         {"op", "conv_transpose2d"},
                         {"inputs", {"up1"}},
                         {"out_channels", 1},
                         {"kernel", 3},
                         {"stride", 2},
                         {"padding", 1},
                         {"output_padding", 1},
                         {"activation", "sigmoid"}});
        return {{"name", "seed2020"},
                {"input_channels", 1},
                {"input_colour", "luma 0.21R + 0.72G + 0.07B of sRGB-encoded values"},
                {"normalisation", "[0, 1]"},
                {"init", "glorot_uniform"},
                {"nodes", nodes},
                {"output", "up2"}};
    }
    if (name == "fast" || name == "kpn") {
        // Residual RGB: output = input + correction. The correction is a small U-Net that never works at
        // full resolution: a stride-2 conv to 1/2 (width w), then per level a stride-2 conv and a conv
        // (widths 2w, 4w, ...) down to 1/2^depth; back up, each level is pixel-shuffled to the next finer
        // one, concatenated with its encoder features and convolved; a last conv makes 4 x channels at
        // 1/2 and a pixel shuffle brings them to full resolution. The coarse levels see far along an edge
        // for a few multiply-adds per pixel (docs/train.md).
        const int w = options.width, c = options.channels, levels = options.depth;
        if (w < 2 || w % 2 != 0 || w > kMaxChannels || levels < 2 || levels > 6 || c < 1)
            throw Error("the fast and kpn families need an even width from 2 to " +
                        std::to_string(kMaxChannels) + " and a depth (levels) in 2..6");
        json nodes = json::array();
        nodes.push_back(conv("enc1", "input", w, 3, "relu", 2));
        std::vector<std::string> encoder = {"enc1"};  // the output of each level
        for (int l = 2; l <= levels; ++l) {
            const std::string n = "enc" + std::to_string(l);
            const int width = w << (l - 1);
            nodes.push_back(conv(n, encoder.back(), width, 3, "relu", 2));
            nodes.push_back(conv(n + "b", n, width, 3, "relu"));
            encoder.push_back(n + "b");
        }
        std::string previous = encoder.back();
        for (int l = levels; l >= 2; --l) {
            const std::string up = "up" + std::to_string(l), cat = "cat" + std::to_string(l - 1),
                              dec = "dec" + std::to_string(l - 1);
            nodes.push_back({{"name", up}, {"op", "pixel_shuffle"}, {"inputs", {previous}}, {"factor", 2}});
            nodes.push_back({{"name", cat}, {"op", "concat"}, {"inputs", {up, encoder[size_t(l - 2)]}}});
            nodes.push_back(conv(dec, cat, w << (l - 2), 3, "relu"));
            previous = dec;
        }
        // The head, the same size for both: a last conv at 1/2 starting at 0.1x its initialisation
        // (the network starts near the identity), then a pixel shuffle to full resolution.
        const bool kernels = name == "kpn";
        const std::string head = kernels ? "to_kernels" : "to_subpixels",
                          output = kernels ? "filter" : "residual";
        if (kernels) {
            // Kernel-predicting: per full-resolution pixel, the 9 logits of a 3x3 kernel (a 1x1 conv makes 4
            // pixels' worth at 1/2); the output is the input filtered by those kernels (kernel_filter). A
            // softmax of near-zero logits with the centre raised by 4 puts 87 % of the weight in the centre.
            nodes.push_back(conv(head, previous, 4 * 9, 1, "none"));
        } else {
            nodes.push_back(conv(head, previous, 4 * c, 3, "none"));  // residual: output = input + correction
        }
        nodes.back()["init_scale"] = 0.1;
        nodes.push_back({{"name", "shuffle"}, {"op", "pixel_shuffle"}, {"inputs", {head}}, {"factor", 2}});
        if (kernels)
            nodes.push_back({{"name", output},
                             {"op", "kernel_filter"},
                             {"inputs", {"input", "shuffle"}},
                             {"kernel", 3},
                             {"centre_bias", 4.0}});
        else
            nodes.push_back({{"name", output}, {"op", "add"}, {"inputs", {"input", "shuffle"}}});
        return {{"name", name},
                {"input_channels", c},
                {"input_colour", "sRGB-encoded RGB"},
                {"normalisation", "[0, 1]"},
                {"init", "he_normal"},
                {"nodes", nodes},
                {"output", output},
                {"family", {{"width", w}, {"depth", levels}}}};
    }
    throw Error("unknown built-in architecture '" + name + "' (seed2020, fast, kpn)");
}

Model Model::builtin(const std::string& name, const ModelOptions& options) {
    return fromArchitecture(builtinArchitecture(name, options));
}

const nlohmann::json& Model::architecture() const {
    return impl_->architecture;
}
const std::string& Model::name() const {
    return impl_->name;
}
int Model::inputChannels() const {
    return impl_->inputChannels;
}
int Model::outputChannels() const {
    return impl_->nodes[size_t(impl_->outputNode)].outChannels;
}
const std::vector<ParameterInfo>& Model::parameters() const {
    return impl_->parameters;
}
std::vector<GraphNode> Model::graph() const {
    return {impl_->nodes.begin(), impl_->nodes.end()};
}
int Model::outputNode() const {
    return impl_->outputNode;
}

std::vector<Shape> Model::nodeShapes(const Shape& input) const {
    outputShape(input);  // validates the input shape
    std::vector<Shape> shapes;
    for (const Node& n : impl_->nodes)
        shapes.push_back(impl_->nodeOutputShape(n, impl_->inputShapes(n, shapes, input)));
    return shapes;
}
int64_t Model::parameterCount() const {
    return int64_t(impl_->params.size());
}
float* Model::parameterData() {
    return impl_->params.data();
}
const float* Model::parameterData() const {
    return impl_->params.data();
}
float* Model::gradientData() {
    return impl_->grads.data();
}
const float* Model::gradientData() const {
    return impl_->grads.data();
}

const ParameterInfo& Model::parameter(const std::string& name) const {
    for (const ParameterInfo& p : impl_->parameters)
        if (p.name == name) return p;
    throw Error("model '" + impl_->name + "' has no parameter '" + name + "'");
}

void Model::setFastKernels(bool fast) {
    impl_->fastKernels = fast;
}
bool Model::fastKernels() const {
    return impl_->fastKernels;
}

void Model::initialize(uint64_t seed) {
    Rng rng(seed);
    for (const ParameterInfo& p : impl_->parameters) {
        float* data = impl_->params.data() + p.offset;
        const int64_t count = shapeNumel(p.shape);
        if (p.isBias)
            std::fill(data, data + count, 0.0f);
        else if (impl_->init == "glorot_uniform")
            glorotUniform(data, count, p.fanIn, p.fanOut, rng);
        else
            heNormal(data, count, p.fanIn, rng);
        if (!p.isBias && p.initScale != 1.0)
            for (int64_t i = 0; i < count; ++i) data[i] = float(data[i] * p.initScale);
    }
}

Shape Model::outputShape(const Shape& input) const {
    if (input.size() != 4 || input[1] != impl_->inputChannels)
        throw Error("model '" + impl_->name + "' takes (N, " + std::to_string(impl_->inputChannels) +
                    ", H, W) input, not " + shapeToString(input));
    std::vector<Shape> shapes;
    for (const Node& n : impl_->nodes)
        shapes.push_back(impl_->nodeOutputShape(n, impl_->inputShapes(n, shapes, input)));
    return shapes[size_t(impl_->outputNode)];
}

int64_t Model::macs(const Shape& input) const {
    outputShape(input);
    std::vector<Shape> shapes;
    int64_t total = 0;
    for (const Node& n : impl_->nodes) {
        const std::vector<Shape> ins = impl_->inputShapes(n, shapes, input);
        if (n.op == Op::Conv2d) total += n.convDesc(ins[0]).macs();
        if (n.op == Op::ConvTranspose2d) total += n.convTransposeDesc(ins[0]).macs();
        if (n.op == Op::KernelFilter) total += shapeNumel(ins[0]) * n.kernel * n.kernel;
        shapes.push_back(impl_->nodeOutputShape(n, ins));
    }
    return total;
}

const Tensor& Model::forward(const Tensor& input) {
    Impl& m = *impl_;
    if (input.rank() != 4 || input.dim(1) != m.inputChannels)
        throw Error("model '" + m.name + "' takes (N, " + std::to_string(m.inputChannels) +
                    ", H, W) input, not " + shapeToString(input.shape()));
    if (const int64_t bad = input.findNonFinite(); bad >= 0)
        throw Error("the model input has a non-finite value (" + std::to_string(input.data()[bad]) +
                    ") at element " + std::to_string(bad));
    m.lastInput = &input;
    m.lastInputShape = input.shape();
    std::vector<Shape> shapes;
    for (Node& n : m.nodes) {
        const std::vector<Shape> ins = m.inputShapes(n, shapes, input.shape());
        const Shape out = m.nodeOutputShape(n, ins);
        shapes.push_back(out);
        ensureShape(n.output, out);
        const float* x = m.inputTensor(n.inputs[0]).data();
        const float* weight = n.weightOffset >= 0 ? m.params.data() + n.weightOffset : nullptr;
        const float* bias = n.biasOffset >= 0 ? m.params.data() + n.biasOffset : nullptr;
        const bool fused =
            (n.op == Op::Conv2d || n.op == Op::ConvTranspose2d) && n.activation.kind != Activation::None;
        float* target = n.output.data();
        if (fused) {
            ensureShape(n.preActivation, out);
            target = n.preActivation.data();
        }
        switch (n.op) {
            case Op::Conv2d:
            case Op::ConvTranspose2d:
                if (m.fastKernels) {
                    n.fastConv.reset();  // weights change between steps: pack again
                    // A few input channels (the RGB or grey image): planar, a 16th of the traffic.
                    const int inputBlock = n.inChannels <= 4 ? 1 : 0;
                    if (n.op == Op::Conv2d)
                        n.fastConv.emplace(n.convDesc(ins[0]), weight, bias, ActivationDesc{Activation::None},
                                           inputBlock);
                    else
                        n.fastConv.emplace(n.convTransposeDesc(ins[0]), weight, bias,
                                           ActivationDesc{Activation::None}, inputBlock);
                    const BlockedShape inShape = n.fastConv->inputShape(n.fastConv->requiredInputBorder());
                    const BlockedShape outShape = n.fastConv->outputShape(0);
                    if (n.blockedInput.numel() != inShape.floatCount() ||
                        n.blockedInputShape.border != inShape.border ||
                        n.blockedInputShape.block != inShape.block)
                        n.blockedInput = allocateBlocked(inShape);  // zero border and unused channels
                    n.blockedInputShape = inShape;
                    ensureBlocked(n.blockedOutput, outShape);
                    toBlocked(n.blockedInput.data(), x, inShape);
                    n.fastConv->forward(n.blockedOutput.data(), outShape, n.blockedInput.data(), inShape);
                    fromBlocked(target, n.blockedOutput.data(), outShape);
                } else if (n.op == Op::Conv2d) {
                    conv2dForward(target, x, weight, bias, n.convDesc(ins[0]));
                } else {
                    convTranspose2dForward(target, x, weight, bias, n.convTransposeDesc(ins[0]));
                }
                break;
            case Op::MaxPool2d:
                n.argmax.resize(size_t(shapeNumel(out)));
                maxPool2dForward(target, n.argmax.data(), x, n.poolDesc(ins[0]));
                break;
            case Op::Activation:
                activationForward(target, x, shapeNumel(out), n.activation);
                break;
            case Op::Add:
                addForward(target, x, m.inputTensor(n.inputs[1]).data(), shapeNumel(out));
                break;
            case Op::Concat: {
                std::vector<const float*> sources;
                std::vector<int64_t> channels;
                for (size_t i = 0; i < n.inputs.size(); ++i) {
                    sources.push_back(m.inputTensor(n.inputs[i]).data());
                    channels.push_back(ins[i][1]);
                }
                concatForward(target, sources, channels, out[0], out[2] * out[3]);
                break;
            }
            case Op::Upsample:
                if (n.bilinear)
                    upsampleBilinearForward(target, x, n.resampleDesc(ins[0]));
                else
                    upsampleNearestForward(target, x, n.resampleDesc(ins[0]));
                break;
            case Op::PixelShuffle:
                pixelShuffleForward(target, x, n.resampleDesc(ins[0]));
                break;
            case Op::KernelFilter:
                kernelFilterForward(target, x, m.inputTensor(n.inputs[1]).data(), n.kernelFilterDesc(ins[0]));
                break;
            case Op::Count:
                break;
        }
        if (fused) activationForward(n.output.data(), n.preActivation.data(), shapeNumel(out), n.activation);
    }
    return m.nodes[size_t(m.outputNode)].output;
}

void Model::backward(const Tensor& doutput) {
    Impl& m = *impl_;
    if (!m.lastInput) throw Error("backward() before forward()");
    Node& outputNode = m.nodes[size_t(m.outputNode)];
    doutput.requireShape(outputNode.output.shape(), "model output gradient");
    std::fill(m.grads.begin(), m.grads.end(), 0.0f);
    for (Node& n : m.nodes) {
        ensureShape(n.gradient, n.output.shape());
        n.gradient.zero();
    }
    std::memcpy(outputNode.gradient.data(), doutput.data(), doutput.byteSize());
    std::vector<Shape> shapes;
    for (const Node& n : m.nodes) shapes.push_back(n.output.shape());

    for (int i = int(m.nodes.size()) - 1; i >= 0; --i) {
        Node& n = m.nodes[size_t(i)];
        const std::vector<Shape> ins = m.inputShapes(n, shapes, m.lastInputShape);
        const float* x = m.inputTensor(n.inputs[0]).data();
        float* dx = n.inputs[0] >= 0 ? m.nodes[size_t(n.inputs[0])].gradient.data() : nullptr;
        const float* weight = n.weightOffset >= 0 ? m.params.data() + n.weightOffset : nullptr;
        float* dweight = n.weightOffset >= 0 ? m.grads.data() + n.weightOffset : nullptr;
        float* dbias = n.biasOffset >= 0 ? m.grads.data() + n.biasOffset : nullptr;
        const int64_t count = n.output.numel();
        const float* g = n.gradient.data();
        const bool fused =
            (n.op == Op::Conv2d || n.op == Op::ConvTranspose2d) && n.activation.kind != Activation::None;
        if (fused) {
            ensureShape(n.preActivationGradient, n.output.shape());
            n.preActivationGradient.zero();
            activationBackward(n.preActivationGradient.data(), g, n.preActivation.data(), n.output.data(),
                               count, n.activation);
            g = n.preActivationGradient.data();
        }
        switch (n.op) {
            case Op::Conv2d:
            case Op::ConvTranspose2d:
                if (m.fastKernels && n.fastConv) {
                    // Weight and bias gradients from the blocked forward input; the input gradient as the
                    // adjoint convolution when there is one, else the reference kernel.
                    std::optional<BlockedConv> adjoint;
                    if (dx)
                        adjoint = n.op == Op::Conv2d
                                      ? BlockedConv::inputGradient(n.convDesc(ins[0]), weight)
                                      : BlockedConv::inputGradient(n.convTransposeDesc(ins[0]), weight);
                    const int border = adjoint ? adjoint->requiredInputBorder() : 0;
                    const BlockedShape gShape = n.fastConv->outputShape(border);
                    if (n.blockedGradient.numel() != gShape.floatCount())
                        n.blockedGradient = allocateBlocked(gShape);
                    toBlocked(n.blockedGradient.data(), g, gShape);
                    n.fastConv->backwardWeights(dweight, dbias, n.blockedGradient.data(), gShape,
                                                n.blockedInput.data(), n.blockedInputShape);
                    if (adjoint) {
                        const BlockedShape dinShape = adjoint->outputShape(0);
                        ensureBlocked(n.blockedInputGradient, dinShape);
                        adjoint->forward(n.blockedInputGradient.data(), dinShape, n.blockedGradient.data(),
                                         gShape);
                        ensureShape(n.inputGradient, ins[0]);
                        fromBlocked(n.inputGradient.data(), n.blockedInputGradient.data(), dinShape);
                        addForward(dx, dx, n.inputGradient.data(), n.inputGradient.numel());
                    } else if (dx && n.op == Op::Conv2d) {
                        conv2dBackward<float>(dx, nullptr, nullptr, g, x, weight, n.convDesc(ins[0]));
                    } else if (dx) {
                        convTranspose2dBackward<float>(dx, nullptr, nullptr, g, x, weight,
                                                       n.convTransposeDesc(ins[0]));
                    }
                } else if (n.op == Op::Conv2d) {
                    conv2dBackward(dx, dweight, dbias, g, x, weight, n.convDesc(ins[0]));
                } else {
                    convTranspose2dBackward(dx, dweight, dbias, g, x, weight, n.convTransposeDesc(ins[0]));
                }
                break;
            case Op::MaxPool2d:
                if (dx) maxPool2dBackward(dx, g, n.argmax.data(), n.poolDesc(ins[0]));
                break;
            case Op::Activation:
                if (dx) activationBackward(dx, g, x, n.output.data(), count, n.activation);
                break;
            case Op::Add: {
                float* db = n.inputs[1] >= 0 ? m.nodes[size_t(n.inputs[1])].gradient.data() : nullptr;
                addBackward(dx, db, g, count);
                break;
            }
            case Op::Concat: {
                std::vector<float*> grads;
                std::vector<int64_t> channels;
                for (size_t k = 0; k < n.inputs.size(); ++k) {
                    grads.push_back(n.inputs[k] >= 0 ? m.nodes[size_t(n.inputs[k])].gradient.data()
                                                     : nullptr);
                    channels.push_back(ins[k][1]);
                }
                concatBackward(grads, g, channels, n.output.dim(0), n.output.dim(2) * n.output.dim(3));
                break;
            }
            case Op::Upsample:
                if (dx) {
                    if (n.bilinear)
                        upsampleBilinearBackward(dx, g, n.resampleDesc(ins[0]));
                    else
                        upsampleNearestBackward(dx, g, n.resampleDesc(ins[0]));
                }
                break;
            case Op::PixelShuffle:
                if (dx) pixelShuffleBackward(dx, g, n.resampleDesc(ins[0]));
                break;
            case Op::KernelFilter: {
                float* dlogits = n.inputs[1] >= 0 ? m.nodes[size_t(n.inputs[1])].gradient.data() : nullptr;
                kernelFilterBackward(dx, dlogits, g, x, m.inputTensor(n.inputs[1]).data(),
                                     n.kernelFilterDesc(ins[0]));
                break;
            }
            case Op::Count:
                break;
        }
    }
}

void saveModel(const std::string& path, const Model& model,
               const std::map<std::string, std::string>& metadata) {
    std::vector<TensorToWrite> tensors;
    for (const ParameterInfo& p : model.parameters())
        tensors.push_back({p.name, p.shape, model.parameterData() + p.offset});
    std::map<std::string, std::string> all = metadata;
    all["dejag.architecture"] = model.architecture().dump();
    all["dejag.input_colour"] = model.architecture().value("input_colour", "unspecified");
    all["dejag.normalisation"] = model.architecture().value("normalisation", "unspecified");
    all["dejag.format"] = "dejag-model-1";
    writeSafetensors(path, tensors, all);
}

Model loadModel(const std::string& path, std::map<std::string, std::string>* metadata) {
    const SafetensorsFile file = readSafetensors(path);
    auto fail = [&](const std::string& what) { return Error("model '" + path + "': " + what); };
    auto it = file.metadata.find("dejag.architecture");
    if (it == file.metadata.end()) throw fail("no dejag.architecture in the metadata (not a dejag model)");
    nlohmann::json architecture;
    try {
        architecture = nlohmann::json::parse(it->second);
    } catch (const nlohmann::json::exception&) {
        throw fail("dejag.architecture is not JSON");
    }
    Model model = [&] {
        try {
            return Model::fromArchitecture(architecture);
        } catch (const Error& e) {
            throw fail(e.what());
        }
    }();
    // A training checkpoint holds the architecture too, but its weights as one flat tensor with the
    // optimizer's moments: it is no model file until `dejag train export` makes one of the run.
    if (auto format = file.metadata.find("dejag.format");
        format != file.metadata.end() && format->second.rfind("dejag-checkpoint", 0) == 0)
        throw fail(
            "a training checkpoint, not a model; export the run with dejag train export RUN "
            "MODEL.safetensors");
    for (const ParameterInfo& p : model.parameters()) {
        auto tensor = file.tensors.find(p.name);
        if (tensor == file.tensors.end()) throw fail("parameter '" + p.name + "' is missing");
        if (tensor->second.shape != p.shape)
            throw fail("parameter '" + p.name + "' has shape " + shapeToString(tensor->second.shape) +
                       ", the architecture needs " + shapeToString(p.shape));
        const std::vector<float> values = tensor->second.asFloat();
        for (size_t i = 0; i < values.size(); ++i)
            if (!std::isfinite(values[i]))
                throw fail("parameter '" + p.name + "' has a non-finite value at " + std::to_string(i));
        std::memcpy(model.parameterData() + p.offset, values.data(), values.size() * sizeof(float));
    }
    if (file.tensors.size() != model.parameters().size()) {
        for (const auto& [name, tensor] : file.tensors) {
            bool known = false;
            for (const ParameterInfo& p : model.parameters()) known |= p.name == name;
            if (!known) throw fail("tensor '" + name + "' is not a parameter of the architecture");
        }
    }
    if (metadata) *metadata = file.metadata;
    return model;
}

std::vector<double> forwardInDouble(const Model& model, const std::vector<double>& input,
                                    const Shape& inputShape) {
    if (int64_t(input.size()) != shapeNumel(inputShape))
        throw Error("forwardInDouble: the input does not have the shape given");
    const std::vector<GraphNode> graph = model.graph();
    const std::vector<Shape> shapes = model.nodeShapes(inputShape);
    const std::vector<double> params(model.parameterData(), model.parameterData() + model.parameterCount());
    std::vector<std::vector<double>> outputs(graph.size());
    auto tensor = [&](int index) -> const std::vector<double>& {
        return index < 0 ? input : outputs[size_t(index)];
    };
    auto shapeOf = [&](int index) -> const Shape& { return index < 0 ? inputShape : shapes[size_t(index)]; };
    for (size_t k = 0; k < graph.size(); ++k) {
        const GraphNode& n = graph[k];
        const Shape& in = shapeOf(n.inputs[0]);
        std::vector<double>& out = outputs[k];
        out.assign(size_t(shapeNumel(shapes[k])), 0.0);
        const double* x = tensor(n.inputs[0]).data();
        const double* weight = n.weightOffset >= 0 ? params.data() + n.weightOffset : nullptr;
        const double* bias = n.biasOffset >= 0 ? params.data() + n.biasOffset : nullptr;
        switch (n.op) {
            case GraphOp::Conv2d:
                conv2dForward(out.data(), x, weight, bias, n.convDesc(in));
                activationForward(out.data(), out.data(), int64_t(out.size()), n.activation);
                break;
            case GraphOp::ConvTranspose2d:
                convTranspose2dForward(out.data(), x, weight, bias, n.convTransposeDesc(in));
                activationForward(out.data(), out.data(), int64_t(out.size()), n.activation);
                break;
            case GraphOp::MaxPool2d: {
                std::vector<int32_t> argmax(out.size());
                maxPool2dForward(out.data(), argmax.data(), x, n.poolDesc(in));
                break;
            }
            case GraphOp::Activation:
                activationForward(out.data(), x, int64_t(out.size()), n.activation);
                break;
            case GraphOp::Add:
                addForward(out.data(), x, tensor(n.inputs[1]).data(), int64_t(out.size()));
                break;
            case GraphOp::Concat: {
                std::vector<const double*> sources;
                std::vector<int64_t> channels;
                for (int i : n.inputs) sources.push_back(tensor(i).data()), channels.push_back(shapeOf(i)[1]);
                concatForward(out.data(), sources, channels, shapes[k][0], shapes[k][2] * shapes[k][3]);
                break;
            }
            case GraphOp::Upsample:
                if (n.bilinear)
                    upsampleBilinearForward(out.data(), x, n.resampleDesc(in));
                else
                    upsampleNearestForward(out.data(), x, n.resampleDesc(in));
                break;
            case GraphOp::PixelShuffle:
                pixelShuffleForward(out.data(), x, n.resampleDesc(in));
                break;
            case GraphOp::KernelFilter:
                kernelFilterForward(out.data(), x, tensor(n.inputs[1]).data(), n.kernelFilterDesc(in));
                break;
            default:
                throw Error("forwardInDouble: node '" + n.name + "' has an op it does not know");
        }
    }
    return outputs[size_t(model.outputNode())];
}

}  // namespace dejag::nn

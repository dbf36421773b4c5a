#include "nn/model.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <optional>

#include "base/error.h"
#include "nn/fast_conv.h"
#include "nn/init.h"
#include "nn/ops.h"
#include "nn/safetensors.h"

namespace dejag::nn {
namespace {

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
    const Op op = opNamed(name);
    if (op == Op::Count) throw Error("node '" + node + "': unknown op '" + name + "'");
    return op;
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
    bool wantInputGradient = false;
    Tensor inputGradient;  // backward(): the gradient w.r.t. *lastInput, when wanted

    // Output shape of node i given its input shapes (validating them).
    Shape nodeOutputShape(const Node& n, const std::vector<Shape>& ins) const {
        auto fail = [&](const std::string& what) { return Error("node '" + n.name + "': " + what); };
        try {
            return opDef(n.op).outputShape(n, ins);
        } catch (const Error& e) {
            const std::string message = e.what();
            if (message.rfind("node '", 0) == 0) throw;
            throw fail(message);
        }
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
    return op < GraphOp::Count ? opDef(op).name : "unknown";
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
WarpDesc GraphNode::warpDesc(const Shape& in) const {
    WarpDesc d;
    d.batch = in[0], d.channels = in[1], d.height = in[2], d.width = in[3];
    d.filter = warpFilter;
    return d;
}

KernelFilterDesc GraphNode::kernelFilterDesc(const Shape& in, bool history) const {
    return {in[0], in[1], in[2], in[3], kernel, centreBias, history};
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
            const OpDef& def = opDef(n.op);
            if (int(n.inputs.size()) < def.minInputs ||
                (def.maxInputs && int(n.inputs.size()) > def.maxInputs))
                throw Error("node '" + n.name + "': " + def.name + " takes " +
                            (def.maxInputs == 0   ? std::to_string(def.minInputs) + " or more inputs"
                             : def.minInputs == 1 ? std::string("1 input")
                                                  : std::to_string(def.minInputs) + " inputs"));
            auto channelsOf = [&](int i) { return i < 0 ? impl->inputChannels : channels[size_t(i)]; };
            n.inChannels = channelsOf(n.inputs[0]);
            std::vector<int> inputChannels;
            for (int i : n.inputs) inputChannels.push_back(channelsOf(i));
            try {
                def.parse(n, OpParse{j, inputChannels, impl->parameters, offset});
            } catch (const Error& e) {
                throw Error("node '" + n.name + "': " + e.what());
            }
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
    // fast's U-Net from `from` (its nodes appended): a stride-2 conv to 1/2 (width w), then per level a
    // stride-2 conv and a conv (widths 2w, 4w, ...) down to 1/2^levels; back up, each level
    // pixel-shuffled to the next finer one, concatenated with its encoder features and convolved. Returns
    // the name of its last node (at 1/2, width w).
    auto unet = [&conv](json& nodes, const std::string& from, int w, int levels) {
        nodes.push_back(conv("enc1", from, w, 3, "relu", 2));
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
        return previous;
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
        const bool guided = options.guide;
        if (guided && (name != "kpn" || c != 3)) throw Error("a guide is for the RGB kpn family");
        json nodes = json::array();
        if (guided) {
            // The frame (channels 0..2) and the guide (3..5): the trunk sees both, the blend reads each.
            nodes.push_back(
                {{"name", "frame"}, {"op", "slice"}, {"inputs", {"input"}}, {"from", 0}, {"to", 3}});
            nodes.push_back(
                {{"name", "guide"}, {"op", "slice"}, {"inputs", {"input"}}, {"from", 3}, {"to", 6}});
        }
        const std::string previous = unet(nodes, "input", w, levels);
        // The head, the same size for both: a last conv at 1/2 starting at 0.1x its initialisation
        // (the network starts near the identity), then a pixel shuffle to full resolution.
        const bool kernels = name == "kpn";
        const std::string head = kernels ? "to_kernels" : "to_subpixels",
                          output = kernels ? "filter" : "residual";
        if (kernels) {
            // Kernel-predicting: per full-resolution pixel, the 9 logits of a 3x3 kernel (a 1x1 conv makes 4
            // pixels' worth at 1/2); the output is the input filtered by those kernels (kernel_filter). A
            // softmax of near-zero logits with the centre raised by 4 puts 87 % of the weight in the centre.
            // A guide adds a tenth logit per pixel: the weight of the guide's own pixel.
            nodes.push_back(conv(head, previous, 4 * (guided ? 10 : 9), 1, "none"));
        } else {
            nodes.push_back(conv(head, previous, 4 * c, 3, "none"));  // residual: output = input + correction
        }
        nodes.back()["init_scale"] = 0.1;
        nodes.push_back({{"name", "shuffle"}, {"op", "pixel_shuffle"}, {"inputs", {head}}, {"factor", 2}});
        if (kernels && guided)
            nodes.push_back({{"name", output},
                             {"op", "kernel_filter"},
                             {"inputs", {"frame", "shuffle", "guide"}},
                             {"kernel", 3},
                             {"centre_bias", 4.0}});
        else if (kernels)
            nodes.push_back({{"name", output},
                             {"op", "kernel_filter"},
                             {"inputs", {"input", "shuffle"}},
                             {"kernel", 3},
                             {"centre_bias", 4.0}});
        else
            nodes.push_back({{"name", output}, {"op", "add"}, {"inputs", {"input", "shuffle"}}});
        json family = {{"width", w}, {"depth", levels}};
        if (guided) family["guide"] = true;
        return {{"name", name},
                {"input_channels", guided ? 6 : c},
                {"input_colour", guided ? "sRGB-encoded RGB frame, then the guide method's result on it (RGB)"
                                        : "sRGB-encoded RGB"},
                {"normalisation", "[0, 1]"},
                {"init", "he_normal"},
                {"nodes", nodes},
                {"output", output},
                {"family", family}};
    }
    if (name == "accumulate") {
        // The temporal family's trunk with a TAA's running mean for its blend (docs/train.md). The output,
        // and so the next frame's history, is the frame shown (RGB), the mean of the samples kept (RGB)
        // and their confidence s = n / (n + 1); only the last four are warped and read. The head's 10
        // logits are the frame's 3x3 kernel and the trust in the history's samples, and `accumulate`
        // shows the kept mean blended with the filtered frame and keeps it blended with the frame's own
        // sample (up to max_count samples): a still view converges to the mean of its jittered samples
        // for any length of sequence, with nothing the network must learn to keep bounded.
        const int w = options.width, levels = options.depth;
        if (w < 2 || w % 2 != 0 || w > kMaxChannels || levels < 1 || levels > 6)
            throw Error("the accumulate family needs an even width from 2 to " +
                        std::to_string(kMaxChannels) + " and a depth (levels) in 1..6");
        auto slice = [](const std::string& n, const std::string& in, int from, int to) {
            return json{{"name", n}, {"op", "slice"}, {"inputs", {in}}, {"from", from}, {"to", to}};
        };
        json nodes = json::array();
        nodes.push_back(slice("frame", "input", 0, 3));
        nodes.push_back(slice("history", "input", 6, 10));  // the kept mean and its confidence
        nodes.push_back(slice("motion", "input", 10, 12));
        nodes.push_back(slice("jitter", "input", 12, 14));
        nodes.push_back({{"name", "warped"},
                         {"op", "warp"},
                         {"inputs", {"history", "motion"}},
                         {"filter", "catmull-rom"}});
        // The motion too, clamped to +-4 px: where it is 0 the history is exact (no resampling), which the
        // colours alone do not tell.
        nodes.push_back({{"name", "motion_seen"},
                         {"op", "activation"},
                         {"inputs", {"motion"}},
                         {"activation", "clamp"},
                         {"low", -4.0},
                         {"high", 4.0}});
        json seen = {"frame", "warped", "jitter", "motion_seen"};
        if (options.depthInput) {
            // The frame's depth, and the previous frame's read where each pixel was (bilinear: no
            // overshoot across a silhouette): where they differ, the history saw another surface.
            nodes.push_back(slice("depth", "input", 14, 15));
            nodes.push_back(slice("previous_depth", "input", 15, 16));
            nodes.push_back({{"name", "warped_depth"},
                             {"op", "warp"},
                             {"inputs", {"previous_depth", "motion"}},
                             {"filter", "bilinear"}});
            seen.push_back("depth"), seen.push_back("warped_depth");
        }
        nodes.push_back({{"name", "seen"}, {"op", "concat"}, {"inputs", seen}});
        const std::string previous = unet(nodes, "seen", w, levels);
        nodes.push_back(conv("head", previous, 4 * 10, 1, "none"));
        nodes.back()["init_scale"] = 0.1;
        nodes.push_back({{"name", "shuffle"}, {"op", "pixel_shuffle"}, {"inputs", {"head"}}, {"factor", 2}});
        nodes.push_back({{"name", "output"},
                         {"op", "accumulate"},
                         {"inputs", {"frame", "shuffle", "warped"}},
                         {"kernel", 3},
                         {"max_count", options.maxCount}});
        if (options.clip) nodes.back()["clip"] = true;
        json family = {{"width", w}, {"depth", levels}, {"max_count", options.maxCount}};
        if (options.depthInput) family["depth_input"] = true;
        if (options.clip) family["clip"] = true;
        return {
            {"name", "accumulate"},
            {"input_channels", options.depthInput ? 16 : 14},
            {"input_colour",
             std::string("sRGB-encoded RGB frame, previous output (RGB shown, RGB kept, confidence), motion "
                         "(px), jitter (px)") +
                 (options.depthInput ? ", depth / far, previous frame's depth / far" : "")},
            {"normalisation", "[0, 1]"},
            {"init", "he_normal"},
            {"nodes", nodes},
            {"output", "output"},
            {"family", family}};
    }
    if (name == "temporal") {
        // A recurrent network (docs/train.md, train/temporal.h): its input holds the frame, its own
        // previous output (RGB and `state` channels), the motion and the jitter. The history is warped
        // to where each pixel was (Catmull-Rom, taa-hq's history filter), put beside the frame and the
        // jitter, and the fast family's U-Net (from 1/2 down to 1/2^depth and back) makes per pixel the 10
        // logits of a blend: the softmax weights of the frame's
        // 3x3 neighbourhood and of the warped history (kernel_filter with a history). As in a TAA the output
        // can only mix what the frame and the history hold, and accumulating over frames is one weight.
        // The state channels are the warped state plus a correction.
        const int w = options.width, levels = options.depth, state = options.state, history = 3 + state;
        if (w < 2 || w % 2 != 0 || w > kMaxChannels || levels < 1 || levels > 6 || state < 0 || state > 16)
            throw Error("the temporal family needs an even width from 2 to " + std::to_string(kMaxChannels) +
                        ", a depth (levels) in 1..6 and 0..16 state channels");
        auto slice = [](const std::string& n, const std::string& in, int from, int to) {
            return json{{"name", n}, {"op", "slice"}, {"inputs", {in}}, {"from", from}, {"to", to}};
        };
        json nodes = json::array();
        nodes.push_back(slice("frame", "input", 0, 3));
        nodes.push_back(slice("history", "input", 3, 3 + history));
        nodes.push_back(slice("motion", "input", 3 + history, 5 + history));
        nodes.push_back(slice("jitter", "input", 5 + history, 7 + history));
        nodes.push_back({{"name", "warped"},
                         {"op", "warp"},
                         {"inputs", {"history", "motion"}},
                         {"filter", "catmull-rom"}});
        nodes.push_back({{"name", "seen"}, {"op", "concat"}, {"inputs", {"frame", "warped", "jitter"}}});
        const std::string previous = unet(nodes, "seen", w, levels);
        // The head at 1/2, as kpn's: a 1x1 conv makes four full-resolution pixels' worth of the blend's 10
        // logits and the state's correction, and a pixel shuffle puts them in place. Nothing but the
        // warp and the blend runs at full resolution.
        nodes.push_back(conv("head", previous, 4 * (10 + state), 1, "none"));
        nodes.back()["init_scale"] = 0.1;
        nodes.push_back({{"name", "shuffle"}, {"op", "pixel_shuffle"}, {"inputs", {"head"}}, {"factor", 2}});
        nodes.push_back(slice("blend_logits", "shuffle", 0, 10));
        std::string colourHistory = "warped";
        if (state > 0) {
            nodes.push_back(slice("warped_rgb", "warped", 0, 3));
            nodes.push_back(slice("warped_state", "warped", 3, history));
            colourHistory = "warped_rgb";
        }
        nodes.push_back({{"name", "blended"},
                         {"op", "kernel_filter"},
                         {"inputs", {"frame", "blend_logits", colourHistory}},
                         {"kernel", 3}});
        std::string output = "blended";
        if (state > 0) {
            nodes.push_back(slice("state_correction", "shuffle", 10, 10 + state));
            nodes.push_back(
                {{"name", "state"}, {"op", "add"}, {"inputs", {"warped_state", "state_correction"}}});
            nodes.push_back({{"name", "output"}, {"op", "concat"}, {"inputs", {"blended", "state"}}});
            output = "output";
        }
        return {{"name", "temporal"},
                {"input_channels", 3 + history + 4},
                {"input_colour",
                 "sRGB-encoded RGB frame, previous output (RGB + state), motion (px), jitter (px)"},
                {"normalisation", "[0, 1]"},
                {"init", "he_normal"},
                {"nodes", nodes},
                {"output", output},
                {"family", {{"width", w}, {"depth", levels}, {"state", state}}}};
    }
    throw Error("unknown built-in architecture '" + name + "' (seed2020, fast, kpn, temporal, accumulate)");
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
        if (const OpDef& def = opDef(n.op); def.macs) total += def.macs(n, ins);
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
        const OpDef& def = opDef(n.op);
        const bool fused = def.fusesActivation && n.activation.kind != Activation::None;
        float* target = n.output.data();
        if (fused) {
            ensureShape(n.preActivation, out);
            target = n.preActivation.data();
        }
        if (m.fastKernels && (n.op == Op::Conv2d || n.op == Op::ConvTranspose2d)) {
            // The convolutions' fast forward (nn/fast_conv.h), tested against the reference below.
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
                n.blockedInputShape.border != inShape.border || n.blockedInputShape.block != inShape.block)
                n.blockedInput = allocateBlocked(inShape);  // zero border and unused channels
            n.blockedInputShape = inShape;
            ensureBlocked(n.blockedOutput, outShape);
            toBlocked(n.blockedInput.data(), x, inShape);
            n.fastConv->forward(n.blockedOutput.data(), outShape, n.blockedInput.data(), inShape);
            fromBlocked(target, n.blockedOutput.data(), outShape);
        } else {
            OpForward<float> call{n, ins, out};
            for (int i : n.inputs) call.inputs.push_back(m.inputTensor(i).data());
            call.weight = weight, call.bias = bias, call.output = target, call.indices = &n.argmax;
            def.forward(call);
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
    float* dinput = nullptr;
    if (m.wantInputGradient) {
        ensureShape(m.inputGradient, m.lastInputShape);
        m.inputGradient.zero();
        dinput = m.inputGradient.data();
    }
    std::vector<Shape> shapes;
    for (const Node& n : m.nodes) shapes.push_back(n.output.shape());

    for (int i = int(m.nodes.size()) - 1; i >= 0; --i) {
        Node& n = m.nodes[size_t(i)];
        const std::vector<Shape> ins = m.inputShapes(n, shapes, m.lastInputShape);
        const float* x = m.inputTensor(n.inputs[0]).data();
        float* dx = n.inputs[0] >= 0 ? m.nodes[size_t(n.inputs[0])].gradient.data() : dinput;
        const float* weight = n.weightOffset >= 0 ? m.params.data() + n.weightOffset : nullptr;
        float* dweight = n.weightOffset >= 0 ? m.grads.data() + n.weightOffset : nullptr;
        float* dbias = n.biasOffset >= 0 ? m.grads.data() + n.biasOffset : nullptr;
        const int64_t count = n.output.numel();
        const float* g = n.gradient.data();
        const OpDef& def = opDef(n.op);
        const bool fused = def.fusesActivation && n.activation.kind != Activation::None;
        if (fused) {
            ensureShape(n.preActivationGradient, n.output.shape());
            n.preActivationGradient.zero();
            activationBackward(n.preActivationGradient.data(), g, n.preActivation.data(), n.output.data(),
                               count, n.activation);
            g = n.preActivationGradient.data();
        }
        if (m.fastKernels && n.fastConv && (n.op == Op::Conv2d || n.op == Op::ConvTranspose2d)) {
            // Weight and bias gradients from the blocked forward input; the input gradient as the
            // adjoint convolution when there is one, else the reference kernel.
            std::optional<BlockedConv> adjoint;
            if (dx)
                adjoint = n.op == Op::Conv2d
                              ? BlockedConv::inputGradient(n.convDesc(ins[0]), weight)
                              : BlockedConv::inputGradient(n.convTransposeDesc(ins[0]), weight);
            const int border = adjoint ? adjoint->requiredInputBorder() : 0;
            const BlockedShape gShape = n.fastConv->outputShape(border);
            if (n.blockedGradient.numel() != gShape.floatCount()) n.blockedGradient = allocateBlocked(gShape);
            toBlocked(n.blockedGradient.data(), g, gShape);
            n.fastConv->backwardWeights(dweight, dbias, n.blockedGradient.data(), gShape,
                                        n.blockedInput.data(), n.blockedInputShape);
            if (adjoint) {
                const BlockedShape dinShape = adjoint->outputShape(0);
                ensureBlocked(n.blockedInputGradient, dinShape);
                adjoint->forward(n.blockedInputGradient.data(), dinShape, n.blockedGradient.data(), gShape);
                ensureShape(n.inputGradient, ins[0]);
                fromBlocked(n.inputGradient.data(), n.blockedInputGradient.data(), dinShape);
                addForward(dx, dx, n.inputGradient.data(), n.inputGradient.numel());
            } else if (dx && n.op == Op::Conv2d) {
                conv2dBackward<float>(dx, nullptr, nullptr, g, x, weight, n.convDesc(ins[0]));
            } else if (dx) {
                convTranspose2dBackward<float>(dx, nullptr, nullptr, g, x, weight,
                                               n.convTransposeDesc(ins[0]));
            }
        } else {
            OpBackward<float> call{n, ins, n.output.shape()};
            for (int k : n.inputs) {
                call.inputs.push_back(m.inputTensor(k).data());
                call.dInputs.push_back(k >= 0 ? m.nodes[size_t(k)].gradient.data() : dinput);
            }
            call.weight = weight, call.output = n.output.data(), call.dOutput = g;
            call.dWeight = dweight, call.dBias = dbias, call.indices = &n.argmax;
            def.backward(call);
        }
    }
}

void Model::setInputGradient(bool wanted) {
    impl_->wantInputGradient = wanted;
}

const Tensor& Model::inputGradient() const {
    if (!impl_->wantInputGradient) throw Error("inputGradient(): not asked for (setInputGradient)");
    return impl_->inputGradient;
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
        std::vector<double>& out = outputs[k];
        out.assign(size_t(shapeNumel(shapes[k])), 0.0);
        const double* weight = n.weightOffset >= 0 ? params.data() + n.weightOffset : nullptr;
        const double* bias = n.biasOffset >= 0 ? params.data() + n.biasOffset : nullptr;
        const OpDef& def = opDef(n.op);
        std::vector<Shape> ins;
        for (int i : n.inputs) ins.push_back(shapeOf(i));
        OpForward<double> call{n, ins, shapes[k]};
        for (int i : n.inputs) call.inputs.push_back(tensor(i).data());
        call.weight = weight, call.bias = bias, call.output = out.data();
        def.forwardDouble(call);
        if (def.fusesActivation) activationForward(out.data(), out.data(), int64_t(out.size()), n.activation);
    }
    return outputs[size_t(model.outputNode())];
}

}  // namespace dejag::nn

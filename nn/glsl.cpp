// GLSL export: see nn/glsl.h. Each op's shader is written out from a template with its constants.
#include "nn/glsl.h"

#include <cstring>
#include <filesystem>
#include <fstream>
#include <numeric>
#include <sstream>

#include "base/error.h"
#include "base/files.h"

namespace dejag::nn {
namespace {

namespace fs = std::filesystem;

}  // namespace

std::string glslFloat(float v) {
    char text[48];
    std::snprintf(text, sizeof text, "%.9g", double(v));
    std::string s = text;
    if (s.find_first_of(".en") == std::string::npos) s += ".0";
    return s;
}

namespace {

// The prelude of every pass: version, work group, the buffers it binds, its sizes, the tensor index.
std::string prelude(const std::string& what, int inputs, bool weights) {
    std::ostringstream s;
    s << "#version 430\n// dejag: " << what << "\nlayout(local_size_x = 8, local_size_y = 8) in;\n";
    if (weights) s << "layout(std430, binding = 0) readonly buffer Weights { float weights[]; };\n";
    for (int i = 0; i < inputs; ++i)
        s << "layout(std430, binding = " << i + 1 << ") readonly buffer Input" << i << " { float in" << i
          << "[]; };\n";
    s << "layout(std430, binding = 4) writeonly buffer Output { float result[]; };\n"
         "uniform ivec2 inSize;   // width, height of the first input\n"
         "uniform ivec2 outSize;  // width, height of the output\n"
         "int at(int c, int y, int x, ivec2 size) { return (c * size.y + y) * size.x + x; }\n";
    return s.str();
}

std::string activationFunction(const ActivationDesc& a) {
    std::string body;
    switch (a.kind) {
        case Activation::None:
            body = "return v;";
            break;
        case Activation::ReLU:
            body = "return max(v, 0.0);";
            break;
        case Activation::LeakyReLU:
            body = "return v < 0.0 ? " + glslFloat(a.slope) + " * v : v;";
            break;
        case Activation::Sigmoid:
            body = "return 1.0 / (1.0 + exp(-v));";
            break;
        case Activation::Clamp:
            body = "return clamp(v, " + glslFloat(a.low) + ", " + glslFloat(a.high) + ");";
            break;
    }
    return "float activate(float v) { " + body + " }\n";
}

const char* const kMainStart =
    "void main() {\n"
    "    ivec2 p = ivec2(gl_GlobalInvocationID.xy);\n"
    "    if (p.x >= outSize.x || p.y >= outSize.y) return;\n";

}  // namespace

nlohmann::json GlslNetwork::description() const {
    nlohmann::json buffersJson = nlohmann::json::array(), passesJson = nlohmann::json::array();
    for (const GlslBuffer& b : buffers)
        buffersJson.push_back(
            {{"name", b.name}, {"channels", b.channels}, {"scale", {b.scaleNum, b.scaleDen}}});
    for (const GlslPass& p : passes)
        passesJson.push_back({{"shader", p.name + ".comp"}, {"inputs", p.inputs}, {"output", p.output}});
    nlohmann::json d = {
        {"format", "dejag-glsl-1"},
        {"model", model},
        {"architecture", architecture},
        {"input_channels", inputChannels},
        {"output_channels", outputChannels},
        {"size_divisor", sizeDivisor},
        {"layout",
         "every buffer planar float32 (channel, row, column); input: the model's input (sRGB-encoded "
         "values in [0, 1]); a buffer's width and height are the input's times scale[0] / scale[1]"},
        {"bindings",
         "0: weights.bin, 1-3: the pass's inputs in order, 4: its output; uniforms inSize (first input) "
         "and outSize (output), ivec2 (width, height); dispatch ceil(outSize / 8) groups of 8 x 8, a "
         "memory barrier (GL_SHADER_STORAGE_BARRIER_BIT) between passes"},
        {"weights", "weights.bin"},
        {"buffers", buffersJson},
        {"passes", passesJson},
        {"output", output}};
    bool recurrent = false;
    for (const nlohmann::json& node : architecture.value("nodes", nlohmann::json::array()))
        recurrent = recurrent || node.value("op", "") == "warp" || node.value("op", "") == "accumulate";
    if (recurrent)
        d["recurrent"] =
            "one frame per run: the input holds the frame and the network's own previous output (its whole "
            "output, kept between frames: the history), then the motion, the jitter" +
            std::string(inputChannels == 3 + outputChannels + 6 ? " and the depths" : "") +
            " (architecture.input_colour has the layout); on a fresh start the colour stands in for the "
            "previous output's R G B, its other channels and the motion are 0 (infer/glsl_filter.h's "
            "cnn-temporal assembles it so)";
    return d;
}

GlslNetwork exportGlsl(const Model& model) {
    static_assert(int(GraphOp::Count) == 12, "a new graph op needs its GLSL form here");
    GlslNetwork net;
    net.model = model.name();
    net.architecture = model.architecture();
    net.inputChannels = model.inputChannels();
    net.outputChannels = model.outputChannels();
    net.weights.assign(model.parameterData(), model.parameterData() + model.parameterCount());
    const std::vector<GraphNode> nodes = model.graph();
    // Sizes relative to the input's, from the shapes at a probe size every family takes.
    constexpr int kProbe = 1024;
    const std::vector<Shape> shapes = model.nodeShapes(Shape{1, model.inputChannels(), kProbe, kProbe});
    net.buffers.push_back({"input", model.inputChannels(), 1, 1});
    std::vector<std::string> names(nodes.size());
    for (size_t i = 0; i < nodes.size(); ++i) {
        const int side = int(shapes[i][2]);
        const int g = std::gcd(side, kProbe);
        const GlslBuffer b{nodes[i].name, int(shapes[i][1]), side / g, kProbe / g};
        net.sizeDivisor = std::lcm(net.sizeDivisor, b.scaleDen);
        net.buffers.push_back(b);
        names[i] = nodes[i].name;
    }
    const auto inputName = [&](int index) { return index < 0 ? std::string("input") : names[size_t(index)]; };
    const auto channelsOf = [&](int index) {
        return index < 0 ? model.inputChannels() : int(shapes[size_t(index)][1]);
    };
    int passIndex = 0;
    const auto addPass = [&](const std::string& name, std::string source, std::vector<std::string> inputs,
                             const std::string& output) {
        char stem[16];
        std::snprintf(stem, sizeof stem, "%02d_", passIndex++);
        net.passes.push_back({stem + name, std::move(source), std::move(inputs), output});
    };

    for (size_t i = 0; i < nodes.size(); ++i) {
        const GraphNode& n = nodes[i];
        const std::string& name = n.name;
        const int cin = n.inputs.empty() ? 0 : channelsOf(n.inputs[0]);
        const int cout = int(shapes[i][1]);
        std::ostringstream s;
        switch (n.op) {
            case GraphOp::Conv2d: {
                s << prelude("conv2d '" + name + "'", 1, true) << activationFunction(n.activation)
                  << "const int CIN = " << cin << ", COUT = " << cout << ", OB = " << std::min(cout, 16)
                  << ", K = " << n.kernel << ", S = " << n.stride << ", D = " << n.dilation << ";\n"
                  << "const int WOFF = " << n.weightOffset << ", BOFF = " << n.biasOffset << ";\n"
                  << kMainStart;
                if (n.samePadding)  // "same": the padding the size needs, the odd one after
                    s << "    int padY = max(0, (outSize.y - 1) * S + D * (K - 1) + 1 - inSize.y) / 2;\n"
                         "    int padX = max(0, (outSize.x - 1) * S + D * (K - 1) + 1 - inSize.x) / 2;\n";
                else
                    s << "    int padY = " << n.padding << ", padX = " << n.padding << ";\n";
                // Output channels in blocks of OB: a pixel's sums stay in registers (a sum array as large
                // as 56 x 64 weights is computed wrongly by llvmpipe of Mesa 22.3, and is slower anyway).
                s << "    for (int o0 = 0; o0 < COUT; o0 += OB) {\n"
                     "        float acc[OB];\n"
                     "        for (int o = 0; o < OB; ++o)\n"
                     "            acc[o] = o0 + o < COUT && BOFF >= 0 ? weights[BOFF + o0 + o] : 0.0;\n"
                     "        for (int ky = 0; ky < K; ++ky) {\n"
                     "            int iy = p.y * S - padY + ky * D;\n"
                     "            if (iy < 0 || iy >= inSize.y) continue;\n"
                     "            for (int kx = 0; kx < K; ++kx) {\n"
                     "                int ix = p.x * S - padX + kx * D;\n"
                     "                if (ix < 0 || ix >= inSize.x) continue;\n"
                     "                for (int ci = 0; ci < CIN; ++ci) {\n"
                     "                    float v = in0[at(ci, iy, ix, inSize)];\n"
                     "                    for (int o = 0; o < OB; ++o)\n"
                     "                        if (o0 + o < COUT)\n"
                     "                            acc[o] += v * weights[WOFF + (((o0 + o) * CIN + ci) * K + "
                     "ky) * K + kx];\n"
                     "                }\n"
                     "            }\n"
                     "        }\n"
                     "        for (int o = 0; o < OB && o0 + o < COUT; ++o)\n"
                     "            result[at(o0 + o, p.y, p.x, outSize)] = activate(acc[o]);\n"
                     "    }\n"
                     "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0])}, name);
                break;
            }
            case GraphOp::ConvTranspose2d: {
                s << prelude("conv_transpose2d '" + name + "'", 1, true) << activationFunction(n.activation)
                  << "const int CIN = " << cin << ", COUT = " << cout << ", K = " << n.kernel
                  << ", S = " << n.stride << ", D = " << n.dilation << ", P = " << n.padding << ";\n"
                  << "const int WOFF = " << n.weightOffset << ", BOFF = " << n.biasOffset << ";\n"
                  << kMainStart
                  << "    float acc[COUT];\n"
                     "    for (int o = 0; o < COUT; ++o) acc[o] = BOFF >= 0 ? weights[BOFF + o] : 0.0;\n"
                     "    for (int ky = 0; ky < K; ++ky) {\n"
                     "        int ty = p.y + P - ky * D;\n"
                     "        if (ty < 0 || ty % S != 0 || ty / S >= inSize.y) continue;\n"
                     "        for (int kx = 0; kx < K; ++kx) {\n"
                     "            int tx = p.x + P - kx * D;\n"
                     "            if (tx < 0 || tx % S != 0 || tx / S >= inSize.x) continue;\n"
                     "            for (int ci = 0; ci < CIN; ++ci) {\n"
                     "                float v = in0[at(ci, ty / S, tx / S, inSize)];\n"
                     "                for (int o = 0; o < COUT; ++o)\n"
                     "                    acc[o] += v * weights[WOFF + ((ci * COUT + o) * K + ky) * K + "
                     "kx];\n"
                     "            }\n"
                     "        }\n"
                     "    }\n"
                     "    for (int o = 0; o < COUT; ++o) result[at(o, p.y, p.x, outSize)] = "
                     "activate(acc[o]);\n"
                     "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0])}, name);
                break;
            }
            case GraphOp::MaxPool2d:
                s << prelude("maxpool2d '" + name + "'", 1, false) << "const int C = " << cout
                  << ", K = " << n.kernel << ", S = " << n.stride << ";\n"
                  << kMainStart
                  << "    for (int c = 0; c < C; ++c) {\n"
                     "        float m = -3.4e38;\n"
                     "        for (int ky = 0; ky < K; ++ky)\n"
                     "            for (int kx = 0; kx < K; ++kx)\n"
                     "                m = max(m, in0[at(c, p.y * S + ky, p.x * S + kx, inSize)]);\n"
                     "        result[at(c, p.y, p.x, outSize)] = m;\n"
                     "    }\n"
                     "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0])}, name);
                break;
            case GraphOp::Activation:
                s << prelude("activation '" + name + "'", 1, false) << activationFunction(n.activation)
                  << "const int C = " << cout << ";\n"
                  << kMainStart
                  << "    for (int c = 0; c < C; ++c)\n"
                     "        result[at(c, p.y, p.x, outSize)] = activate(in0[at(c, p.y, p.x, inSize)]);\n"
                     "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0])}, name);
                break;
            case GraphOp::Add:
                s << prelude("add '" + name + "'", 2, false) << "const int C = " << cout << ";\n"
                  << kMainStart
                  << "    for (int c = 0; c < C; ++c) {\n"
                     "        int i = at(c, p.y, p.x, outSize);\n"
                     "        result[i] = in0[i] + in1[i];\n"
                     "    }\n"
                     "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0]), inputName(n.inputs[1])}, name);
                break;
            case GraphOp::Concat:
            case GraphOp::Slice: {
                // Channel copies: a concatenation is one pass per input, each into its channels.
                std::vector<std::pair<int, int>> parts;  // (input index, destination offset)
                int offset = 0;
                if (n.op == GraphOp::Slice) {
                    parts.push_back({n.inputs[0], 0});
                } else {
                    for (int input : n.inputs) parts.push_back({input, offset}), offset += channelsOf(input);
                }
                int part = 0;
                for (const auto& [input, destination] : parts) {
                    const int from = n.op == GraphOp::Slice ? n.sliceFrom : 0;
                    const int count = n.op == GraphOp::Slice ? cout : channelsOf(input);
                    std::ostringstream c;
                    c << prelude(std::string(n.op == GraphOp::Slice ? "slice" : "concat") + " '" + name + "'",
                                 1, false)
                      << "const int FROM = " << from << ", COUNT = " << count << ", TO = " << destination
                      << ";\n"
                      << kMainStart
                      << "    for (int c = 0; c < COUNT; ++c)\n"
                         "        result[at(TO + c, p.y, p.x, outSize)] = in0[at(FROM + c, p.y, p.x, "
                         "inSize)];\n"
                         "}\n";
                    addPass(name + (parts.size() > 1 ? "_" + std::to_string(part++) : ""), c.str(),
                            {inputName(input)}, name);
                }
                break;
            }
            case GraphOp::Upsample:
                s << prelude(std::string(n.bilinear ? "bilinear" : "nearest") + " upsampling '" + name + "'",
                             1, false)
                  << "const int C = " << cout << ", F = " << n.factor << ";\n"
                  << kMainStart;
                if (n.bilinear)  // PyTorch's align_corners = false, the source clamped at 0
                    s << "    float sy = max((float(p.y) + 0.5) / float(F) - 0.5, 0.0);\n"
                         "    float sx = max((float(p.x) + 0.5) / float(F) - 0.5, 0.0);\n"
                         "    int y0 = min(int(sy), inSize.y - 1), x0 = min(int(sx), inSize.x - 1);\n"
                         "    int y1 = min(y0 + 1, inSize.y - 1), x1 = min(x0 + 1, inSize.x - 1);\n"
                         "    float wy = sy - float(y0), wx = sx - float(x0);\n"
                         "    for (int c = 0; c < C; ++c) {\n"
                         "        float top = mix(in0[at(c, y0, x0, inSize)], in0[at(c, y0, x1, inSize)], "
                         "wx);\n"
                         "        float bottom = mix(in0[at(c, y1, x0, inSize)], in0[at(c, y1, x1, inSize)], "
                         "wx);\n"
                         "        result[at(c, p.y, p.x, outSize)] = mix(top, bottom, wy);\n"
                         "    }\n"
                         "}\n";
                else
                    s << "    for (int c = 0; c < C; ++c)\n"
                         "        result[at(c, p.y, p.x, outSize)] = in0[at(c, p.y / F, p.x / F, inSize)];\n"
                         "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0])}, name);
                break;
            case GraphOp::PixelShuffle:
                s << prelude("pixel shuffle '" + name + "'", 1, false) << "const int C = " << cout
                  << ", F = " << n.factor << ";\n"
                  << kMainStart
                  << "    int sub = (p.y % F) * F + p.x % F;\n"
                     "    for (int c = 0; c < C; ++c)\n"
                     "        result[at(c, p.y, p.x, outSize)] = in0[at(c * F * F + sub, p.y / F, p.x / F, "
                     "inSize)];\n"
                     "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0])}, name);
                break;
            case GraphOp::KernelFilter: {
                const bool third = n.inputs.size() > 2;
                const int taps = n.kernel * n.kernel;
                s << prelude("kernel filter '" + name + "'", third ? 3 : 2, false) << "const int C = " << cout
                  << ", K = " << n.kernel << ", R = " << n.kernel / 2 << ", TAPS = " << taps
                  << ", T = " << taps + (third ? 1 : 0) << ";\n"
                  << "const float CENTRE_BIAS = " << glslFloat(n.centreBias) << ";\n"
                  << kMainStart
                  << "    // softmax of the logits, the centre's raised\n"
                     "    float w[T];\n"
                     "    float top = -3.4e38;\n"
                     "    for (int j = 0; j < T; ++j) {\n"
                     "        w[j] = in1[at(j, p.y, p.x, outSize)] + (j == TAPS / 2 ? CENTRE_BIAS : 0.0);\n"
                     "        top = max(top, w[j]);\n"
                     "    }\n"
                     "    float sum = 0.0;\n"
                     "    for (int j = 0; j < T; ++j) { w[j] = exp(w[j] - top); sum += w[j]; }\n"
                     "    for (int c = 0; c < C; ++c) {\n"
                     "        float acc = 0.0;\n"
                     "        for (int j = 0; j < TAPS; ++j) {\n"
                     "            int y = clamp(p.y + j / K - R, 0, inSize.y - 1);\n"
                     "            int x = clamp(p.x + j % K - R, 0, inSize.x - 1);\n"
                     "            acc += w[j] * in0[at(c, y, x, inSize)];\n"
                     "        }\n";
                if (third) s << "        acc += w[TAPS] * in2[at(c, p.y, p.x, outSize)];\n";
                s << "        result[at(c, p.y, p.x, outSize)] = acc / sum;\n"
                     "    }\n"
                     "}\n";
                std::vector<std::string> inputs = {inputName(n.inputs[0]), inputName(n.inputs[1])};
                if (third) inputs.push_back(inputName(n.inputs[2]));
                addPass(name, s.str(), inputs, name);
                break;
            }
            case GraphOp::Warp: {
                // The image read at (x - motion x, y - motion y) in index coordinates (nn/layers.h's warp):
                // bilinear 2 x 2, or the cubic convolution 4 x 4 (a = -0.5 Catmull-Rom, -0.75 bicubic),
                // each tap clamped to the image; a place that is not a number reads 0, a far one the border.
                const bool cubic = n.warpFilter != WarpFilter::Bilinear;
                const float a = n.warpFilter == WarpFilter::CatmullRom ? -0.5f : -0.75f;
                s << prelude("warp '" + name + "'", 2, false) << "const int C = " << cout
                  << ", TAPS = " << (cubic ? 4 : 2) << ";\n"
                  << "const float A = " << glslFloat(a) << ";\n"
                  << "float near(float t) { precise float v = ((A + 2.0) * t - (A + 3.0)) * t * t + 1.0; "
                     "return v; }\n"
                     "float far(float t) { precise float v = ((A * t - 5.0 * A) * t + 8.0 * A) * t - 4.0 * "
                     "A; "
                     "return v; }\n"
                     "float place(float s, float limit) { return isnan(s) ? 0.0 : clamp(s, -limit, 2.0 * "
                     "limit); "
                     "}\n"
                     "void taps(float s, out int first, out float w[4]) {\n"
                     "    precise float base = floor(s), f = s - base;\n"
                     "    if (TAPS == 2) {\n"
                     "        first = int(base);\n"
                     "        w[0] = 1.0 - f; w[1] = f; w[2] = 0.0; w[3] = 0.0;\n"
                     "    } else {\n"
                     "        first = int(base) - 1;\n"
                     "        w[0] = far(1.0 + f); w[1] = near(f); w[2] = near(1.0 - f); w[3] = far(2.0 - "
                     "f);\n"
                     "    }\n"
                     "}\n"
                  << kMainStart
                  << "    precise float sx = float(p.x) - in1[at(0, p.y, p.x, inSize)];\n"
                     "    precise float sy = float(p.y) - in1[at(1, p.y, p.x, inSize)];\n"
                     "    sx = place(sx, float(inSize.x + 2));\n"
                     "    sy = place(sy, float(inSize.y + 2));\n"
                     "    int fx, fy;\n"
                     "    float wx[4], wy[4];\n"
                     "    taps(sx, fx, wx);\n"
                     "    taps(sy, fy, wy);\n"
                     "    for (int c = 0; c < C; ++c) {\n"
                     "        precise float sum = 0.0;\n"
                     "        for (int j = 0; j < TAPS; ++j) {\n"
                     "            int y = clamp(fy + j, 0, inSize.y - 1);\n"
                     "            precise float row = 0.0;\n"
                     "            for (int i = 0; i < TAPS; ++i)\n"
                     "                row += wx[i] * in0[at(c, y, clamp(fx + i, 0, inSize.x - 1), inSize)];\n"
                     "            sum += wy[j] * row;\n"
                     "        }\n"
                     "        result[at(c, p.y, p.x, outSize)] = sum;\n"
                     "    }\n"
                     "}\n";
                addPass(name, s.str(), {inputName(n.inputs[0]), inputName(n.inputs[1])}, name);
                break;
            }
            case GraphOp::Accumulate: {
                // nn/layers.h's accumulatePixel: the frame's k x k softmax filter shown over the history's
                // kept mean by the trust, the mean kept with the frame's own sample, the confidence grown.
                const int image = channelsOf(n.inputs[0]), taps = n.kernel * n.kernel;
                s << prelude("accumulate '" + name + "'", 3, false) << "const int C = " << image
                  << ", K = " << n.kernel << ", R = " << n.kernel / 2 << ", TAPS = " << taps << ";\n"
                  << "const float N = " << glslFloat(n.maxCount) << ";\n"
                  << "const bool CLIP = " << (n.clip ? "true" : "false") << ";\n"
                  << "float decode(float v) {\n"
                     "    v = clamp(v, 0.0, 1.0);\n"
                     "    return v <= 0.04045 ? v / 12.92 : pow((v + 0.055) / 1.055, 2.4);\n"
                     "}\n"
                     "float encode(float x) {\n"
                     "    x = clamp(x, 0.0, 1.0);\n"
                     "    return x <= 0.0031308 ? x * 12.92 : 1.055 * pow(x, 1.0 / 2.4) - 0.055;\n"
                     "}\n"
                  << kMainStart
                  << "    float w[TAPS];\n"
                     "    int offset[TAPS];\n"
                     "    float top = -3.4e38;\n"
                     "    for (int j = 0; j < TAPS; ++j) {\n"
                     "        w[j] = in1[at(j, p.y, p.x, outSize)];\n"
                     "        top = max(top, w[j]);\n"
                     "    }\n"
                     "    float sum = 0.0;\n"
                     "    for (int j = 0; j < TAPS; ++j) { w[j] = exp(w[j] - top); sum += w[j]; }\n"
                     "    for (int j = 0; j < TAPS; ++j) {\n"
                     "        w[j] /= sum;\n"
                     "        offset[j] = clamp(p.y + j / K - R, 0, inSize.y - 1) * inSize.x +\n"
                     "                    clamp(p.x + j % K - R, 0, inSize.x - 1);\n"
                     "    }\n"
                     "    int plane = inSize.x * inSize.y, self = p.y * inSize.x + p.x;\n"
                     "    float maxConfidence = N / (N + 1.0);\n"
                     "    float s = clamp(in2[C * plane + self], 0.0, maxConfidence);\n"
                     "    float n = s / (1.0 - s);\n"
                     "    float rho = min(1.0, 2.0 / (1.0 + exp(-in1[TAPS * plane + self])));\n"
                     "    float m = rho * n, a = m / (1.0 + m);\n"
                     "    for (int c = 0; c < C; ++c) {\n"
                     "        float spatial = 0.0;\n"
                     "        for (int j = 0; j < TAPS; ++j) spatial += w[j] * in0[c * plane + offset[j]];\n"
                     "        float h = in2[c * plane + self];\n"
                     "        if (CLIP) {\n"
                     "            float lo = in0[c * plane + offset[0]], hi = lo;\n"
                     "            for (int j = 1; j < TAPS; ++j) {\n"
                     "                lo = min(lo, in0[c * plane + offset[j]]);\n"
                     "                hi = max(hi, in0[c * plane + offset[j]]);\n"
                     "            }\n"
                     "            h = clamp(h, decode(lo), decode(hi));\n"
                     "        }\n"
                     "        float filtered = decode(spatial), own = decode(in0[c * plane + self]);\n"
                     "        result[at(c, p.y, p.x, outSize)] = encode(filtered + a * (h - filtered));\n"
                     "        result[at(C + c, p.y, p.x, outSize)] = own + a * (h - own);\n"
                     "    }\n"
                     "    float next = min(1.0 + m, N);\n"
                     "    result[at(2 * C, p.y, p.x, outSize)] = next / (next + 1.0);\n"
                     "}\n";
                addPass(name, s.str(),
                        {inputName(n.inputs[0]), inputName(n.inputs[1]), inputName(n.inputs[2])}, name);
                break;
            }
            case GraphOp::Count:
                throw Error("model '" + model.name() + "': node '" + name + "' (" + graphOpName(n.op) +
                            ") has no GLSL form");
        }
    }
    net.output = names[size_t(model.outputNode())];
    return net;
}

void writeGlslNetwork(const std::string& folder, const GlslNetwork& network) {
    std::error_code error;
    fs::create_directories(folder, error);
    if (!fs::is_directory(folder)) throw Error("cannot write to the folder '" + folder + "'");
    for (const GlslPass& pass : network.passes)
        writeTextFileAtomically((fs::path(folder) / (pass.name + ".comp")).string(), pass.source);
    writeBytesAtomically((fs::path(folder) / "weights.bin").string(),
                         std::string_view(reinterpret_cast<const char*>(network.weights.data()),
                                          network.weights.size() * sizeof(float)));
    writeTextFileAtomically((fs::path(folder) / "network.json").string(),
                            network.description().dump(2) + "\n");
}

GlslNetwork readGlslNetwork(const std::string& folder) {
    const auto slurp = [&](const std::string& file) {
        const std::string path = (fs::path(folder) / file).string();
        std::ifstream in(path, std::ios::binary);
        if (!in) throw Error("cannot read '" + path + "'");
        std::stringstream text;
        text << in.rdbuf();
        return text.str();
    };
    const nlohmann::json j = nlohmann::json::parse(slurp("network.json"), nullptr, false);
    if (!j.is_object() || j.value("format", "") != "dejag-glsl-1")
        throw Error("'" + folder + "/network.json' is not a dejag GLSL network (format dejag-glsl-1)");
    GlslNetwork net;
    try {
        net.model = j.at("model").get<std::string>();
        net.architecture = j.at("architecture");
        net.inputChannels = j.at("input_channels").get<int>();
        net.outputChannels = j.at("output_channels").get<int>();
        net.sizeDivisor = j.at("size_divisor").get<int>();
        net.output = j.at("output").get<std::string>();
        for (const nlohmann::json& b : j.at("buffers"))
            net.buffers.push_back({b.at("name").get<std::string>(), b.at("channels").get<int>(),
                                   b.at("scale").at(0).get<int>(), b.at("scale").at(1).get<int>()});
        for (const nlohmann::json& p : j.at("passes")) {
            const std::string shader = p.at("shader").get<std::string>();
            net.passes.push_back({fs::path(shader).stem().string(), slurp(shader),
                                  p.at("inputs").get<std::vector<std::string>>(),
                                  p.at("output").get<std::string>()});
        }
    } catch (const nlohmann::json::exception& e) {
        throw Error("'" + folder + "/network.json': " + e.what());
    }
    const std::string bytes = slurp(j.value("weights", "weights.bin"));
    if (bytes.size() % sizeof(float) != 0) throw Error("'" + folder + "/weights.bin' is not whole floats");
    net.weights.resize(bytes.size() / sizeof(float));
    std::memcpy(net.weights.data(), bytes.data(), bytes.size());
    return net;
}

}  // namespace dejag::nn

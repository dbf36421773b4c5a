// dejag-bench-nn: dejag's convolution kernels side by side with oneDNN and libtorch, in one process.
// Run through `dejag bench nn` (or `make bench`). oneDNN and libtorch are linked here only, never into nn/.
//
// Every case runs each library at each thread count: one warm-up each, then --repeat rounds in which the
// FMA peak, dejag, oneDNN and libtorch run one after the other; each figure is the median over the
// rounds. Interleaving matters on this shared machine: a neighbour's load that comes and goes then
// slows every library alike, instead of whichever happened to be measuring. Each library works in its
// preferred layout (dejag: blocked with a zero border; oneDNN: the format it picks with format_tag::any;
// libtorch: NCHW), with layout conversions outside the timed region, and every library fuses bias and ReLU
// (libtorch: an in-place relu_ after the convolution, which is how a libtorch user would write it).
#include <sys/resource.h>
#include <unistd.h>

#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <functional>
#include <memory>
#include <nlohmann/json.hpp>
#include <optional>
#include <string>
#include <unordered_map>
#include <vector>

#include "base/error.h"
#include "base/peak.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "base/timer.h"
#include "nn/fast_conv.h"
#include "nn/inference.h"
#include "nn/init.h"
#include "nn/losses.h"
#include "nn/model.h"
#include "nn/optim.h"

#if DEJAG_HAVE_ONEDNN
#include <omp.h>
#include <dnnl.hpp>
#endif
#if DEJAG_HAVE_LIBTORCH
#include <torch/torch.h>
#endif

namespace {

using namespace dejag;
using namespace dejag::nn;

struct Case {
    std::string name;
    int64_t inChannels, outChannels, kernel, height, width;  // input size
    bool transposed = false;  // ConvTranspose2D, stride 2, padding 1, output padding 1 (doubles the size)
    int64_t macs() const { return inChannels * outChannels * kernel * kernel * height * width; }
};

// One library's work for a case, set up once (weights packed, buffers allocated); empty if the
// library is not built in.
using Runner = std::function<void()>;

struct Rounds {
    double peakGmacs = 0.0;       // median of the FMA peak measured in each round
    std::vector<double> medians;  // per runner, ms (0 for an empty runner)
};

Rounds runInterleaved(int repeat, const std::vector<Runner>& runners) {
    for (const Runner& run : runners)
        if (run) run();  // warm-up
    std::vector<std::vector<double>> times(runners.size());
    std::vector<double> peaks;
    for (int round = 0; round < repeat; ++round) {
        peaks.push_back(measureFmaPeak(60.0).gmacsTotal);
        for (size_t k = 0; k < runners.size(); ++k) {
            if (!runners[k]) continue;
            Stopwatch watch;
            runners[k]();
            times[k].push_back(watch.elapsedMs());
        }
    }
    Rounds r;
    r.peakGmacs = median(peaks);
    for (const std::vector<double>& t : times) r.medians.push_back(t.empty() ? 0.0 : median(t));
    return r;
}

void setAllThreads(int threads) {
    setThreadCount(threads);
#if DEJAG_HAVE_ONEDNN
    omp_set_num_threads(threads);
#endif
#if DEJAG_HAVE_LIBTORCH
    at::set_num_threads(threads);
#endif
}

Runner dejagRunner(const Case& c) {
    Rng rng(1);
    std::vector<float> weight(size_t(c.inChannels * c.outChannels * c.kernel * c.kernel)),
        bias(size_t(c.outChannels));
    for (float& w : weight) w = rng.uniform(-0.1f, 0.1f);
    for (float& b : bias) b = rng.uniform(-0.1f, 0.1f);
    // A layer reading the network's input (1-3 channels) reads it planar, as InferencePlan does.
    const int inputBlock = c.inChannels <= 4 ? 1 : 0;
    auto make = [&]() {
        if (c.transposed) {
            ConvTranspose2dDesc d;
            d.inChannels = c.inChannels, d.outChannels = c.outChannels, d.inHeight = c.height,
            d.inWidth = c.width;
            d.kernelHeight = d.kernelWidth = c.kernel;
            d.strideH = d.strideW = 2, d.padH = d.padW = 1, d.outputPaddingH = d.outputPaddingW = 1;
            return BlockedConv(d, weight.data(), bias.data(), ActivationDesc{Activation::ReLU}, inputBlock);
        }
        Conv2dDesc d;
        d.inChannels = c.inChannels, d.outChannels = c.outChannels, d.inHeight = c.height,
        d.inWidth = c.width;
        d.kernelHeight = d.kernelWidth = c.kernel;
        d.padTop = d.padBottom = d.padLeft = d.padRight = int(c.kernel / 2);
        return BlockedConv(d, weight.data(), bias.data(), ActivationDesc{Activation::ReLU}, inputBlock);
    };
    auto conv = std::make_shared<BlockedConv>(make());
    // A layer of 1-4 outputs writes them compactly (4 floats per pixel for 3 channels), as the
    // inference plan does for a network's last layer.
    if (conv->compactOutputBlock() > 0) conv->useCompactOutput();
    const int border = conv->requiredInputBorder();
    const BlockedShape inShape = conv->inputShape(border), outShape = conv->outputShape(border);
    auto in = std::make_shared<Tensor>(allocateBlocked(inShape));
    auto out = std::make_shared<Tensor>(allocateBlocked(outShape));
    std::vector<float> plain(size_t(c.inChannels * c.height * c.width));
    for (float& v : plain) v = rng.uniform(0.0f, 1.0f);
    toBlocked(in->data(), plain.data(), inShape);
    return [=] { conv->forward(out->data(), outShape, in->data(), inShape); };
}

Runner oneDnnRunner(const Case& c) {
#if DEJAG_HAVE_ONEDNN
    using namespace dnnl;
    using tag = memory::format_tag;
    using dt = memory::data_type;
    engine eng(engine::kind::cpu, 0);
    stream s(eng);
    const int64_t outH = c.transposed ? 2 * c.height : c.height, outW = c.transposed ? 2 * c.width : c.width;
    const memory::dims src{1, c.inChannels, c.height, c.width},
        wei{c.outChannels, c.inChannels, c.kernel, c.kernel};
    const memory::dims bia{c.outChannels}, dst{1, c.outChannels, outH, outW};
    const memory::dims strides{c.transposed ? 2 : 1, c.transposed ? 2 : 1};
    const memory::dims padLeft{c.kernel / 2, c.kernel / 2},
        padRight{c.transposed ? 0 : c.kernel / 2, c.transposed ? 0 : c.kernel / 2};
    const auto anySrc = memory::desc(src, dt::f32, tag::any), anyWei = memory::desc(wei, dt::f32, tag::any);
    const auto plainBias = memory::desc(bia, dt::f32, tag::x), anyDst = memory::desc(dst, dt::f32, tag::any);
    post_ops ops;
    ops.append_eltwise(1.0f, algorithm::eltwise_relu, 0.0f, 0.0f);
    primitive_attr attr;
    attr.set_post_ops(ops);
    primitive primitiveToRun;
    memory::desc srcDesc, weiDesc, biaDesc, dstDesc;
    if (c.transposed) {
        const auto desc =
            deconvolution_forward::desc(prop_kind::forward_inference, algorithm::deconvolution_direct, anySrc,
                                        anyWei, plainBias, anyDst, strides, padLeft, padRight);
        const auto pd = deconvolution_forward::primitive_desc(desc, attr, eng);
        srcDesc = pd.src_desc(), weiDesc = pd.weights_desc(), biaDesc = pd.bias_desc(),
        dstDesc = pd.dst_desc();
        primitiveToRun = deconvolution_forward(pd);
    } else {
        const auto desc =
            convolution_forward::desc(prop_kind::forward_inference, algorithm::convolution_auto, anySrc,
                                      anyWei, plainBias, anyDst, strides, padLeft, padRight);
        const auto pd = convolution_forward::primitive_desc(desc, attr, eng);
        srcDesc = pd.src_desc(), weiDesc = pd.weights_desc(), biaDesc = pd.bias_desc(),
        dstDesc = pd.dst_desc();
        primitiveToRun = convolution_forward(pd);
    }
    memory srcMem(srcDesc, eng), weiMem(weiDesc, eng), biaMem(biaDesc, eng), dstMem(dstDesc, eng);
    auto fill = [](memory& m, float value) {
        float* p = static_cast<float*>(m.get_data_handle());
        const size_t n = m.get_desc().get_size() / sizeof(float);
        for (size_t i = 0; i < n; ++i) p[i] = value * float(int(i % 13) - 6);
    };
    fill(srcMem, 0.05f), fill(weiMem, 0.01f), fill(biaMem, 0.01f);
    return [=]() mutable {
        primitiveToRun.execute(s, {{DNNL_ARG_SRC, srcMem},
                                   {DNNL_ARG_WEIGHTS, weiMem},
                                   {DNNL_ARG_BIAS, biaMem},
                                   {DNNL_ARG_DST, dstMem}});
        s.wait();
    };
#else
    (void)c;
    return {};
#endif
}

Runner libtorchRunner(const Case& c) {
#if DEJAG_HAVE_LIBTORCH
    torch::manual_seed(1);
    const auto x = torch::rand({1, c.inChannels, c.height, c.width});
    const auto b = torch::randn({c.outChannels}) * 0.1;
    if (c.transposed) {
        const auto w = torch::randn({c.inChannels, c.outChannels, c.kernel, c.kernel}) * 0.1;
        return [=] {
            torch::NoGradGuard noGrad;
            auto y = torch::conv_transpose2d(x, w, b, 2, 1, 1);
            torch::relu_(y);
        };
    }
    const auto w = torch::randn({c.outChannels, c.inChannels, c.kernel, c.kernel}) * 0.1;
    const int64_t padding = c.kernel / 2;
    return [=] {
        torch::NoGradGuard noGrad;
        auto y = torch::conv2d(x, w, b, 1, padding);
        torch::relu_(y);
    };
#else
    (void)c;
    return {};
#endif
}

// ---- Whole networks: seed2020 forward (inference plan) and one training step ----------------------

struct NetworkRunner {
    Runner run;
    double macs = 0.0;
    size_t arenaBytes = 0;
};

NetworkRunner seed2020ForwardRunner(int64_t size) {
    struct State {
        Model model = Model::builtin("seed2020");
        Tensor input;
        std::optional<InferencePlan> plan;
    };
    auto state = std::make_shared<State>();
    state->model.initialize(1);
    state->input = Tensor({1, 1, size, size});
    Rng rng(2);
    for (int64_t i = 0; i < state->input.numel(); ++i) state->input.data()[i] = rng.uniform();
    state->plan.emplace(state->model, state->input.shape());
    NetworkRunner r;
    r.run = [state] { state->plan->runUnchecked(state->input); };
    r.macs = double(state->plan->macs());
    r.arenaBytes = state->plan->arenaBytes();
    return r;
}

NetworkRunner seed2020TrainingStepRunner(int64_t batch, int64_t size) {
    struct State {
        Model model = Model::builtin("seed2020");
        Tensor input, target, dout;
        std::optional<Optimizer> optimizer;
        SsimLossDesc shape;
    };
    auto state = std::make_shared<State>();
    state->model.initialize(1);
    state->input = Tensor({batch, 1, size, size}), state->target = Tensor({batch, 1, size, size});
    Rng rng(3);
    for (int64_t i = 0; i < state->input.numel(); ++i)
        state->input.data()[i] = rng.uniform(), state->target.data()[i] = rng.uniform();
    state->optimizer.emplace(OptimizerConfig{}, state->model.parameterCount());
    state->shape = SsimLossDesc{batch, 1, size, size, 1.0};
    state->dout = Tensor({batch, 1, size, size});
    NetworkRunner r;
    r.run = [state] {
        State& m = *state;
        const Tensor& out = m.model.forward(m.input);
        m.dout.zero();
        ssimLossBackward(m.dout.data(), out.data(), m.target.data(), m.shape, 1.0);
        m.model.backward(m.dout);
        m.optimizer->step(m.model.parameterData(), m.model.gradientData(), 1e-3);
    };
    r.macs = 3.0 * double(state->model.macs(state->input.shape()));  // forward + input and weight gradients
    return r;
}

#if DEJAG_HAVE_ONEDNN
Runner oneDnnSeed2020Forward(int64_t size) {
    using namespace dnnl;
    using tag = memory::format_tag;
    using dt = memory::data_type;
    engine eng(engine::kind::cpu, 0);
    stream s(eng);
    std::vector<primitive> primitives;
    std::vector<std::unordered_map<int, memory>> arguments;
    memory current(memory::desc({1, 1, size, size}, dt::f32, tag::nchw), eng);
    std::fill_n(static_cast<float*>(current.get_data_handle()), size * size, 0.5f);
    int64_t channels = 1, height = size;
    auto fill = [](memory& m, float value) {
        float* p = static_cast<float*>(m.get_data_handle());
        for (size_t i = 0; i < m.get_desc().get_size() / sizeof(float); ++i)
            p[i] = value * float(int(i % 7) - 3);
    };
    auto addConv = [&](int64_t out, int64_t k, bool transposed, algorithm activation) {
        const int64_t outHeight = transposed ? height * 2 : height;
        const memory::dims wei{out, channels, k, k}, dst{1, out, outHeight, outHeight};
        const memory::dims strides{transposed ? 2 : 1, transposed ? 2 : 1}, padL{k / 2, k / 2};
        const memory::dims padR{transposed ? 0 : k / 2, transposed ? 0 : k / 2};
        post_ops ops;
        ops.append_eltwise(1.0f, activation, 0.0f, 0.0f);
        primitive_attr attr;
        attr.set_post_ops(ops);
        const auto weiAny = memory::desc(wei, dt::f32, tag::any), bias = memory::desc({out}, dt::f32, tag::x);
        const auto dstAny = memory::desc(dst, dt::f32, tag::any);
        memory::desc weiDesc, dstDesc;
        if (transposed) {
            const auto pd = deconvolution_forward::primitive_desc(
                deconvolution_forward::desc(prop_kind::forward_inference, algorithm::deconvolution_direct,
                                            current.get_desc(), weiAny, bias, dstAny, strides, padL, padR),
                attr, eng);
            weiDesc = pd.weights_desc(), dstDesc = pd.dst_desc();
            primitives.push_back(deconvolution_forward(pd));
        } else {
            const auto pd = convolution_forward::primitive_desc(
                convolution_forward::desc(prop_kind::forward_inference, algorithm::convolution_auto,
                                          current.get_desc(), weiAny, bias, dstAny, strides, padL, padR),
                attr, eng);
            weiDesc = pd.weights_desc(), dstDesc = pd.dst_desc();
            primitives.push_back(convolution_forward(pd));
        }
        memory w(weiDesc, eng), b(bias, eng), d(dstDesc, eng);
        fill(w, 0.01f), fill(b, 0.01f);
        arguments.push_back(
            {{DNNL_ARG_SRC, current}, {DNNL_ARG_WEIGHTS, w}, {DNNL_ARG_BIAS, b}, {DNNL_ARG_DST, d}});
        current = d, channels = out, height = outHeight;
    };
    auto addPool = [&]() {
        const memory::dims dst{1, channels, height / 2, height / 2};
        const auto pd = pooling_v2_forward::primitive_desc(
            pooling_v2_forward::desc(prop_kind::forward_inference, algorithm::pooling_max, current.get_desc(),
                                     memory::desc(dst, dt::f32, tag::any), {2, 2}, {2, 2}, {0, 0}, {0, 0},
                                     {0, 0}),
            eng);
        memory d(pd.dst_desc(), eng);
        primitives.push_back(pooling_v2_forward(pd));
        arguments.push_back({{DNNL_ARG_SRC, current}, {DNNL_ARG_DST, d}});
        current = d, height /= 2;
    };
    addConv(32, 5, false, algorithm::eltwise_relu);
    addConv(32, 3, false, algorithm::eltwise_relu);
    addPool();
    addConv(64, 1, false, algorithm::eltwise_relu);
    addPool();
    addConv(128, 3, false, algorithm::eltwise_relu);
    addConv(64, 3, true, algorithm::eltwise_relu);
    addConv(1, 3, true, algorithm::eltwise_logistic);
    return [=]() mutable {
        for (size_t i = 0; i < primitives.size(); ++i) primitives[i].execute(s, arguments[i]);
        s.wait();
    };
}
#endif

#if DEJAG_HAVE_LIBTORCH
torch::nn::Sequential torchSeed2020() {
    namespace tnn = torch::nn;
    return tnn::Sequential(
        tnn::Conv2d(tnn::Conv2dOptions(1, 32, 5).padding(2)), tnn::ReLU(),
        tnn::Conv2d(tnn::Conv2dOptions(32, 32, 3).padding(1)), tnn::ReLU(), tnn::MaxPool2d(2),
        tnn::Conv2d(tnn::Conv2dOptions(32, 64, 1)), tnn::ReLU(), tnn::MaxPool2d(2),
        tnn::Conv2d(tnn::Conv2dOptions(64, 128, 3).padding(1)), tnn::ReLU(),
        tnn::ConvTranspose2d(tnn::ConvTranspose2dOptions(128, 64, 3).stride(2).padding(1).output_padding(1)),
        tnn::ReLU(),
        tnn::ConvTranspose2d(tnn::ConvTranspose2dOptions(64, 1, 3).stride(2).padding(1).output_padding(1)),
        tnn::Sigmoid());
}

Runner libtorchSeed2020Forward(int64_t size) {
    auto net = torchSeed2020();
    net->eval();
    const auto x = torch::rand({1, 1, size, size});
    return [=]() mutable {
        torch::NoGradGuard noGrad;
        net->forward(x);
    };
}

torch::Tensor torchSsimLoss(const torch::Tensor& pred, const torch::Tensor& target) {
    auto g = torch::exp(-0.5 * torch::pow(torch::arange(11, torch::kFloat) - 5, 2) / (1.5 * 1.5));
    g = g / g.sum();
    const auto window = torch::outer(g, g).reshape({1, 1, 11, 11});
    auto f = [&](const torch::Tensor& t) { return torch::conv2d(t, window); };
    const auto mx = f(target), my = f(pred);
    const auto vx = f(target * target) - mx * mx, vy = f(pred * pred) - my * my,
               cxy = f(target * pred) - mx * my;
    const double c1 = 1e-4, c2 = 9e-4;
    return 1 - (((2 * mx * my + c1) * (2 * cxy + c2)) / ((mx * mx + my * my + c1) * (vx + vy + c2))).mean();
}

Runner libtorchSeed2020TrainingStep(int64_t batch, int64_t size) {
    auto net = torchSeed2020();
    net->train();
    auto adam = std::make_shared<torch::optim::Adam>(net->parameters(), torch::optim::AdamOptions(1e-3));
    const auto x = torch::rand({batch, 1, size, size}), y = torch::rand({batch, 1, size, size});
    return [=]() mutable {
        adam->zero_grad();
        torchSsimLoss(net->forward(x), y).backward();
        adam->step();
    };
}
#endif

}  // namespace

int main(int argc, char** argv) {
    // Idle OpenMP threads of the peers must sleep, not spin, or they steal the other core from the next
    // measurement. libgomp reads the policy when it loads, so set it and start again if it is missing.
    if (!std::getenv("OMP_WAIT_POLICY")) {
        ::setenv("OMP_WAIT_POLICY", "PASSIVE", 1);
        ::execv("/proc/self/exe", argv);
    }
    bool json = false;
    int repeat = 7;
    std::vector<int> threadCounts = {1, 2};
    std::string only;
    for (int i = 1; i < argc; ++i) {
        const std::string arg = argv[i];
        if (arg == "--json")
            json = true;
        else if (arg == "--repeat" && i + 1 < argc)
            repeat = std::max(1, std::atoi(argv[++i]));
        else if ((arg == "--thread-counts" || arg == "--threads") && i + 1 < argc) {
            // --thread-counts 1,2 sweeps; --threads N is one count (as everywhere in dejag).
            const std::string value = argv[++i];
            if (arg == "--threads" && value.find(',') != std::string::npos) {
                std::fprintf(stderr,
                             "dejag bench nn: --threads takes one count; sweep with --thread-counts %s\n",
                             value.c_str());
                return 2;
            }
            threadCounts.clear();
            for (char* t = std::strtok(argv[i], ","); t; t = std::strtok(nullptr, ","))
                threadCounts.push_back(std::max(1, std::atoi(t)));
        } else if (arg == "--case" && i + 1 < argc)
            only = argv[++i];
        else if (arg == "--help" || arg == "-h") {
            std::printf(
                "dejag bench nn [--json] [--repeat N] [--thread-counts 1,2 | --threads N] [--case NAME]\n"
                "dejag's fast convolution vs oneDNN and libtorch; median ms, GMAC/s, fraction of the\n"
                "measured FMA peak, and peer time / dejag time (above 1: dejag is faster).\n"
                "Example: dejag bench nn --case conv3x3 --threads 2\n");
            return 0;
        } else {
            std::fprintf(stderr, "dejag bench nn: unknown argument '%s' (see --help)\n", arg.c_str());
            return 2;
        }
    }
    const std::vector<Case> cases = {
        {"conv3x3 32->32 1920x1080", 32, 32, 3, 1080, 1920},
        {"conv3x3 3->16 1920x1080", 3, 16, 3, 1080, 1920},
        {"conv3x3 16->16 1920x1080", 16, 16, 3, 1080, 1920},
        {"conv3x3 16->3 1920x1080", 16, 3, 3, 1080, 1920},
        {"conv1x1 32->64 400x400", 32, 64, 1, 400, 400},
        {"conv5x5 1->32 800x800 (seed2020 conv1)", 1, 32, 5, 800, 800},
        {"convT3x3 s2 128->64 200x200", 128, 64, 3, 200, 200, true},
    };
    try {
        if (!json)
            std::printf("%-40s %3s %6s %9s %8s %7s | %9s %6s | %9s %6s\n", "case", "thr", "simd", "dejag ms",
                        "GMAC/s", "% peak", "oneDNN ms", "ratio", "torch ms", "ratio");
        for (const Case& c : cases) {
            if (!only.empty() && c.name.find(only) == std::string::npos) continue;
            const double macs =
                double(c.inChannels * c.outChannels * c.kernel * c.kernel * c.height * c.width);
            for (int threads : threadCounts) {
                setAllThreads(threads);
                const Rounds rounds =
                    runInterleaved(repeat, {dejagRunner(c), oneDnnRunner(c), libtorchRunner(c)});
                const double ours = rounds.medians[0], onednn = rounds.medians[1],
                             libtorch = rounds.medians[2];
                const FmaPeak peak{threads, activeSimdLevel(), rounds.peakGmacs, rounds.peakGmacs / threads};
                const double gmacs = macs / (ours * 1e6);
                nlohmann::json row = {
                    {"name", c.name},
                    {"threads", threads},
                    {"simd", simdLevelName(activeSimdLevel())},
                    {"ms", ours},
                    {"gmacs", gmacs},
                    {"peak_gmacs", peak.gmacsTotal},
                    {"peak_fraction", gmacs / peak.gmacsTotal},
                    {"onednn_ms", onednn > 0 ? nlohmann::json(onednn) : nlohmann::json(nullptr)},
                    {"onednn_ratio", onednn > 0 ? nlohmann::json(onednn / ours) : nlohmann::json(nullptr)},
                    {"libtorch_ms", libtorch > 0 ? nlohmann::json(libtorch) : nlohmann::json(nullptr)},
                    {"libtorch_ratio",
                     libtorch > 0 ? nlohmann::json(libtorch / ours) : nlohmann::json(nullptr)}};
                if (json) {
                    std::printf("%s\n", row.dump().c_str());
                } else {
                    std::printf("%-40s %3d %6s %9.2f %8.2f %6.1f%% | %9.2f %6.2f | %9.2f %6.2f\n",
                                c.name.c_str(), threads, simdLevelName(activeSimdLevel()), ours, gmacs,
                                100.0 * gmacs / peak.gmacsTotal, onednn, onednn > 0 ? onednn / ours : 0.0,
                                libtorch, libtorch > 0 ? libtorch / ours : 0.0);
                }
                std::fflush(stdout);
            }
        }
        struct NetworkCase {
            std::string name;
            bool training;
        };
        for (const NetworkCase& net : {NetworkCase{"seed2020 forward 1x1x800x800", false},
                                       NetworkCase{"seed2020 training step 8x1x128x128", true}}) {
            if (!only.empty() && net.name.find(only) == std::string::npos) continue;
            for (int threads : threadCounts) {
                setAllThreads(threads);
                const int netRepeat = net.training ? std::max(1, repeat / 2) : repeat;
                const NetworkRunner dejagNet =
                    net.training ? seed2020TrainingStepRunner(8, 128) : seed2020ForwardRunner(800);
                Runner onednnNet, libtorchNet;
#if DEJAG_HAVE_ONEDNN
                if (!net.training) onednnNet = oneDnnSeed2020Forward(800);  // no oneDNN training loop here
#endif
#if DEJAG_HAVE_LIBTORCH
                libtorchNet =
                    net.training ? libtorchSeed2020TrainingStep(8, 128) : libtorchSeed2020Forward(800);
#endif
                const Rounds rounds = runInterleaved(netRepeat, {dejagNet.run, onednnNet, libtorchNet});
                struct {
                    double ms, macs;
                    size_t arenaBytes;
                } ours{rounds.medians[0], dejagNet.macs, dejagNet.arenaBytes};
                const double onednn = rounds.medians[1], libtorch = rounds.medians[2];
                const FmaPeak peak{threads, activeSimdLevel(), rounds.peakGmacs, rounds.peakGmacs / threads};
                const double gmacs = ours.macs / (ours.ms * 1e6);
                nlohmann::json row = {
                    {"name", net.name},
                    {"threads", threads},
                    {"simd", simdLevelName(activeSimdLevel())},
                    {"ms", ours.ms},
                    {"gmacs", gmacs},
                    {"peak_gmacs", peak.gmacsTotal},
                    {"peak_fraction", gmacs / peak.gmacsTotal},
                    {"onednn_ms", onednn > 0 ? nlohmann::json(onednn) : nlohmann::json(nullptr)},
                    {"onednn_ratio", onednn > 0 ? nlohmann::json(onednn / ours.ms) : nlohmann::json(nullptr)},
                    {"libtorch_ms", libtorch > 0 ? nlohmann::json(libtorch) : nlohmann::json(nullptr)},
                    {"libtorch_ratio",
                     libtorch > 0 ? nlohmann::json(libtorch / ours.ms) : nlohmann::json(nullptr)}};
                if (ours.arenaBytes) row["arena_mb"] = double(ours.arenaBytes) / 1048576.0;
                if (json) {
                    std::printf("%s\n", row.dump().c_str());
                } else {
                    std::printf("%-40s %3d %6s %9.2f %8.2f %6.1f%% | %9.2f %6.2f | %9.2f %6.2f\n",
                                net.name.c_str(), threads, simdLevelName(activeSimdLevel()), ours.ms, gmacs,
                                100.0 * gmacs / peak.gmacsTotal, onednn, onednn > 0 ? onednn / ours.ms : 0.0,
                                libtorch, libtorch > 0 ? libtorch / ours.ms : 0.0);
                }
                std::fflush(stdout);
            }
        }
        struct rusage usage {};
        getrusage(RUSAGE_SELF, &usage);
        if (!json)
            std::printf("peak RSS of this process (all libraries): %.0f MB\n",
                        double(usage.ru_maxrss) / 1024.0);
        if (!json)
            std::printf(
                "ratio = peer ms / dejag ms (above 1: dejag is faster). Peak: measured fp32 FMA rate at that "
                "thread count.\n");
    } catch (const std::exception& e) {
        std::fprintf(stderr, "dejag bench nn: %s\n", e.what());
        return 2;
    }
    return 0;
}

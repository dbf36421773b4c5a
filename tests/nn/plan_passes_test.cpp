// The inference plan's passes (nn/plan_passes.h), each on small graphs made to fire it and on graphs
// one condition away from firing it. tests/nn/inference_test.cpp runs the plan they make against the
// reference forward.
#include "nn/plan_passes.h"

#include <gtest/gtest.h>

#include <algorithm>

#include "base/error.h"

namespace dejag::nn::plan {
namespace {

using nlohmann::json;

json conv(const std::string& name, const std::string& input, int outChannels, int kernel = 3, int stride = 1,
          const std::string& activation = "relu") {
    return {{"name", name},     {"op", "conv2d"},   {"inputs", {input}}, {"out_channels", outChannels},
            {"kernel", kernel}, {"stride", stride}, {"padding", "same"}, {"activation", activation}};
}
json node(const std::string& name, const std::string& op, const std::vector<std::string>& inputs) {
    return {{"name", name}, {"op", op}, {"inputs", inputs}};
}
Model modelOf(const json& nodes, int inputChannels, const std::string& output = "") {
    json a = {{"name", "t"}, {"input_channels", inputChannels}, {"nodes", nodes}};
    if (!output.empty()) a["output"] = output;
    Model m = Model::fromArchitecture(a);
    m.initialize(7);
    return m;
}
int indexOf(const PlanGraph& g, const std::string& name) {
    for (int i = 0; i < g.size(); ++i)
        if (g.node(i).name == name) return i;
    throw Error("no node " + name);
}

// A residual network: input + shuffle(conv(input)).
json residualNodes() {
    return json::array({conv("down", "input", 12, 3, 2), node("shuf", "pixel_shuffle", {"down"}),
                        node("sum", "add", {"input", "shuf"})});
}

TEST(PlanPasses, TheResidualOutputIsFusedWhenNothingElseReadsTheShuffle) {
    const Model model = modelOf(residualNodes(), 3);
    const PlanGraph g(model, {1, 3, 16, 20});
    const auto r = fuseResidualOutput(g);
    ASSERT_TRUE(r);
    EXPECT_EQ(r->add, indexOf(g, "sum"));
    EXPECT_EQ(r->shuffle, indexOf(g, "shuf"));
    EXPECT_EQ(r->source, indexOf(g, "down"));
    EXPECT_EQ(r->factor, 2);
    EXPECT_TRUE(planarInput(g, r, std::nullopt));
    EXPECT_FALSE(planarInput(g, std::nullopt, std::nullopt)) << "the add reads the input";

    // Not for a sum of the input and a convolution, nor with a second reader of the shuffle.
    const Model plain =
        modelOf(json::array({conv("same", "input", 3), node("sum", "add", {"input", "same"})}), 3);
    EXPECT_FALSE(fuseResidualOutput(PlanGraph(plain, {1, 3, 16, 20})));
    json shared = residualNodes();
    shared.push_back(node("also", "activation", {"shuf"}));
    shared.back()["activation"] = "relu";
    const Model second = modelOf(shared, 3, "sum");
    EXPECT_FALSE(fuseResidualOutput(PlanGraph(second, {1, 3, 16, 20})));
}

// A kernel-predicting network: kernel_filter(input, shuffle(head(features(input)))).
json kernelNodes(int taps = 9, const std::string& headActivation = "none") {
    json nodes = json::array(
        {conv("features", "input", 8, 3, 2), conv("head", "features", taps * 4, 1, 1, headActivation),
         node("shuf", "pixel_shuffle", {"head"}), node("kf", "kernel_filter", {"input", "shuf"})});
    nodes[3]["kernel"] = taps == 25 ? 5 : 3;
    return nodes;
}

TEST(PlanPasses, TheKernelOutputAndItsHeadAreFusedWithTheHeadsWeightsByRowPhase) {
    const Model model = modelOf(kernelNodes(), 3);
    const PlanGraph g(model, {1, 3, 16, 20});
    auto k = fuseKernelOutput(g);
    ASSERT_TRUE(k);
    EXPECT_EQ(k->filter, indexOf(g, "kf"));
    EXPECT_EQ(k->source, indexOf(g, "head"));
    EXPECT_EQ(k->desc.taps(), 9);
    EXPECT_EQ(k->features, -1) << "fuseKernelHead decides the head";
    fuseKernelHead(g, *k);
    ASSERT_EQ(k->features, indexOf(g, "features"));
    ASSERT_EQ(k->featureChannels, 8);
    // Slot (py taps + j) f + px holds logit channel (j f + py) f + px: the pixel shuffle's order.
    const GraphNode& head = g.node(indexOf(g, "head"));
    const int f = 2, taps = 9, cin = 8;
    for (int py = 0; py < f; ++py)
        for (int j = 0; j < taps; ++j)
            for (int px = 0; px < f; ++px) {
                const int channel = (j * f + py) * f + px, slot = (py * taps + j) * f + px;
                for (int c = 0; c < cin; ++c)
                    ASSERT_EQ(k->headWeights[size_t(slot * cin + c)],
                              g.params[head.weightOffset + channel * cin + c]);
                ASSERT_EQ(k->headBias[size_t(slot)], g.params[head.biasOffset + channel]);
            }
    EXPECT_TRUE(planarInput(g, std::nullopt, k));

    // An activation on the head keeps it a layer of its own; more than 4 input channels, the stage.
    const Model activated = modelOf(kernelNodes(9, "relu"), 3);
    const PlanGraph ga(activated, {1, 3, 16, 20});
    auto ka = fuseKernelOutput(ga);
    ASSERT_TRUE(ka);
    fuseKernelHead(ga, *ka);
    EXPECT_EQ(ka->features, -1);
    const Model wide = modelOf(kernelNodes(), 5);
    EXPECT_FALSE(fuseKernelOutput(PlanGraph(wide, {1, 5, 16, 20})));
    EXPECT_FALSE(planarInput(PlanGraph(wide, {1, 5, 16, 20}), std::nullopt, std::nullopt));
}

// An input read by convolutions only is planar up to 16 channels (a temporal network's trunk takes 13 to
// 15), blocked beyond.
TEST(PlanPasses, AnInputOfUpTo16ChannelsReadByConvolutionsIsPlanar) {
    const json nodes = json::array({conv("down", "input", 8, 3, 2), conv("more", "down", 4)});
    for (int channels : {3, 13, 16})
        EXPECT_TRUE(planarInput(PlanGraph(modelOf(nodes, channels), {1, channels, 16, 20}), std::nullopt,
                                std::nullopt))
            << channels;
    EXPECT_FALSE(planarInput(PlanGraph(modelOf(nodes, 17), {1, 17, 16, 20}), std::nullopt, std::nullopt));
}

// A U-Net's last level: concat(encoder, shuffle(coarse)) read by a convolution.
json concatNodes(bool convFirst, bool encoderAlsoPooled = false) {
    json nodes = json::array({conv("enc", "input", 8), conv("down", "enc", 8, 3, 2),
                              conv("up", "down", 16, 1), node("shuf", "pixel_shuffle", {"up"})});
    nodes.push_back(
        node("cat", "concat",
             convFirst ? std::vector<std::string>{"enc", "shuf"} : std::vector<std::string>{"shuf", "enc"}));
    nodes.push_back(conv("out", "cat", 3, 3, 1, "none"));
    if (encoderAlsoPooled) {
        nodes.push_back(node("pool", "maxpool2d", {"enc"}));
        nodes.push_back(node("small", "upsample", {"pool"}));
        nodes.push_back(node("res", "concat", {"out", "small"}));
    }
    return nodes;
}

TEST(PlanPasses, AConcatenationOfAConvAndAShuffleIsWrittenInPlace) {
    for (const bool convFirst : {true, false}) {
        const Model model = modelOf(concatNodes(convFirst), 3);
        const PlanGraph g(model, {1, 3, 12, 16});
        const std::vector<ConcatInPlace> found = concatInPlace(g);
        ASSERT_EQ(found.size(), 1u) << "conv first: " << convFirst;
        const ConcatInPlace& c = found[0];
        EXPECT_EQ(c.concat, indexOf(g, "cat"));
        EXPECT_EQ(c.conv, indexOf(g, "enc"));
        EXPECT_EQ(c.shuffle, indexOf(g, "shuf"));
        EXPECT_EQ(c.laneOffset, 8);
        ASSERT_EQ(c.lane.size(), 12u);
        for (int64_t ch = 0; ch < 12; ++ch) {  // the conv's channels first in the buffer
            const int64_t want = convFirst ? ch : ch < 4 ? 8 + ch : ch - 4;
            EXPECT_EQ(c.lane[size_t(ch)], want) << "channel " << ch;
        }
        // The reader's weights follow: its weight for channel ch is at lane[ch].
        const int out = indexOf(g, "out");
        const std::vector<float> w = permutedWeights(g, c, out);
        const float* original = g.params + g.node(out).weightOffset;
        for (int64_t o = 0; o < 3; ++o)
            for (int64_t ch = 0; ch < 12; ++ch)
                for (int64_t t = 0; t < 9; ++t)
                    ASSERT_EQ(w[size_t((o * 12 + c.lane[size_t(ch)]) * 9 + t)],
                              original[(o * 12 + ch) * 9 + t]);
    }
    // Not for two images, nor when something other than a convolution reads the encoder.
    const Model model = modelOf(concatNodes(true), 3);
    EXPECT_TRUE(concatInPlace(PlanGraph(model, {2, 3, 12, 16})).empty());
    const Model pooled = modelOf(concatNodes(true, true), 3);
    EXPECT_TRUE(concatInPlace(PlanGraph(pooled, {1, 3, 12, 16})).empty());
}

TEST(PlanPasses, ATwoByTwoPoolingIsFusedIntoItsOnlyConvolution) {
    json nodes = json::array({conv("a", "input", 8), node("pool", "maxpool2d", {"a"}), conv("b", "pool", 8)});
    const Model model = modelOf(nodes, 3);
    const PlanGraph g(model, {1, 3, 12, 16});
    const std::vector<PoolFusion> found = fusePooling(g);
    ASSERT_EQ(found.size(), 1u);
    EXPECT_EQ(found[0].conv, indexOf(g, "a"));
    EXPECT_EQ(found[0].pool, indexOf(g, "pool"));

    json three = nodes;
    three[1]["kernel"] = 3;
    const Model wide = modelOf(three, 3);
    EXPECT_TRUE(fusePooling(PlanGraph(wide, {1, 3, 12, 16})).empty()) << "a 3x3 pooling";
    json shared = nodes;
    shared.push_back(node("up", "upsample", {"b"}));
    shared.push_back(node("cat", "concat", {"up", "a"}));
    const Model twoReaders = modelOf(shared, 3);
    EXPECT_TRUE(fusePooling(PlanGraph(twoReaders, {1, 3, 12, 16})).empty()) << "a conv read twice";
    json overlapping = nodes;
    overlapping[1]["stride"] = 1;
    const Model strided = modelOf(overlapping, 3);
    EXPECT_TRUE(fusePooling(PlanGraph(strided, {1, 3, 12, 16})).empty()) << "a stride of 1";
}

TEST(PlanPasses, PrecisionMakesBf16OnlyWhatEveryWriterAndReaderCanTake) {
    // a -> b -> c -> out, and an activation reading b.
    json nodes =
        json::array({conv("a", "input", 8), conv("b", "a", 8), conv("c", "b", 8), conv("out", "c", 3)});
    const Model model = modelOf(nodes, 3);
    const PlanGraph g(model, {1, 3, 8, 8});
    std::vector<NodePlan> plans(4);
    std::vector<NodeKernel> all(4, NodeKernel{true, true});
    Precision p = assignPrecision(g, plans, all, {g.output});
    EXPECT_EQ(std::vector<char>(p.bf16Buffer), (std::vector<char>{1, 1, 1, 0}));
    EXPECT_EQ(p.bf16Activations, 3);
    EXPECT_FALSE(plans[0].inBf16) << "the input stays float";
    EXPECT_TRUE(plans[1].inBf16 && plans[1].outBf16);
    EXPECT_TRUE(plans[3].inBf16 && !plans[3].outBf16);

    // c cannot read bf16: b stays float; a cannot write it: a stays float.
    std::vector<NodePlan> plans2(4);
    std::vector<NodeKernel> some = all;
    some[2].canReadBf16 = false;
    some[0].canWriteBf16 = false;
    p = assignPrecision(g, plans2, some, {g.output});
    EXPECT_EQ(std::vector<char>(p.bf16Buffer), (std::vector<char>{0, 0, 1, 0}));
    EXPECT_EQ(p.bf16Activations, 1);
    EXPECT_FALSE(plans2[1].inBf16);

    // A buffer the caller keeps float (an output stage's source) stays float.
    std::vector<NodePlan> plans3(4);
    p = assignPrecision(g, plans3, all, {g.output, 1});
    EXPECT_EQ(std::vector<char>(p.bf16Buffer), (std::vector<char>{1, 0, 1, 0}));
}

TEST(PlanPasses, TheArenaReusesWhatIsDeadAndNeverOverlapsWhatIsAlive) {
    // a dies at 1, so c (born 2) takes its place; b is alive next to both.
    const ArenaPlan p = placeFirstFit({{100, 0, 1}, {50, 1, 2}, {100, 2, 3}, {10, 3, 3}});
    ASSERT_EQ(p.offsets.size(), 4u);
    EXPECT_EQ(p.offsets[0], 0);
    EXPECT_EQ(p.offsets[1], 112) << "64-byte aligned";
    EXPECT_EQ(p.offsets[2], 0);
    EXPECT_EQ(p.offsets[3], 112) << "b died at 2";
    EXPECT_EQ(p.floats, 176);
    EXPECT_EQ(p.unpackedFloats, 112 + 64 + 112 + 16);

    // On whole networks: no two tensors alive at one step share a float.
    for (const Model& model :
         {Model::builtin("seed2020"), Model::builtin("kpn", {8, 3}), Model::builtin("fast")}) {
        const Shape input{1, model.inputChannels(), 32, 48};
        const PlanGraph g(model, input);
        std::vector<NodePlan> nodes(size_t(g.size()));
        for (const ConcatInPlace& c : concatInPlace(g)) {
            nodes[size_t(c.conv)].concatBuffer = nodes[size_t(c.shuffle)].concatBuffer = c.concat;
            nodes[size_t(c.concat)].concatInPlace = true;
        }
        for (const PoolFusion& f : fusePooling(g)) {
            nodes[size_t(f.conv)].pooledInto = f.pool;
            nodes[size_t(f.pool)].fusedIntoConv = true;
        }
        std::vector<int64_t> floats{input[0] * input[1] * input[2] * input[3]};
        for (const Shape& s : g.shapes) floats.push_back(s[0] * s[1] * s[2] * s[3]);
        const ArenaTensors t = arenaTensors(g, nodes, floats, {g.output});
        const ArenaPlan a = placeFirstFit(t.tensors);
        EXPECT_LT(a.floats, a.unpackedFloats) << model.name() << ": something is reused";
        for (size_t i = 0; i < t.tensors.size(); ++i)
            for (size_t j = i + 1; j < t.tensors.size(); ++j) {
                const ArenaTensor &x = t.tensors[i], &y = t.tensors[j];
                const bool alive = x.born <= y.dies && y.born <= x.dies;
                const bool overlap =
                    a.offsets[i] < a.offsets[j] + y.floats && a.offsets[j] < a.offsets[i] + x.floats;
                ASSERT_FALSE(alive && overlap)
                    << model.name() << ": buffers " << t.buffer[i] << " and " << t.buffer[j];
            }
        // Every stored buffer placed once: a pooled conv's is its pooling's, a concatenation's inputs' the
        // concatenation's.
        for (int i = 0; i < g.size(); ++i) {
            const NodePlan& n = nodes[size_t(i)];
            if (n.fusedIntoConv || n.concatInPlace || (n.concatBuffer >= 0 && g.opOf(i) != GraphOp::Conv2d))
                continue;
            EXPECT_EQ(std::count(t.buffer.begin(), t.buffer.end(), bufferOf(nodes, i)), 1)
                << model.name() << " node " << g.node(i).name;
        }
    }
}

}  // namespace
}  // namespace dejag::nn::plan

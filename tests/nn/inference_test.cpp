// The inference plan (blocked layout, fast kernels, one arena) against the reference Model::forward, on
// every SIMD path; no allocation per run.
#include "nn/inference.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <mutex>

#include "base/error.h"
#include "base/random.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/init.h"
#include "nn/kernel_filter_kernels.h"
#include "nn/layers.h"
#include "tests/alloc_counter.h"
#include "tests/test_util.h"

namespace dejag::nn {
namespace {

Tensor randomTensor(const Shape& shape, uint64_t seed) {
    Tensor t(shape);
    Rng rng(seed);
    for (int64_t i = 0; i < t.numel(); ++i) t.data()[i] = rng.uniform(0.0f, 1.0f);
    return t;
}

// Every op, with strides, paddings, a skip connection and unfused activations.
nlohmann::json everyOpArchitecture() {
    using nlohmann::json;
    json nodes = json::array();
    nodes.push_back({{"name", "a"},
                     {"op", "conv2d"},
                     {"inputs", {"input"}},
                     {"out_channels", 20},
                     {"kernel", 3},
                     {"padding", "same"},
                     {"activation", "leaky_relu"},
                     {"slope", 0.1}});
    nodes.push_back({{"name", "down"},
                     {"op", "conv2d"},
                     {"inputs", {"a"}},
                     {"out_channels", 18},
                     {"kernel", 3},
                     {"stride", 2},
                     {"padding", "same"},
                     {"activation", "relu"}});
    nodes.push_back({{"name", "pool"}, {"op", "maxpool2d"}, {"inputs", {"a"}}, {"kernel", 2}});
    nodes.push_back({{"name", "cat"}, {"op", "concat"}, {"inputs", {"down", "pool"}}});
    nodes.push_back({{"name", "v"},
                     {"op", "conv2d"},
                     {"inputs", {"cat"}},
                     {"out_channels", 12},
                     {"kernel", 5},
                     {"padding", 2},
                     {"activation", "clamp"},
                     {"low", -0.2},
                     {"high", 0.8}});
    nodes.push_back({{"name", "up"},
                     {"op", "conv_transpose2d"},
                     {"inputs", {"v"}},
                     {"out_channels", 20},
                     {"kernel", 3},
                     {"stride", 2},
                     {"padding", 1},
                     {"output_padding", 1}});
    nodes.push_back({{"name", "skip"}, {"op", "add"}, {"inputs", {"up", "a"}}});
    nodes.push_back({{"name", "near"}, {"op", "upsample"}, {"inputs", {"v"}}, {"mode", "nearest"}});
    nodes.push_back({{"name", "bil"}, {"op", "upsample"}, {"inputs", {"v"}}, {"mode", "bilinear"}});
    nodes.push_back(
        {{"name", "sub"}, {"op", "conv2d"}, {"inputs", {"v"}}, {"out_channels", 8}, {"kernel", 1}});
    nodes.push_back({{"name", "shuf"}, {"op", "pixel_shuffle"}, {"inputs", {"sub"}}});
    nodes.push_back(
        {{"name", "taps"}, {"op", "conv2d"}, {"inputs", {"v"}}, {"out_channels", 9}, {"kernel", 1}});
    nodes.push_back(
        {{"name", "kf"}, {"op", "kernel_filter"}, {"inputs", {"v", "taps"}}, {"centre_bias", 1.5}});
    nodes.push_back({{"name", "kfup"}, {"op", "upsample"}, {"inputs", {"kf"}}, {"mode", "nearest"}});
    nodes.push_back({{"name", "all"}, {"op", "concat"}, {"inputs", {"skip", "near", "bil", "shuf", "kfup"}}});
    nodes.push_back({{"name", "out"},
                     {"op", "conv2d"},
                     {"inputs", {"all"}},
                     {"out_channels", 3},
                     {"kernel", 3},
                     {"padding", "same"},
                     {"activation", "sigmoid"}});
    return {{"name", "every_op"}, {"input_channels", 3}, {"nodes", nodes}};
}

class Inference : public testing::SimdLevelTest {};

// Output rows handed over by runInPlace(), kept as a tensor; each row's deliveries counted.
struct CollectedRows final : OutputRowSink {
    Tensor rows;
    std::vector<int> deliveries;  // per (image, row)
    explicit CollectedRows(const Shape& shape) : rows(shape), deliveries(size_t(shape[0] * shape[2])) {}
    void row(int64_t n, int64_t y, const float* const* channels) override {
        const int64_t C = rows.shape()[1], H = rows.shape()[2], W = rows.shape()[3];
        for (int64_t c = 0; c < C; ++c) std::copy_n(channels[c], W, rows.data() + ((n * C + c) * H + y) * W);
        ++deliveries[size_t(n * H + y)];  // rows come once each: no two threads share an element
    }
    // Asks for the rows as the plan holds them (OutputRowSink::takesStridedRows).
    bool strided = false;
    bool takesStridedRows() const override { return strided; }
    void rowStrided(int64_t n, int64_t y, const float* const* channels, int64_t stride) override {
        const int64_t C = rows.shape()[1], H = rows.shape()[2], W = rows.shape()[3];
        for (int64_t c = 0; c < C; ++c)
            for (int64_t x = 0; x < W; ++x)
                rows.data()[((n * C + c) * H + y) * W + x] = channels[c][x * stride];
        ++deliveries[size_t(n * H + y)];
    }
};

// The rows [first, last) of every image equal want's bit for bit, each delivered once; no other row.
void expectRowsMatch(const CollectedRows& got, const Tensor& want, int64_t first, int64_t last) {
    const Shape& o = want.shape();
    for (int64_t n = 0; n < o[0]; ++n)
        for (int64_t y = 0; y < o[2]; ++y) {
            const bool wanted = y >= first && y < last;
            ASSERT_EQ(got.deliveries[size_t(n * o[2] + y)], wanted ? 1 : 0) << "image " << n << " row " << y;
            for (int64_t c = 0; wanted && c < o[1]; ++c)
                for (int64_t x = 0; x < o[3]; ++x) {
                    const int64_t i = ((n * o[1] + c) * o[2] + y) * o[3] + x;
                    ASSERT_EQ(got.rows.data()[i], want.data()[i])
                        << "image " << n << " channel " << c << " row " << y << " column " << x;
                }
        }
}

// A tensor's rows as a streamed input, counting the rows asked for.
struct TensorRows final : InputRowSource {
    const Tensor* input = nullptr;
    std::vector<int> asked;  // per row (several threads: counted under a lock)
    std::mutex lock;
    explicit TensorRows(const Tensor& t) : input(&t), asked(size_t(t.shape()[2]), 0) {}
    void row(int64_t n, int64_t y, float* const* channels) override {
        const Shape& s = input->shape();
        for (int64_t c = 0; c < s[1]; ++c)
            std::copy_n(input->data() + ((n * s[1] + c) * s[2] + y) * s[3], s[3], channels[c]);
        std::lock_guard<std::mutex> hold(lock);
        ++asked[size_t(y)];
    }
};

// The input written through inputRow() and the rows [first, last) taken from runInPlace(), and the same
// rows of runStreamed() (where the plan can stream its input), equal run()'s
// bit for bit; every other row is left out, each wanted one comes once.
void expectInPlaceRunMatchesRun(InferencePlan& plan, const Tensor& input, int64_t first, int64_t last) {
    const Tensor want = plan.run(input).clone();
    const Shape& s = input.shape();
    auto writeInput = [&] {  // (a run may reuse the input's memory)
        for (int64_t n = 0; n < s[0]; ++n)
            for (int64_t c = 0; c < s[1]; ++c)
                for (int64_t y = 0; y < s[2]; ++y)
                    std::copy_n(input.data() + ((n * s[1] + c) * s[2] + y) * s[3], s[3],
                                plan.inputRow(n, c, y));
    };
    writeInput();
    CollectedRows inPlace(want.shape());
    plan.runInPlace(inPlace, first, last);
    expectRowsMatch(inPlace, want, first, last);
    // A sink taking the rows as the plan holds them gets the same values.
    writeInput();
    CollectedRows stridedRows(want.shape());
    stridedRows.strided = true;
    plan.runInPlace(stridedRows, first, last);
    expectRowsMatch(stridedRows, want, first, last);
    // Streamed (the input's rows asked for as the first layers and the output stage need them).
    TensorRows source(input);
    if (plan.canStreamInput()) {
        CollectedRows streamed(want.shape());
        plan.runStreamed(source, streamed, first, last);
        expectRowsMatch(streamed, want, first, last);
        for (int64_t y = 0; y < s[2]; ++y) EXPECT_GT(source.asked[size_t(y)], 0) << "input row " << y;
        // With pass-through (a kernel-predicting network's; others ignore it) over a flat left part: the
        // marks streamed from the first layer's bands — and, for rows no band holds (a stride-3 first
        // layer skips the last), from the source — give run()'s rows.
        Tensor flatLeft = input.clone();
        for (int64_t c = 0; c < s[1]; ++c)
            for (int64_t y = 0; y < s[2]; ++y)
                std::fill_n(flatLeft.data() + (c * s[2] + y) * s[3], std::min<int64_t>(s[3], 34),
                            0.25f + 0.1f * float(c));
        plan.setPassThrough(1.0f / 1024);
        const Tensor passed = plan.run(flatLeft).clone();
        TensorRows flatSource(flatLeft);
        CollectedRows streamedPassed(want.shape());
        plan.runStreamed(flatSource, streamedPassed, first, last);
        expectRowsMatch(streamedPassed, passed, first, last);
        plan.setPassThrough(0.0f);
    } else {
        EXPECT_THROW(plan.runStreamed(source, inPlace, first, last), Error);
    }
}

void expectPlanMatchesReference(Model& model, const Shape& shape) {
    model.initialize(11);
    // Biases start at zero; non-zero ones check that every fused path adds them.
    uint64_t state = 13;
    for (const ParameterInfo& p : model.parameters())
        if (p.isBias)
            for (int64_t i = p.offset; i < p.offset + shapeNumel(p.shape); ++i)
                model.parameterData()[i] = float(unitInterval(state = splitMix64(state), -0.5, 0.5));
    const Tensor input = randomTensor(shape, 12);
    const Tensor want = model.forward(input).clone();
    InferencePlan plan(model, shape);
    const Tensor& got = plan.run(input);
    ASSERT_EQ(got.shape(), want.shape());
    double worst = 0.0, scale = 1e-6;
    for (int64_t i = 0; i < want.numel(); ++i) {
        worst = std::max(worst, double(std::abs(got.data()[i] - want.data()[i])));
        scale = std::max(scale, double(std::abs(want.data()[i])));
    }
    EXPECT_LE(worst / scale, 1e-5) << model.name();
    expectInPlaceRunMatchesRun(plan, input, 1, shape[2] - 1);
}

TEST_P(Inference, Seed2020MatchesTheReference) {
    Model model = Model::builtin("seed2020");
    expectPlanMatchesReference(model, {2, 1, 32, 28});
}

TEST_P(Inference, FastFamilyMatchesTheReference) {
    Model model = Model::builtin("fast");
    expectPlanMatchesReference(model, {1, 3, 40, 32});
}

TEST_P(Inference, KpnFamilyMatchesTheReference) {
    Model model = Model::builtin("kpn");
    expectPlanMatchesReference(model, {1, 3, 40, 32});
    Model narrow = Model::builtin("kpn", {8, 2, 3});
    expectPlanMatchesReference(narrow, {2, 3, 20, 28});
    expectPlanMatchesReference(narrow, {1, 3, 4, 8});  // narrower than a vector: the edge path only
    // dejag-fast's architecture, wide enough for the fused head's vector path on every level (40
    // half-resolution pixels: two vectors of 16 and a tail on AVX-512, whose 8 features per pixel are
    // read by transposes).
    Model fast = Model::builtin("kpn", {8, 3});
    expectPlanMatchesReference(fast, {1, 3, 16, 80});
    // With a guide beside the frame (channels 3..5, the blend's tenth weight): fused and streamed too.
    ModelOptions guidedOptions;
    guidedOptions.width = 8, guidedOptions.guide = true;
    Model guided = Model::builtin("kpn", guidedOptions);
    expectPlanMatchesReference(guided, {1, 6, 16, 80});
    expectPlanMatchesReference(guided, {2, 6, 24, 40});
    EXPECT_TRUE(InferencePlan(guided, {1, 6, 16, 80}).canStreamInput());
    // The output stage with a 5x5 kernel, a factor of 3 and a width that is no multiple of a vector.
    using nlohmann::json;
    const json nodes =
        json::array({{{"name", "down"},
                      {"op", "conv2d"},
                      {"inputs", {"input"}},
                      {"out_channels", 8},
                      {"kernel", 3},
                      {"stride", 3},
                      {"padding", "same"},
                      {"activation", "relu"}},
                     {{"name", "taps"},
                      {"op", "conv2d"},
                      {"inputs", {"down"}},
                      {"out_channels", 9 * 25},
                      {"kernel", 1},
                      {"init_scale", 8.0}},
                     {{"name", "shuffle"}, {"op", "pixel_shuffle"}, {"inputs", {"taps"}}, {"factor", 3}},
                     {{"name", "filter"},
                      {"op", "kernel_filter"},
                      {"inputs", {"input", "shuffle"}},
                      {"kernel", 5},
                      {"centre_bias", -1.0}}});
    Model wide = Model::fromArchitecture({{"name", "k5"}, {"input_channels", 2}, {"nodes", nodes}});
    expectPlanMatchesReference(wide, {2, 2, 21, 39});
    // One image (streamed), its first layer a 1x1 of stride 2 that reads only every other row.
    json sparse = nodes;
    sparse[0]["kernel"] = 1, sparse[0]["stride"] = 2, sparse[1]["out_channels"] = 4 * 25;
    sparse[2]["factor"] = 2;
    Model skipping = Model::fromArchitecture({{"name", "k5s"}, {"input_channels", 2}, {"nodes", sparse}});
    expectPlanMatchesReference(skipping, {1, 2, 22, 40});
}

TEST_P(Inference, EveryOpMatchesTheReference) {
    Model model = Model::fromArchitecture(everyOpArchitecture());
    expectPlanMatchesReference(model, {2, 3, 20, 24});
}

// Pass-through (setPassThrough): a kpn's pixels in groups of 32 columns whose 3x3 neighbourhoods span at
// most `span` in every channel are the input bit for bit — the groups found independently here — and
// every other pixel is run()'s without it; where a pixel is passed, the filter would have moved it by no
// more than span (its output is a convex combination of the neighbourhood). A NaN is never passed.
TEST_P(Inference, KpnPassesFlatGroupsThrough) {
    Model model = Model::builtin("kpn", {8, 3});
    model.initialize(31);
    const int64_t C = 3, H = 24, W = 152;  // 4 groups and a partial fifth
    Tensor input({1, C, H, W});
    Rng rng(32);
    for (int64_t c = 0; c < C; ++c)
        for (int64_t y = 0; y < H; ++y)
            for (int64_t x = 0; x < W; ++x) {
                float v = 0.25f + 0.1f * float(c);                         // flat ...
                if (x >= 40 && x < 60 && y % 6 < 3) v = 0.9f;              // ... but for an edge pattern,
                if (x >= 100 && y >= 12) v += rng.uniform(0.0f, 0.0008f);  // faint noise (under the span)
                if (x >= 120 && y < 4) v += rng.uniform(0.0f, 0.01f);      // and noise above it
                if (x == 100 && y == 14) v = 0.95f;  // a lone pixel: its rows' half-resolution neighbours
                input.data()[(c * H + y) * W + x] = v;
            }
    const float span = 1.0f / 1024;
    InferencePlan plan(model, input.shape());
    const Tensor exact = plan.run(input).clone();
    // The arena filled with another input's activations first: a skipped column that was needed would
    // then hold wrong values (not the right ones left by the run above).
    plan.run(randomTensor(input.shape(), 33));
    plan.setPassThrough(span);
    const Tensor got = plan.run(input).clone();
    auto at = [&](const Tensor& t, int64_t c, int64_t y, int64_t x) { return t.data()[(c * H + y) * W + x]; };
    const int64_t groups = (W + 31) / 32;
    int64_t passed = 0;
    std::vector<char> flatGroups(size_t(H * groups));
    for (int64_t y = 0; y < H; ++y)
        for (int64_t g = 0; g < groups; ++g) {
            bool flat = true;
            for (int64_t c = 0; c < C; ++c) {
                float low = 1e30f, high = -1e30f;
                for (int64_t yy = std::max<int64_t>(0, y - 1); yy <= std::min(H - 1, y + 1); ++yy)
                    for (int64_t x = std::max<int64_t>(0, 32 * g - 1); x <= std::min(W - 1, 32 * g + 32); ++x)
                        low = std::min(low, at(input, c, yy, x)), high = std::max(high, at(input, c, yy, x));
                flat = flat && high - low <= span;
            }
            passed += flat;
            flatGroups[size_t(y * groups + g)] = flat;
            for (int64_t x = 32 * g; x < std::min(W, 32 * g + 32); ++x)
                for (int64_t c = 0; c < C; ++c) {
                    if (flat) {
                        ASSERT_EQ(at(got, c, y, x), at(input, c, y, x)) << "passed pixel " << y << "," << x;
                        ASSERT_LE(std::abs(at(exact, c, y, x) - at(input, c, y, x)), span * 1.001f);
                    } else {
                        ASSERT_EQ(at(got, c, y, x), at(exact, c, y, x)) << "filtered pixel " << y << "," << x;
                    }
                }
        }
    EXPECT_GT(passed, 0);
    EXPECT_LT(passed, H * groups);
    EXPECT_DOUBLE_EQ(plan.passedThroughFraction(), double(passed) / double(H * groups));
    // Streamed, the marks taken from the first layer's bands: the same rows, bit for bit (the arena
    // filled with the other input's activations again).
    ASSERT_TRUE(plan.canStreamInput());
    for (auto [first, last] : {std::pair<int64_t, int64_t>{0, H}, {3, H - 2}}) {
        plan.setPassThrough(0.0f);
        plan.run(randomTensor(input.shape(), 34));
        plan.setPassThrough(span);
        TensorRows source(input);
        CollectedRows streamed(got.shape());
        plan.runStreamed(source, streamed, first, last);
        expectRowsMatch(streamed, got, first, last);
        int64_t passedInRows = 0;
        for (int64_t y = first; y < last; ++y)
            for (int64_t g = 0; g < groups; ++g) passedInRows += flatGroups[size_t(y * groups + g)];
        EXPECT_DOUBLE_EQ(plan.passedThroughFraction(),
                         double(passedInRows) / double((last - first) * groups));
        // A sink that copies whole passed rows itself (OutputRowSink::passRow) is asked for exactly the
        // rows whose every group is flat, and given every other row, made as before.
        struct PassingRows final : OutputRowSink {
            CollectedRows made;
            std::vector<int> passed;  // per row
            explicit PassingRows(const Shape& shape) : made(shape), passed(size_t(shape[2]), 0) {}
            void row(int64_t n, int64_t y, const float* const* channels) override {
                made.row(n, y, channels);
            }
            bool passRow(int64_t, int64_t y) override {
                ++passed[size_t(y)];
                return true;
            }
        } passing(got.shape());
        plan.runStreamed(source, passing, first, last);
        int64_t wholeRows = 0;
        for (int64_t y = 0; y < H; ++y) {
            bool whole = y >= first && y < last;
            for (int64_t g = 0; g < groups; ++g) whole = whole && flatGroups[size_t(y * groups + g)];
            wholeRows += whole;
            ASSERT_EQ(passing.passed[size_t(y)], whole ? 1 : 0) << "row " << y;
            ASSERT_EQ(passing.made.deliveries[size_t(y)], y >= first && y < last && !whole ? 1 : 0)
                << "row " << y;
            for (int64_t c = 0; c < C && passing.made.deliveries[size_t(y)]; ++c)
                for (int64_t x = 0; x < W; ++x)
                    ASSERT_EQ(at(passing.made.rows, c, y, x), at(got, c, y, x))
                        << "row " << y << " column " << x;
        }
        EXPECT_GT(wholeRows, 0);
        EXPECT_DOUBLE_EQ(plan.passedThroughFraction(),
                         double(passedInRows) / double((last - first) * groups));
    }
    // A NaN inside a flat area is filtered (NaN), never passed as if flat; an infinity likewise.
    Tensor poisoned = input.clone();
    poisoned.data()[(0 * H + 5) * W + 10] = NAN;
    poisoned.data()[(1 * H + 20) * W + 12] = INFINITY;
    const Tensor& withNan = plan.runUnchecked(poisoned);
    EXPECT_TRUE(std::isnan(withNan.data()[(0 * H + 5) * W + 11]));
    EXPECT_FALSE(withNan.data()[(1 * H + 20) * W + 13] == at(input, 1, 20, 13));
    {
        TensorRows source(poisoned);
        CollectedRows streamed(got.shape());
        plan.runStreamed(source, streamed, 0, H);
        EXPECT_TRUE(std::isnan(streamed.rows.data()[(0 * H + 5) * W + 11]));
        EXPECT_FALSE(streamed.rows.data()[(1 * H + 20) * W + 13] == at(input, 1, 20, 13));
    }
    // Off again: run()'s result.
    plan.setPassThrough(0.0f);
    const Tensor& off = plan.run(input);
    for (int64_t i = 0; i < off.numel(); ++i) ASSERT_EQ(off.data()[i], exact.data()[i]);
}

// The pass-through test split by rows (kernelRowRanges, what a streamed frame's bands compute) decides
// every group as kernelFlatGroups() does on the three rows together: widths under a vector, partial
// groups, 1 to 4 channels, spreads at and around the span, and NaN, infinities and signed zeros.
TEST_P(Inference, RowRangesDecideAsTheFlatGroupTest) {
    Rng rng(41);
    const float span = 1.0f / 1024, inf = std::numeric_limits<float>::infinity();
    int64_t flatCount = 0, total = 0;
    for (int64_t width : {5, 16, 33, 70, 100, 129})
        for (int channels = 1; channels <= 4; ++channels)
            for (int trial = 0; trial < 40; ++trial) {
                const int64_t groups = (width + kPassGroup - 1) / kPassGroup;
                std::vector<float> data(size_t(3 * channels * width));
                for (int64_t x = 0; x < width; ++x)
                    for (int c = 0; c < channels; ++c) {
                        const float base = 0.5f + 0.1f * float(c);
                        for (int dy = 0; dy < 3; ++dy) {
                            // Mostly flat rows: a spread of about the span (half of them under it).
                            float v = base + span * rng.uniform(0.0f, trial % 2 ? 0.9f : 1.1f);
                            if (rng.below(200) == 0) v = base + 0.01f;
                            if (trial % 5 == 4 && rng.below(150) == 0) {
                                const float specials[] = {NAN, inf, -inf, 0.0f, -0.0f};
                                v = specials[rng.below(5)];
                            }
                            data[size_t((c * 3 + dy) * width + x)] = v;
                        }
                    }
                const float* in[12];
                for (int c = 0; c < channels; ++c)
                    for (int dy = 0; dy < 3; ++dy) in[c * 3 + dy] = data.data() + (c * 3 + dy) * width;
                KernelFilterRowArgs args;
                args.in = in, args.width = width, args.channels = channels, args.kernel = 3;
                std::vector<uint8_t> want(static_cast<size_t>(groups), 0);
                DEJAG_SIMD_CALL(kernelFlatGroups, args, span, want.data());
                std::vector<float> low(size_t(3 * groups * channels)), high(low.size());
                std::vector<uint8_t> bad(static_cast<size_t>(3 * groups), 0);
                for (int dy = 0; dy < 3; ++dy) {
                    const float* rows[4];
                    for (int c = 0; c < channels; ++c) rows[c] = in[c * 3 + dy];
                    DEJAG_SIMD_CALL(kernelRowRanges, rows, channels, width, 1,
                                    low.data() + dy * groups * channels, high.data() + dy * groups * channels,
                                    bad.data() + dy * groups);
                    // Each range exactly: the least and greatest of the group's columns and one each side.
                    for (int64_t g = 0; g < groups; ++g)
                        for (int c = 0; c < channels; ++c) {
                            float lo = inf, hi = -inf;
                            bool finite = true;
                            for (int c2 = 0; c2 < channels; ++c2)
                                for (int64_t x = std::max<int64_t>(0, g * kPassGroup - 1);
                                     x <= std::min<int64_t>(width - 1, g * kPassGroup + kPassGroup); ++x) {
                                    finite = finite && std::isfinite(rows[c2][x]);
                                    if (c2 == c) lo = std::min(lo, rows[c][x]), hi = std::max(hi, rows[c][x]);
                                }
                            ASSERT_EQ(bool(bad[size_t(dy * groups + g)]), !finite)
                                << "width " << width << " group " << g;
                            if (!finite) continue;  // the range is then not used
                            const size_t at = size_t((dy * groups + g) * channels + c);
                            ASSERT_EQ(low[at], lo) << "width " << width << " group " << g << " channel " << c;
                            ASSERT_EQ(high[at], hi)
                                << "width " << width << " group " << g << " channel " << c;
                        }
                }
                for (int64_t g = 0; g < groups; ++g) {
                    bool flat = !bad[size_t(g)] && !bad[size_t(groups + g)] && !bad[size_t(2 * groups + g)];
                    for (int c = 0; c < channels && flat; ++c) {
                        float lo = inf, hi = -inf;
                        for (int dy = 0; dy < 3; ++dy) {
                            lo = std::min(lo, low[size_t((dy * groups + g) * channels + c)]);
                            hi = std::max(hi, high[size_t((dy * groups + g) * channels + c)]);
                        }
                        flat = flat && hi - lo <= span;
                    }
                    ASSERT_EQ(flat, bool(want[size_t(g)])) << "width " << width << ", " << channels
                                                           << " channels, trial " << trial << ", group " << g;
                    flatCount += flat, ++total;
                }
            }
    EXPECT_GT(flatCount, total / 10);  // both decisions well represented
    EXPECT_LT(flatCount, total * 9 / 10);
}

// The row kernel's accumulate mode is accumulate's reference (nn/layers.h) on the middle row of a 3-row
// image: confidences below 0, inside and past the clamp, trust logits either side of the kink (and 0),
// kernels 1 and 3, widths that leave a vector tail (the sRGB curves within 5e-6); with the clip; and with
// the still gate (kernel 3), where a still pixel trusted enough whose history lies in the taps' range
// (widened) is the reference's with full trust and no clip, and every other pixel the reference's.
TEST_P(Inference, AccumulateRowMatchesTheReference) {
    Rng rng(43);
    for (int mode = 0; mode < 3; ++mode)  // plain, clip, clip and the still gate
        for (int kernel : {1, 3})
            for (int64_t width : {1, 7, 37, 70}) {
                if (mode == 2 && kernel != 3) continue;
                SCOPED_TRACE("mode " + std::to_string(mode) + " kernel " + std::to_string(kernel) +
                             " width " + std::to_string(width));
                AccumulateDesc d;
                d.batch = 1, d.channels = 3, d.height = 3, d.width = width, d.kernel = kernel, d.maxCount = 6;
                d.clip = mode >= 1;
                const int64_t plane = 3 * width, taps = kernel * kernel;
                std::vector<float> image(size_t(3 * plane)), logits(size_t((taps + 1) * plane)),
                    history(size_t(4 * plane)), out(size_t(7 * plane)), still(static_cast<size_t>(width));
                for (float& v : image) v = rng.uniform(0.0f, 1.0f);
                for (float& v : logits) v = rng.uniform(-4.0f, 4.0f);
                for (float& v : history) v = rng.uniform(-0.1f, 1.0f);
                for (int64_t x = 0; x < width; x += 5) logits[size_t(taps * plane + width + x)] = 0.0f;
                for (float& v : still) v = rng.uniform(0.0f, 1.0f) < 0.7f ? 1.0f : 0.0f;
                const float stillLogit = -1.0f, tolerance = 0.05f;
                // The gate's pixels: the reference with full trust (logit 0 and up) and no clip.
                std::vector<uint8_t> gated(size_t(width), 0);
                std::vector<float> gatedOut(out.size());
                if (mode == 2) {
                    std::vector<float> lifted = logits;
                    for (int64_t x = 0; x < width; ++x) {
                        bool inside =
                            still[size_t(x)] > 0.5f && logits[size_t(taps * plane + width + x)] >= stillLogit;
                        for (int c = 0; c < 3 && inside; ++c) {
                            float lo = 2, hi = -1;
                            for (int dy = 0; dy < 3; ++dy)
                                for (int64_t dx = -1; dx <= 1; ++dx) {
                                    const float v = image[size_t(c * plane + dy * width +
                                                                 std::clamp<int64_t>(x + dx, 0, width - 1))];
                                    lo = std::min(lo, v), hi = std::max(hi, v);
                                }
                            const float h = history[size_t(c * plane + width + x)];
                            inside = h >= srgbDecode(lo) - tolerance && h <= srgbDecode(hi) + tolerance;
                        }
                        gated[size_t(x)] = inside;
                        lifted[size_t(taps * plane + width + x)] = 1.0f;
                    }
                    AccumulateDesc whole = d;
                    whole.clip = false;
                    accumulateForward(gatedOut.data(), image.data(), lifted.data(), history.data(), whole);
                }
                accumulateForward(out.data(), image.data(), logits.data(), history.data(), d);
                for (int64_t x = 0; x < width; ++x)
                    if (gated[size_t(x)])
                        for (int c = 0; c < 7; ++c)
                            out[size_t(c * plane + width + x)] = gatedOut[size_t(c * plane + width + x)];
                const float* in[9];
                const float* hist[3];
                std::vector<float> rowLogits(size_t((taps + 1) * width)), shown(size_t(3 * width)),
                    kept(size_t(3 * width)), next(static_cast<size_t>(width));
                float* shownRows[3];
                float* keptRows[3];
                for (int c = 0; c < 3; ++c) {
                    for (int dy = 0; dy < kernel; ++dy)
                        in[c * kernel + dy] = image.data() + c * plane + (dy + 1 - kernel / 2) * width;
                    hist[c] = history.data() + c * plane + width;
                    shownRows[c] = shown.data() + c * width, keptRows[c] = kept.data() + c * width;
                }
                for (int64_t j = 0; j <= taps; ++j)
                    std::copy_n(logits.data() + j * plane + width, width, rowLogits.data() + j * width);
                KernelFilterRowArgs args;
                args.out = shownRows, args.in = in, args.logits = rowLogits.data(), args.width = width;
                args.channels = 3, args.kernel = kernel, args.history = hist, args.kept = keptRows;
                args.confidence = history.data() + 3 * plane + width, args.nextConfidence = next.data();
                args.maxCount = d.maxCount, args.clip = d.clip;
                if (mode == 2)
                    args.still = still.data(), args.stillLogit = stillLogit, args.stillTolerance = tolerance;
                DEJAG_SIMD_CALL(kernelFilterRow, args);
                for (int64_t x = 0; x < width; ++x) {
                    for (int c = 0; c < 3; ++c) {
                        ASSERT_NEAR(shown[size_t(c * width + x)], out[size_t(c * plane + width + x)], 5e-6)
                            << x;
                        ASSERT_NEAR(kept[size_t(c * width + x)], out[size_t((3 + c) * plane + width + x)],
                                    5e-6)
                            << x;
                    }
                    ASSERT_NEAR(next[size_t(x)], out[size_t(6 * plane + width + x)], 2e-6) << x;
                }
                if (mode == 2 && width == 70) {  // both decisions represented
                    const int count = int(std::count(gated.begin(), gated.end(), uint8_t(1)));
                    EXPECT_GT(count, 3);
                    EXPECT_LT(count, 60);
                }
            }
}

// An input the plan holds blocked (more than 16 channels): inputRow() writes a staging tensor.
TEST_P(Inference, BlockedInputMatchesTheReference) {
    using nlohmann::json;
    const json nodes = json::array({{{"name", "a"},
                                     {"op", "conv2d"},
                                     {"inputs", {"input"}},
                                     {"out_channels", 5},
                                     {"kernel", 3},
                                     {"padding", "same"},
                                     {"activation", "relu"}},
                                    {{"name", "out"},
                                     {"op", "conv2d"},
                                     {"inputs", {"a"}},
                                     {"out_channels", 3},
                                     {"kernel", 3},
                                     {"padding", "same"}}});
    Model model = Model::fromArchitecture({{"name", "wide_input"}, {"input_channels", 17}, {"nodes", nodes}});
    expectPlanMatchesReference(model, {2, 17, 12, 20});
}

INSTANTIATE_TEST_SUITE_P(SimdLevels, Inference, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);

TEST(InferencePlanning, NoAllocationPerRunAfterWarmUp) {
    Model model = Model::builtin("seed2020");
    model.initialize(3);
    const Tensor input = randomTensor({1, 1, 64, 48}, 4);
    InferencePlan plan(model, input.shape());
    plan.run(input);
    plan.run(input);
    const int64_t before = testing::allocationCount();
    for (int i = 0; i < 3; ++i) plan.run(input);
    EXPECT_EQ(testing::allocationCount() - before, 0) << "heap allocations during 3 runs";
}

TEST(InferencePlanning, ArenaReusesMemoryAndThreadsDoNotChangeResults) {
    Model model = Model::builtin("seed2020");
    model.initialize(5);
    const Tensor input = randomTensor({1, 1, 64, 64}, 6);
    setThreadCount(1);
    InferencePlan plan(model, input.shape());
    EXPECT_LT(plan.arenaBytes(), plan.unpackedBytes() * 3 / 4);
    const Tensor one = plan.run(input).clone();
    setThreadCount(2);
    const Tensor& two = plan.run(input);
    setThreadCount(0);
    for (int64_t i = 0; i < one.numel(); ++i) ASSERT_EQ(one.data()[i], two.data()[i]);
    EXPECT_EQ(plan.macs(), model.macs(input.shape()));
}

// InferencePrecision::BFloat16 (AVX-512 BF16 CPUs): the convolutions' bf16 kernels are checked exactly
// in bf16_conv_test.cpp; here, the plan's wiring — which activations are bf16, the shuffles and
// concatenations in place that write them, the arena and the borders. Each network against its own
// float plan: every activation rounded to 8 significant bits moves the output by well under 1 %, a bf16
// tensor read as float (or a lane written to the wrong place) by far more.
TEST(InferenceBf16, EveryArchitectureStaysCloseToTheFloatPlan) {
    if (!bf16Available()) {  // the plan refuses bf16 there (and InferenceBf16.RefusedWithoutTheInstructions)
        Model model = Model::builtin("kpn", {8, 3});
        model.initialize(1);
        EXPECT_THROW(InferencePlan(model, {1, 3, 16, 16}, InferencePrecision::BFloat16), Error);
        return;
    }
    struct Case {
        Model model;
        Shape shape;
        int bf16Activations;
    };
    Case cases[] = {{Model::builtin("kpn", {8, 3}), {1, 3, 72, 88}, 6},  // dejag-fast's architecture
                    {Model::builtin("kpn"), {1, 3, 48, 64}, 6},
                    {Model::builtin("fast"), {1, 3, 48, 40}, 7},
                    {Model::builtin("seed2020"), {2, 1, 36, 44}, 4},
                    // Every activation here has a reader that takes float only: nothing is rounded.
                    {Model::fromArchitecture(everyOpArchitecture()), {2, 3, 20, 24}, 0}};
    for (Case& c : cases) {
        SCOPED_TRACE(c.model.name());
        c.model.initialize(21);
        uint64_t state = 23;
        for (const ParameterInfo& p : c.model.parameters())
            if (p.isBias)
                for (int64_t i = p.offset; i < p.offset + shapeNumel(p.shape); ++i)
                    c.model.parameterData()[i] = float(unitInterval(state = splitMix64(state), -0.2, 0.2));
        const Tensor input = randomTensor(c.shape, 24);
        InferencePlan exact(c.model, c.shape);
        const Tensor want = exact.run(input).clone();
        InferencePlan plan(c.model, c.shape, InferencePrecision::BFloat16);
        EXPECT_EQ(plan.precision(), InferencePrecision::BFloat16);
        EXPECT_EQ(plan.bf16Activations(), c.bf16Activations);
        const Tensor got = plan.run(input).clone();
        double worst = 0.0, sum = 0.0, scale = 1e-6;
        for (int64_t i = 0; i < want.numel(); ++i) {
            const double error = std::abs(double(got.data()[i]) - double(want.data()[i]));
            worst = std::max(worst, error), sum += error;
            scale = std::max(scale, double(std::abs(want.data()[i])));
        }
        EXPECT_LE(worst / scale, 2e-2);
        EXPECT_LE(sum / double(want.numel()) / scale, 2e-3);
        if (c.bf16Activations > 0) {
            EXPECT_GT(worst, 0.0) << "no activation was rounded";
        } else {
            EXPECT_EQ(worst, 0.0);
        }
        // Deterministic: the same result on 1 and 3 threads, and no allocation per run.
        setThreadCount(1);
        const Tensor one = plan.run(input).clone();
        setThreadCount(3);
        plan.run(input);  // the pool's new threads start
        const int64_t before = testing::allocationCount();
        const Tensor& three = plan.run(input);
        // (The every-op graph's generic float ops allocate once per run on 3 threads; its float plan does
        // the same, so that is not the bf16 path's doing.)
        if (c.bf16Activations > 0) {
            EXPECT_EQ(testing::allocationCount() - before, 0);
        }
        setThreadCount(0);
        for (int64_t i = 0; i < one.numel(); ++i) ASSERT_EQ(one.data()[i], three.data()[i]);
        for (int64_t i = 0; i < one.numel(); ++i) ASSERT_EQ(one.data()[i], got.data()[i]);
    }
}

TEST(InferenceBf16, RefusedWithoutTheInstructions) {
    Model model = Model::builtin("kpn", {8, 3});
    model.initialize(1);
    const SimdLevel original = activeSimdLevel();
    if (cpuSimdLevel() == SimdLevel::Avx512) setSimdLevel(SimdLevel::Avx2);  // bf16 needs the avx512 level
    EXPECT_FALSE(bf16Available());
    EXPECT_THROW(InferencePlan(model, {1, 3, 16, 16}, InferencePrecision::BFloat16), Error);
    setSimdLevel(original);
    InferencePlan exact(model, {1, 3, 16, 16});
    EXPECT_EQ(exact.precision(), InferencePrecision::Float32);
    EXPECT_EQ(exact.bf16Activations(), 0);
}

TEST(InferencePlanning, BadInputsAreClearErrors) {
    Model model = Model::builtin("fast");
    model.initialize(1);
    EXPECT_THROW(InferencePlan(model, {1, 3, 20, 16}), Error);  // not a multiple of 8: the levels differ
    InferencePlan plan(model, {1, 3, 16, 16});
    EXPECT_THROW(plan.run(Tensor({1, 3, 16, 18})), Error);
    Tensor nan({1, 3, 16, 16});
    nan.data()[7] = std::nanf("");
    EXPECT_THROW(plan.run(nan), Error);
}

}  // namespace
}  // namespace dejag::nn

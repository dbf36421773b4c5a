// The recurrent network filter: what it outputs is what training's unrolled forward computes on the same
// frames (the inference plan against the model, the history kept and warped alike), a cut starts the
// history over, and the thread count changes nothing.
#include "infer/cnn_temporal.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/model.h"
#include "tests/test_util.h"
#include "train/temporal.h"

namespace dejag::infer {
namespace {

constexpr int W = 40, H = 24, K = 4;

// A short sequence: a soft pattern moving 0.7 px right and 0.3 px down a frame, exact motion, jitter.
struct Sequence {
    std::vector<std::vector<float>> colour, motion, depth, previousDepth;
    std::vector<std::array<float, 2>> jitter;
};
Sequence makeSequence() {
    Sequence s;
    for (int t = 0; t < K; ++t) {
        std::vector<float> c(size_t(W * H * 3)), m(size_t(W * H * 2)), d(size_t(W * H));
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                const double u = x - 0.7 * t, v = y - 0.3 * t;
                d[size_t(y * W + x)] = float(0.4 + 0.3 * std::sin(0.2 * u - 0.1 * v));
                for (int k = 0; k < 3; ++k)
                    c[size_t((y * W + x) * 3 + k)] =
                        float(0.5 + 0.4 * std::sin(0.45 * u * (k + 1) + 0.3 * v));
                m[size_t((y * W + x) * 2)] = 0.7f, m[size_t((y * W + x) * 2 + 1)] = 0.3f;
            }
        s.colour.push_back(c), s.motion.push_back(m);
        s.previousDepth.push_back(t > 0 ? s.depth.back() : d), s.depth.push_back(d);
        s.jitter.push_back({0.25f - 0.1f * t, -0.2f + 0.15f * t});
    }
    return s;
}

// The temporal family with `state` state channels, or (state 0) the accumulate family, (state -1) with
// the depth inputs; `temporalState0`: the temporal family with no state channel. `width`: the first
// level's channels (8, as the shipped network: its head reads 8 features).
std::string savedModel(const testing::TempDir& dir, int state = 1, int width = 4,
                       bool temporalState0 = false) {
    nn::ModelOptions options;
    options.width = width, options.depth = 2, options.state = state, options.maxCount = 3;
    options.depthInput = state < 0;
    nn::Model model = nn::Model::builtin(state <= 0 && !temporalState0 ? "accumulate" : "temporal", options);
    model.initialize(11);
    // The head at full size, so that every part of the network shows in the output (accumulate's trust
    // both below and above its kink, its cap of 3 samples reached).
    for (const nn::ParameterInfo& p : model.parameters())
        if (p.name.rfind("head", 0) == 0)
            for (int64_t i = 0; i < nn::shapeNumel(p.shape); ++i) model.parameterData()[p.offset + i] *= 10;
    const std::string path = dir.file("temporal" + std::to_string(state) + ".safetensors");
    nn::saveModel(path, model);
    return path;
}

std::vector<std::vector<float>> runFilter(Filter& filter, const Sequence& s, int resetAt = -1) {
    std::vector<std::vector<float>> outputs;
    for (int t = 0; t < K; ++t) {
        Frame f;
        f.width = W, f.height = H, f.colour = s.colour[size_t(t)].data(),
        f.motion = s.motion[size_t(t)].data();
        f.hasJitter = true, f.jitter[0] = s.jitter[size_t(t)][0], f.jitter[1] = s.jitter[size_t(t)][1];
        if (!s.depth[size_t(t)].empty())
            f.depth = s.depth[size_t(t)].data(), f.previousDepth = s.previousDepth[size_t(t)].data();
        if (t == resetAt) filter.reset();
        outputs.emplace_back(size_t(W * H * 3));
        filter.apply(f, outputs.back().data());
    }
    return outputs;
}

// At every SIMD level; with one state channel the built-in family runs fused (the warp on 4 floats a
// pixel, the trunk's plan, the blend's row kernel), with two as one plan of the whole graph; the
// accumulate family (state 0 here) fused too.
class CnnTemporalLevels : public testing::SimdLevelTest {};
INSTANTIATE_TEST_SUITE_P(SimdLevels, CnnTemporalLevels, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);

TEST_P(CnnTemporalLevels, TheFilterIsTrainingsUnrolledForward) {
    // (state, width, temporal family with no state): the fused head (10 logits of 4 phases) for the
    // accumulate family and the temporal one without state, at 4 and 8 features.
    struct Case {
        int state, width;
        bool temporalState0;
    };
    for (const Case tc : {Case{1, 4, false}, Case{2, 4, false}, Case{0, 4, false}, Case{-1, 4, false},
                          Case{-1, 8, false}, Case{0, 8, true}}) {
        const int state = tc.state;
        SCOPED_TRACE((tc.temporalState0 ? std::string("temporal, no state")
                      : state == 0      ? std::string("accumulate")
                      : state < 0       ? std::string("accumulate with depth")
                                        : "state " + std::to_string(state)) +
                     ", width " + std::to_string(tc.width));
        testing::TempDir dir;
        const std::string path = savedModel(dir, state, tc.width, tc.temporalState0);
        const Sequence s = makeSequence();
        // (The still gate is the filter's own, off here, though nothing here is still.)
        const auto filter =
            makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}, {"gate", "off"}});
        EXPECT_TRUE(filter->temporal());
        const auto outputs = runFilter(*filter, s);
        // Training's view of the same frames: a batch of one whole sequence.
        data::SequenceBatch batch;
        for (int t = 0; t < K; ++t) {
            data::SequenceFrame f;
            f.colour = nn::Tensor({1, 3, H, W}), f.truth = nn::Tensor({1, 3, H, W}),
            f.motion = nn::Tensor({1, 2, H, W});
            f.depth = nn::Tensor({1, 1, H, W}), f.previousDepth = nn::Tensor({1, 1, H, W});
            std::copy_n(s.depth[size_t(t)].data(), W * H, f.depth.data());
            std::copy_n(s.previousDepth[size_t(t)].data(), W * H, f.previousDepth.data());
            for (int p = 0; p < W * H; ++p) {
                for (int c = 0; c < 3; ++c)
                    f.colour.data()[c * W * H + p] = s.colour[size_t(t)][size_t(p * 3 + c)];
                if (t > 0)
                    for (int c = 0; c < 2; ++c)
                        f.motion.data()[c * W * H + p] = s.motion[size_t(t)][size_t(p * 2 + c)];
            }
            f.fresh = {uint8_t(t == 0)};
            f.jitter = {s.jitter[size_t(t)][0], s.jitter[size_t(t)][1]};
            batch.frames.push_back(std::move(f));
        }
        nn::Model model = nn::loadModel(path);
        train::Unroller unroller(model);
        unroller.run(batch, false);
        double worst = 0, moved = 0;
        for (int t = 0; t < K; ++t) {
            const nn::Tensor& expected = unroller.output(t);
            for (int p = 0; p < W * H; ++p)
                for (int c = 0; c < 3; ++c) {
                    const float want = std::clamp(expected.data()[c * W * H + p], 0.0f, 1.0f);
                    worst = std::max(worst, double(std::abs(outputs[size_t(t)][size_t(p * 3 + c)] - want)));
                    moved = std::max(moved, double(std::abs(want - s.colour[size_t(t)][size_t(p * 3 + c)])));
                }
        }
        EXPECT_LE(worst, 1e-5);
        EXPECT_GT(moved, 1e-2);  // the network does something to the frames
    }
}

// A frame whose size is no multiple of the network's coarsest scale (37 x 21 for 2 levels) is filtered as
// the frame padded by repeating its edges (to 40 x 24), cropped: the same bytes as filtering that padded
// sequence.
TEST(CnnTemporal, AnySizeIsTheEdgePaddedFrameCropped) {
    for (int state : {1, 0, -1}) {
        SCOPED_TRACE(state == 0 ? "accumulate" : state < 0 ? "accumulate with depth" : "temporal");
        testing::TempDir dir;
        const std::string path = savedModel(dir, state);
        const Sequence s = makeSequence();
        constexpr int w = 37, h = 21;
        Sequence cropped, padded = s;
        for (int t = 0; t < K; ++t) {
            std::vector<float> c(size_t(w * h * 3)), m(size_t(w * h * 2)), d(size_t(w * h)), e(d.size());
            for (int y = 0; y < H; ++y)
                for (int x = 0; x < W; ++x) {
                    const int sy = std::min(y, h - 1), sx = std::min(x, w - 1);
                    padded.depth[size_t(t)][size_t(y * W + x)] = s.depth[size_t(t)][size_t(sy * W + sx)];
                    padded.previousDepth[size_t(t)][size_t(y * W + x)] =
                        s.previousDepth[size_t(t)][size_t(sy * W + sx)];
                    if (y < h && x < w)
                        d[size_t(y * w + x)] = s.depth[size_t(t)][size_t(y * W + x)],
                                         e[size_t(y * w + x)] = s.previousDepth[size_t(t)][size_t(y * W + x)];
                    for (int k = 0; k < 3; ++k) {
                        padded.colour[size_t(t)][size_t((y * W + x) * 3 + k)] =
                            s.colour[size_t(t)][size_t((sy * W + sx) * 3 + k)];
                        if (y < h && x < w)
                            c[size_t((y * w + x) * 3 + k)] = s.colour[size_t(t)][size_t((y * W + x) * 3 + k)];
                    }
                    if (y < h && x < w)
                        for (int k = 0; k < 2; ++k)
                            m[size_t((y * w + x) * 2 + k)] = s.motion[size_t(t)][size_t((y * W + x) * 2 + k)];
                }
            cropped.colour.push_back(c), cropped.motion.push_back(m),
                cropped.jitter.push_back(s.jitter[size_t(t)]);
            cropped.depth.push_back(d), cropped.previousDepth.push_back(e);
        }
        const auto reference =
            runFilter(*makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}}), padded);
        const auto filter = makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}});
        for (int t = 0; t < K; ++t) {
            Frame f;
            f.width = w, f.height = h, f.colour = cropped.colour[size_t(t)].data(),
            f.motion = cropped.motion[size_t(t)].data();
            f.depth = cropped.depth[size_t(t)].data(),
            f.previousDepth = cropped.previousDepth[size_t(t)].data();
            f.hasJitter = true, f.jitter[0] = s.jitter[size_t(t)][0], f.jitter[1] = s.jitter[size_t(t)][1];
            std::vector<float> out(size_t(w * h * 3));
            filter->apply(f, out.data());
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    for (int k = 0; k < 3; ++k)
                        ASSERT_EQ(out[size_t((y * w + x) * 3 + k)],
                                  reference[size_t(t)][size_t((y * W + x) * 3 + k)])
                            << "frame " << t << " at " << x << ", " << y;
        }
    }
}

// Frames of 4 channels (37 x 21: the rows end inside a vector) get the colour of the same frames in 3
// channels, bit for bit, and their 4th channel back as it came; at every SIMD level.
TEST_P(CnnTemporalLevels, FourChannelFramesGetTheSameColourAndKeepTheirFourth) {
    for (int state : {0, 1}) {
        SCOPED_TRACE(state == 0 ? "accumulate" : "temporal");
        testing::TempDir dir;
        const std::string path = savedModel(dir, state);
        const Sequence s = makeSequence();
        constexpr int w = 37, h = 21;
        const auto three = makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}});
        const auto four = makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}});
        for (int t = 0; t < K; ++t) {
            std::vector<float> rgb(size_t(w * h * 3)), rgba(size_t(w * h * 4)), motion(size_t(w * h * 2));
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x) {
                    const size_t p = size_t(y * w + x), q = size_t(y * W + x);
                    for (int k = 0; k < 3; ++k)
                        rgb[3 * p + size_t(k)] = rgba[4 * p + size_t(k)] =
                            s.colour[size_t(t)][3 * q + size_t(k)];
                    rgba[4 * p + 3] = float(p % 7) / 7.0f;
                    for (int k = 0; k < 2; ++k)
                        motion[2 * p + size_t(k)] = s.motion[size_t(t)][2 * q + size_t(k)];
                }
            Frame f;
            f.width = w, f.height = h, f.motion = motion.data();
            f.hasJitter = true, f.jitter[0] = s.jitter[size_t(t)][0], f.jitter[1] = s.jitter[size_t(t)][1];
            std::vector<float> out3(rgb.size()), out4(rgba.size());
            f.colour = rgb.data();
            three->apply(f, out3.data());
            f.colour = rgba.data(), f.channels = 4;
            four->apply(f, out4.data());
            for (size_t p = 0; p < size_t(w * h); ++p) {
                for (size_t k = 0; k < 3; ++k)
                    ASSERT_EQ(out4[4 * p + k], out3[3 * p + k]) << "frame " << t << " " << p;
                ASSERT_EQ(out4[4 * p + 3], rgba[4 * p + 3]) << "frame " << t << " " << p;
            }
        }
    }
}

// A network that takes depth runs on frames without it, as on frames whose depth and previous depth are 0.
TEST(CnnTemporal, ADepthNetworkWithoutDepthSeesZeros) {
    testing::TempDir dir;
    const std::string path = savedModel(dir, -1);
    Sequence s = makeSequence(), zeros = s;
    for (auto& d : zeros.depth) std::fill(d.begin(), d.end(), 0.0f);
    for (auto& d : zeros.previousDepth) std::fill(d.begin(), d.end(), 0.0f);
    const auto filter = makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}});
    EXPECT_EQ(filter->needs(), unsigned(Buffer::Motion));
    EXPECT_TRUE(contains(filter->uses(), Buffer::Depth) && contains(filter->uses(), Buffer::PreviousDepth));
    for (auto& d : s.depth) d.clear();
    for (auto& d : s.previousDepth) d.clear();  // no depth
    const auto without = runFilter(*filter, s);
    const auto withZeros =
        runFilter(*makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}}), zeros);
    EXPECT_EQ(without, withZeros);
}

TEST(CnnTemporal, ACutStartsTheHistoryOverAndThreadsChangeNothing) {
    testing::TempDir dir;
    const std::string path = savedModel(dir);
    const Sequence s = makeSequence();
    const auto filter = makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}});
    const auto whole = runFilter(*filter, s);
    // Frame 2 after a reset is frame 2 of a filter that saw nothing before it...
    const auto cut = runFilter(*makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}}), s, 2);
    Sequence later = s;
    later.colour.erase(later.colour.begin(), later.colour.begin() + 2);
    later.motion.erase(later.motion.begin(), later.motion.begin() + 2);
    later.jitter.erase(later.jitter.begin(), later.jitter.begin() + 2);
    std::vector<std::vector<float>> fresh;
    {
        const auto f = makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}});
        for (int t = 0; t < 2; ++t) {
            Frame frame;
            frame.width = W, frame.height = H, frame.colour = later.colour[size_t(t)].data();
            frame.motion = later.motion[size_t(t)].data(), frame.hasJitter = true;
            frame.jitter[0] = later.jitter[size_t(t)][0], frame.jitter[1] = later.jitter[size_t(t)][1];
            fresh.emplace_back(size_t(W * H * 3));
            f->apply(frame, fresh.back().data());
        }
    }
    EXPECT_EQ(cut[2], fresh[0]);
    EXPECT_EQ(cut[3], fresh[1]);
    // ... and not the frame with its history.
    EXPECT_NE(cut[2], whole[2]);
    // One thread or two: the same bytes.
    const int threads = threadCount();
    setThreadCount(1);
    const auto single = runFilter(*makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}}), s);
    setThreadCount(threads);
    EXPECT_EQ(single, whole);
}

// The still gate: where nothing moves, a network that trusts its history enough keeps all of it. On a
// still flat view whose colour changes a little every frame (so the neighbourhood filter is the colour
// itself, and the history stays within the gate's range of it), gate 0 shows the exact running mean of the
// frames in linear light; the network alone does not; a jump of the light (the history out of the range)
// goes back to the network; and where every pixel moves the gate changes nothing.
TEST(CnnTemporal, TheStillGateKeepsTheWholeHistoryWhereNothingMoves) {
    testing::TempDir dir;
    const std::string path = savedModel(dir, 0);
    auto decode = [](double v) { return v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4); };
    auto encode = [](double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1 / 2.4) - 0.055; };
    const double linear[K] = {0.200, 0.206, 0.197, 0.203};  // each within 2/255 of the mean before it
    Sequence still = makeSequence();
    for (int t = 0; t < K; ++t) {
        for (size_t i = 0; i < still.colour[size_t(t)].size(); ++i)
            still.colour[size_t(t)][i] = float(encode(linear[t] + 0.1 * double(i % 3)));
        std::fill(still.motion[size_t(t)].begin(), still.motion[size_t(t)].end(), 0.0f);
    }
    auto filter = [&](const char* gate) {
        return makeFilter("cnn-temporal", {{"model", path}, {"precision", "fp32"}, {"gate", gate}});
    };
    // The largest difference from the running mean of frame t.
    auto worst = [&](const std::vector<float>& frame, int t, const Sequence& s) {
        double w = 0;
        for (size_t i = 0; i < frame.size(); ++i) {
            double mean = 0;
            for (int u = 0; u <= t; ++u) mean += decode(s.colour[size_t(u)][i]) / (t + 1);
            w = std::max(w, std::fabs(frame[i] - encode(mean)));
        }
        return w;
    };
    const auto gated = runFilter(*filter("0"), still);
    const auto ungated = runFilter(*filter("off"), still);
    double worstGated = 0, worstUngated = 0;
    for (int t = 0; t < K; ++t)
        worstGated = std::max(worstGated, worst(gated[size_t(t)], t, still)),
        worstUngated = std::max(worstUngated, worst(ungated[size_t(t)], t, still));
    EXPECT_LT(worstGated, 2e-5);
    EXPECT_GT(worstUngated, 1e-4);  // the network alone trusts less somewhere (the colours differ little)
    Sequence jump = still;          // the light doubles on the last frame
    for (float& v : jump.colour[K - 1]) v = float(encode(std::min(1.0, 2 * decode(v))));
    EXPECT_GT(worst(runFilter(*filter("0"), jump)[K - 1], K - 1, jump), 1e-3);
    const Sequence moving = makeSequence();
    EXPECT_EQ(runFilter(*filter("0"), moving), runFilter(*filter("off"), moving));
    // Still only from frame 2: the history of frame 2 comes from a frame that moved, so the gate first
    // holds on frame 3.
    Sequence settles = still;
    std::fill(settles.motion[1].begin(), settles.motion[1].end(), 0.5f);
    const auto settlesGated = runFilter(*filter("0"), settles),
               settlesUngated = runFilter(*filter("off"), settles);
    for (int t = 0; t < 3; ++t)
        EXPECT_EQ(settlesGated[size_t(t)], settlesUngated[size_t(t)]) << "frame " << t;
    EXPECT_NE(settlesGated[3], settlesUngated[3]);
    for (const char* bad : {"1.5", "-0.1", "half", ""}) EXPECT_THROW((void)filter(bad), Error) << bad;
    EXPECT_THROW((void)makeFilter("cnn-temporal", {{"model", path}, {"clip", "maybe"}}), Error);
}

TEST(CnnTemporal, ASingleFrameModelOrMissingMotionIsOneClearError) {
    testing::TempDir dir;
    const std::string path = dir.file("fast.safetensors");
    nn::saveModel(path, nn::Model::builtin("fast"));
    try {
        (void)makeFilter("cnn-temporal", {{"model", path}});
        ADD_FAILURE() << "accepted a single-frame model";
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find("not a temporal network"), std::string::npos) << e.what();
    }
    const auto filter = makeFilter("cnn-temporal", {{"model", savedModel(dir)}});
    std::vector<float> colour(size_t(W * H * 3), 0.5f), out(colour.size());
    Frame f;
    f.width = W, f.height = H, f.colour = colour.data();
    EXPECT_THROW(filter->apply(f, out.data()), Error);  // no motion
}

}  // namespace
}  // namespace dejag::infer

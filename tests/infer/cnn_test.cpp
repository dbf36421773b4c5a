// The CNN filter: tiles with a receptive-field halo equal the whole frame, gating passes skipped tiles
// through bit for bit and equals the ungated result inside processed ones, no allocation per frame, and
// models it cannot run are refused.
#include "infer/cnn.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <random>

#include "base/error.h"
#include "infer/cnn_kernels.h"
#include "infer/filter.h"
#include "tests/alloc_counter.h"
#include "tests/test_util.h"
#include "train/trainer.h"

namespace dejag::infer {
namespace {

nn::Model seeded(const std::string& name, uint64_t seed) {
    nn::Model m = nn::Model::builtin(name);
    m.initialize(seed);
    return m;
}

// A frame with flat areas, a few hard-edged shapes and a noisy patch; alpha in channel 3.
std::vector<float> testFrame(int width, int height, int channels) {
    std::vector<float> frame(size_t(width) * size_t(height) * size_t(channels));
    std::mt19937 rng(5);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x) {
            float* p = &frame[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels)];
            const bool disc = (x - 40) * (x - 40) + (y - 30) * (y - 30) < 400;
            const bool slab = x + 2 * y > 2 * width && x < width - 10;
            const bool noise = x > width / 2 && y < 24;
            for (int c = 0; c < 3; ++c) p[c] = 0.3f + 0.1f * float(c);
            if (disc) p[0] = 0.9f, p[1] = 0.8f;
            if (slab) p[2] = 0.05f;
            if (noise) p[1] = u(rng);
            for (int c = 3; c < channels; ++c) p[c] = 0.5f;
        }
    return frame;
}

float maxDifference(const std::vector<float>& a, const std::vector<float>& b) {
    float worst = 0;
    for (size_t i = 0; i < a.size(); ++i) worst = std::max(worst, std::abs(a[i] - b[i]));
    return worst;
}

class CnnRows : public testing::SimdLevelTest {};

// The gate's row test on every level equals the pixel loop it replaced: a step to the right or below at
// each position of rows of several widths, inside [first, last] or just outside it, at the row's end
// (no right neighbour), and values a hair either side of the threshold.
TEST_P(CnnRows, LumaStepTestMatchesThePixelLoop) {
    auto luma = [](const float* p) { return 0.21f * p[0] + 0.72f * p[1] + 0.07f * p[2]; };
    const float threshold = 0.04f;
    for (int channels : {3, 4})
        for (int64_t width : {1, 7, 16, 17, 40, 53}) {
            std::vector<float> row(size_t(width * channels), 0.5f), below = row;
            auto expected = [&](int64_t first, int64_t last) {
                for (int64_t x = first; x <= last; ++x) {
                    const float here = luma(&row[size_t(x * channels)]);
                    const float right = x + 1 < width ? luma(&row[size_t((x + 1) * channels)]) : here;
                    if (std::abs(right - here) > threshold ||
                        std::abs(luma(&below[size_t(x * channels)]) - here) > threshold)
                        return true;
                }
                return false;
            };
            for (int64_t at = 0; at < width; ++at)
                for (int where = 0; where < 2; ++where)
                    for (float jump : {0.0399f, 0.0401f, 0.06f}) {
                        std::fill(row.begin(), row.end(), 0.5f), std::fill(below.begin(), below.end(), 0.5f);
                        std::vector<float>& target = where == 0 ? row : below;
                        for (int c = 0; c < 3; ++c) target[size_t(at * channels + c)] += jump;
                        for (const auto& [first, last] : {std::pair<int64_t, int64_t>{0, width - 1},
                                                          {std::min<int64_t>(at + 1, width - 1), width - 1},
                                                          {0, std::max<int64_t>(at - 2, 0)}}) {
                            const bool got = DEJAG_SIMD_CALL(rowHasLumaStep, row.data(), below.data(),
                                                             channels, width, first, last, threshold);
                            ASSERT_EQ(got, expected(first, last))
                                << channels << " channels, width " << width << ", step " << jump << " at "
                                << at << (where ? " below" : " in the row") << ", pixels " << first << ".."
                                << last;
                        }
                    }
        }
}

INSTANTIATE_TEST_SUITE_P(SimdLevels, CnnRows, ::testing::ValuesIn(testing::availableSimdLevels()),
                         testing::simdTestName);

class CnnTiles : public ::testing::TestWithParam<const char*> {};

TEST_P(CnnTiles, TiledEqualsWholeFrame) {
    const int W = 203, H = 141, C = 4;  // not multiples of any tile or stride
    const std::vector<float> frame = testFrame(W, H, C);
    std::vector<float> whole(frame.size()), tiled(frame.size());
    CnnOptions big;
    big.tileSize = 1024, big.gate = false;
    CnnFilter reference(seeded(GetParam(), 3), big);
    reference.apply(frame.data(), whole.data(), W, H, C);
    EXPECT_EQ(reference.tileCount(), 1);
    CnnOptions small;
    small.tileSize = 48, small.gate = false;
    CnnFilter filter(seeded(GetParam(), 3), small);
    filter.apply(frame.data(), tiled.data(), W, H, C);
    EXPECT_GT(filter.tileCount(), 12);
    EXPECT_LE(maxDifference(whole, tiled), 1e-5f);
    for (size_t p = 0; p < size_t(W) * H; ++p) ASSERT_EQ(tiled[p * C + 3], 0.5f) << "alpha passes through";
}

// The filter against the model's own forward (nn::Model::forward, the reference kernels): the frame
// padded by repeating its last row and column up to a multiple of the stride, the network run on it,
// the result cropped and clamped to [0, 1] (a grey model's luma change added to R, G and B).
TEST_P(CnnTiles, WholeFrameEqualsTheModelOnTheReplicatedFrame) {
    const int W = 203, H = 141, C = 4;
    const std::vector<float> frame = testFrame(W, H, C);
    nn::Model model = seeded(GetParam(), 3);
    CnnOptions options;
    options.gate = false;
    CnnFilter filter(seeded(GetParam(), 3), options);
    std::vector<float> got(frame.size());
    filter.apply(frame.data(), got.data(), W, H, C);
    const int a = filter.alignment(), PW = (W + a - 1) / a * a, PH = (H + a - 1) / a * a;
    const bool grey = model.inputChannels() == 1;
    auto luma = [&](const float* p) { return 0.21f * p[0] + 0.72f * p[1] + 0.07f * p[2]; };
    nn::Tensor input({1, model.inputChannels(), PH, PW});
    for (int y = 0; y < PH; ++y)
        for (int x = 0; x < PW; ++x) {
            const float* p = &frame[(size_t(std::min(y, H - 1)) * W + size_t(std::min(x, W - 1))) * C];
            for (int c = 0; c < model.inputChannels(); ++c) input.at(0, c, y, x) = grey ? luma(p) : p[c];
        }
    const nn::Tensor& result = model.forward(input);
    float worst = 0;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const float* p = &frame[(size_t(y) * W + size_t(x)) * C];
            for (int c = 0; c < 3; ++c) {
                const float want = std::clamp(
                    grey ? p[c] + result.at(0, 0, y, x) - luma(p) : result.at(0, c, y, x), 0.0f, 1.0f);
                worst = std::max(worst, std::abs(got[(size_t(y) * W + size_t(x)) * C + size_t(c)] - want));
            }
        }
    EXPECT_LE(worst, 1e-5f);
}

INSTANTIATE_TEST_SUITE_P(Architectures, CnnTiles, ::testing::Values("seed2020", "fast", "kpn"));

TEST(Cnn, GatedTilesAreTheInputOrTheUngatedResult) {
    const int W = 256, H = 192, C = 3;
    const std::vector<float> frame = testFrame(W, H, C);
    std::vector<float> ungated(frame.size()), gated(frame.size());
    CnnOptions off;
    off.tileSize = 64, off.gate = false;
    CnnFilter all(seeded("fast", 7), off);
    all.apply(frame.data(), ungated.data(), W, H, C);
    CnnOptions on = off;
    on.gate = true;
    CnnFilter some(seeded("fast", 7), on);
    some.apply(frame.data(), gated.data(), W, H, C);
    EXPECT_GT(some.processedFraction(), 0.0);
    EXPECT_LT(some.processedFraction(), 1.0);
    int skipped = 0;
    for (int ty = 0; ty < H / 64; ++ty)
        for (int tx = 0; tx < W / 64; ++tx) {
            bool same = true, equalsInput = true;
            for (int y = ty * 64; y < ty * 64 + 64; ++y)
                for (int x = tx * 64; x < tx * 64 + 64; ++x)
                    for (int c = 0; c < C; ++c) {
                        const size_t i = (size_t(y) * W + size_t(x)) * C + size_t(c);
                        same = same && gated[i] == ungated[i];
                        equalsInput = equalsInput && gated[i] == frame[i];
                    }
            EXPECT_TRUE(same || equalsInput) << "tile " << tx << "," << ty;
            skipped += !same && equalsInput;
        }
    EXPECT_EQ(skipped, some.tileCount() - some.tilesProcessed());
    // A constant frame needs nothing: every tile skipped, the output the input.
    std::vector<float> flat(frame.size(), 0.25f), out(frame.size());
    some.apply(flat.data(), out.data(), W, H, C);
    EXPECT_EQ(some.tilesProcessed(), 0);
    EXPECT_EQ(out, flat);
    // ID buffers alone open a tile.
    std::vector<float> ids(size_t(W) * H, 1.0f);
    ids[size_t(100) * W + 10] = 2.0f;
    some.apply(flat.data(), out.data(), W, H, C, {nullptr, ids.data()});
    EXPECT_EQ(some.tilesProcessed(), 1);
}

// Gated, a kernel-predicting network also passes flat runs of pixels through inside processed tiles:
// each pixel is then the ungated result or the input — the input only where the ungated result is within
// the pass-through span of it — and with the span at 0 the processed tiles are exactly the ungated result.
TEST(Cnn, KpnPassesFlatRunsThroughWithinTheSpan) {
    const int W = 256, H = 192, C = 3;
    const std::vector<float> frame = testFrame(W, H, C);
    std::vector<float> ungated(frame.size()), gated(frame.size()), exact(frame.size());
    CnnOptions off;
    off.gate = false;
    CnnFilter all(seeded("kpn", 7), off);
    all.apply(frame.data(), ungated.data(), W, H, C);
    CnnOptions on;
    CnnFilter some(seeded("kpn", 7), on);
    some.apply(frame.data(), gated.data(), W, H, C);
    EXPECT_EQ(some.processedFraction(), 1.0);
    EXPECT_GT(some.passedThroughFraction(), 0.2);
    EXPECT_LT(some.passedThroughFraction(), 1.0);
    EXPECT_EQ(all.passedThroughFraction(), 0.0);
    int passed = 0;
    for (size_t i = 0; i < frame.size(); ++i) {
        if (gated[i] == ungated[i]) continue;
        ASSERT_EQ(gated[i], frame[i]) << "element " << i << " is neither the ungated result nor the input";
        ASSERT_LE(std::abs(ungated[i] - frame[i]), on.passSpan * 1.001f) << "element " << i;
        ++passed;
    }
    // Flat rows outside [0, 1] (an HDR frame): passed through whole, they are clamped as made rows are.
    std::vector<float> bright = frame;
    for (int y = 0; y < 40; ++y)
        for (int x = 0; x < W; ++x)
            for (int c = 0; c < C; ++c) bright[size_t((y * W + x) * C + c)] = c == 0 ? 1.5f : -0.25f;
    std::vector<float> brightUngated(frame.size()), brightGated(frame.size());
    all.apply(bright.data(), brightUngated.data(), W, H, C);
    some.apply(bright.data(), brightGated.data(), W, H, C);
    for (int y = 0; y < 39; ++y)
        for (int x = 0; x < W; ++x)
            for (int c = 0; c < C; ++c) {
                const size_t i = size_t((y * W + x) * C + c);
                ASSERT_EQ(brightGated[i], c == 0 ? 1.0f : 0.0f) << "row " << y << " column " << x;
                ASSERT_EQ(brightGated[i], brightUngated[i]) << "row " << y << " column " << x;
            }
    on.passSpan = 0.0f;
    CnnFilter none(seeded("kpn", 7), on);
    none.apply(frame.data(), exact.data(), W, H, C);
    EXPECT_EQ(exact, ungated);
    EXPECT_EQ(none.passedThroughFraction(), 0.0);
    on.passSpan = -1.0f;
    EXPECT_THROW(CnnFilter(seeded("kpn", 7), on), Error);
}

TEST(Cnn, NoAllocationPerFrameAfterWarmUp) {
    const int W = 160, H = 120, C = 3;
    const std::vector<float> frame = testFrame(W, H, C);
    std::vector<float> out(frame.size());
    CnnOptions options;
    options.tileSize = 64;
    CnnFilter filter(seeded("fast", 1), options);
    filter.apply(frame.data(), out.data(), W, H, C);
    const int64_t before = testing::allocationCount();
    for (int i = 0; i < 3; ++i) filter.apply(frame.data(), out.data(), W, H, C);
    EXPECT_EQ(testing::allocationCount() - before, 0);
}

// One contract for a model on a frame: what training's validation and the model card score
// (train::runNetwork) is what `dejag filter --method cnn --set gate=off` writes, bit for bit.
TEST(Cnn, TheCardScoresWhatTheFilterWrites) {
    const int W = 203, H = 141;
    for (const char* arch : {"fast", "seed2020"}) {
        const std::vector<float> frame = testFrame(W, H, 3);
        Image image(W, H, {"R", "G", "B"}, PixelType::Float);
        image.pixels = frame;
        const nn::Model model = seeded(arch, 7);
        auto network = nn::FrameNetwork::borrowing(model);
        const Image card = train::runNetwork(network, image);
        CnnOptions options;
        options.gate = false;
        CnnFilter filter(seeded(arch, 7), options);
        std::vector<float> filtered(frame.size());
        filter.apply(frame.data(), filtered.data(), W, H, 3);
        ASSERT_EQ(card.pixels.size(), filtered.size());
        for (size_t i = 0; i < filtered.size(); ++i)
            ASSERT_EQ(std::bit_cast<uint32_t>(card.pixels[i]), std::bit_cast<uint32_t>(filtered[i]))
                << arch << ", element " << i;
    }
}

// A network trained after an input method (its architecture's "input_method") is run after that method:
// the filter on the frame equals the same weights without it on the method's output.
TEST(Cnn, RunsTheInputMethodItWasTrainedAfter) {
    testing::TempDir dir;
    nlohmann::json arch = nn::Model::builtinArchitecture("kpn", {8, 3, 3});
    nn::Model plain = nn::Model::fromArchitecture(arch);
    plain.initialize(7);
    arch["input_method"] = "smaa";
    nn::Model after = nn::Model::fromArchitecture(arch);
    after.initialize(7);
    nn::saveModel(dir.file("plain.safetensors"), plain);
    nn::saveModel(dir.file("after.safetensors"), after);
    const int W = 61, H = 37;
    const std::vector<float> frame = testFrame(W, H, 3);
    Frame f;
    f.width = W, f.height = H, f.channels = 3, f.colour = frame.data();
    std::vector<float> smaa(frame.size()), expected(frame.size()), got(frame.size());
    makeFilter("smaa", {})->apply(f, smaa.data());
    ASSERT_NE(smaa, frame);
    Frame g = f;
    g.colour = smaa.data();
    makeFilter("cnn", {{"model", dir.file("plain.safetensors")}, {"gate", "off"}})->apply(g, expected.data());
    const auto filter = makeFilter("cnn", {{"model", dir.file("after.safetensors")}, {"gate", "off"}});
    filter->apply(f, got.data());
    EXPECT_EQ(got, expected);
    bool named = false;
    for (const auto& [key, value] : filter->figures().settings)
        named = named || (key == "input_method" && value == "smaa");
    EXPECT_TRUE(named);
}

// A guided network (its architecture's "guide_method") reads that method's result on the frame beside
// it: the filter equals the model card's run with the guide made by the method, bit for bit, whole or in
// tiles; without a guide the network refuses the frame.
TEST(Cnn, ReadsTheGuideMethodsResultBesideTheFrame) {
    testing::TempDir dir;
    nn::ModelOptions options;
    options.width = 8, options.guide = true;
    nlohmann::json arch = nn::Model::builtinArchitecture("kpn", options);
    arch["guide_method"] = "smaa";
    nn::Model model = nn::Model::fromArchitecture(arch);
    model.initialize(7);
    nn::saveModel(dir.file("guided.safetensors"), model);
    const int W = 203, H = 141;
    const std::vector<float> frame = testFrame(W, H, 3);
    Frame f;
    f.width = W, f.height = H, f.channels = 3, f.colour = frame.data();
    Image image(W, H, {"R", "G", "B"}, PixelType::Float), guide = image;
    image.pixels = frame;
    guide.pixels.resize(frame.size());
    makeFilter("smaa", {})->apply(f, guide.pixels.data());
    auto network = nn::FrameNetwork::borrowing(model);
    const Image card = train::runNetwork(network, image, &guide);
    EXPECT_THROW(train::runNetwork(network, image), Error);
    for (const char* tile : {"2048", "64"}) {
        const auto filter = makeFilter("cnn", {{"model", dir.file("guided.safetensors")},
                                               {"gate", "off"},
                                               {"tile", tile},
                                               {"precision", "fp32"}});
        std::vector<float> got(frame.size());
        filter->apply(f, got.data());
        float worst = 0;
        for (size_t i = 0; i < got.size(); ++i) worst = std::max(worst, std::abs(got[i] - card.pixels[i]));
        EXPECT_LE(worst, tile[0] == '2' ? 0.0f : 1e-5f) << "tile " << tile;
        bool named = false;
        for (const auto& [key, value] : filter->figures().settings)
            named = named || (key == "guide_method" && value == "smaa");
        EXPECT_TRUE(named);
    }
    // Gated, flat runs pass through (the guide lies within a flat neighbourhood's range): every element
    // is the ungated result or the frame's, and that within the span of it.
    const auto gated = makeFilter("cnn", {{"model", dir.file("guided.safetensors")}, {"precision", "fp32"}});
    std::vector<float> passed(frame.size());
    gated->apply(f, passed.data());
    int changed = 0;
    for (size_t i = 0; i < frame.size(); ++i) {
        if (passed[i] == card.pixels[i]) continue;
        ASSERT_EQ(passed[i], frame[i]) << "element " << i;
        ASSERT_LE(std::abs(card.pixels[i] - frame[i]), CnnOptions().passSpan * 1.001f) << "element " << i;
        ++changed;
    }
    EXPECT_GT(changed, 0);
}

TEST(Cnn, RefusesModelsItCannotRun) {
    nlohmann::json arch = nn::Model::builtinArchitecture("fast", {8, 3, 4});
    EXPECT_THROW(CnnFilter(nn::Model::fromArchitecture(arch)), Error);  // 4 channels
    CnnOptions bad;
    bad.tileSize = 4;
    EXPECT_THROW(CnnFilter(nn::Model::builtin("fast"), bad), Error);
}

}  // namespace
}  // namespace dejag::infer

// The patch sampler on a tiny generated dataset: determinism, the aliasing bias, augmentation-free crops
// equal to the items, grey mode, splits and errors.
#include "data/patches.h"

#include <gtest/gtest.h>
#include <sys/wait.h>

#include <cmath>
#include <filesystem>

#include "base/error.h"
#include "data/evaluation.h"
#include "data/image.h"
#include "tests/test_util.h"

namespace dejag::data {
namespace {

namespace fs = std::filesystem;

class Patches : public ::testing::Test {
  protected:
    static void SetUpTestSuite() {
        folder_ = (fs::temp_directory_path() / ("dejag-patches-" + std::to_string(::getpid()))).string();
        fs::remove_all(folder_);
        const std::string command =
            "'" + std::string(DEJAG_BINARY) +
            "' data generate --families shapes,pipes,thin,foliage,random --test-families foliage "
            "--count 12 --size 128x96 --truth 16 --quiet --out '" +
            folder_ + "'";
        ASSERT_EQ(std::system(command.c_str()), 0);
    }
    static void TearDownTestSuite() { fs::remove_all(folder_); }
    static std::string folder_;
};
std::string Patches::folder_;

bool same(const nn::Tensor& a, const nn::Tensor& b) {
    return a.shape() == b.shape() && std::equal(a.data(), a.data() + a.numel(), b.data());
}

TEST_F(Patches, SameSeedSameBatchesWhateverTheThreadTiming) {
    PatchOptions options;
    options.patchSize = 32, options.batchSize = 4, options.seed = 9;
    PatchSampler a(folder_, options), b(folder_, options);
    for (int i = 0; i < 4; ++i) {
        const Batch x = a.next(), y = b.next(), z = a.assemble(uint64_t(i) + 4);
        EXPECT_TRUE(same(x.input, y.input));
        EXPECT_TRUE(same(x.target, y.target));
        EXPECT_EQ(x.items, y.items);
        (void)z;
    }
    EXPECT_TRUE(same(a.assemble(2).input, b.assemble(2).input));
    options.seed = 10;
    PatchSampler c(folder_, options);
    EXPECT_FALSE(same(c.assemble(0).input, a.assemble(0).input));
}

TEST_F(Patches, AliasingBiasIsMeasurable) {
    PatchOptions options;
    options.patchSize = 16, options.batchSize = 16, options.seed = 3;
    options.uniformFraction = 0.0;
    PatchSampler biased(folder_, options);
    options.uniformFraction = 1.0;
    PatchSampler uniform(folder_, options);
    double biasedEdges = 0, uniformEdges = 0;
    for (uint64_t i = 0; i < 40; ++i) {
        biasedEdges += biased.assemble(i).edgeFraction;
        uniformEdges += uniform.assemble(i).edgeFraction;
    }
    EXPECT_GT(biasedEdges, 1.5 * uniformEdges)
        << "biased " << biasedEdges / 40 << ", uniform " << uniformEdges / 40;
}

TEST_F(Patches, WithoutAugmentationAPatchIsTheItemCropAndGreyIsLuma) {
    PatchOptions options;
    options.patchSize = 24, options.batchSize = 2, options.seed = 5;
    options.augment = false, options.brightnessJitter = 0, options.hueJitter = 0, options.uniformFraction = 1;
    PatchSampler colour(folder_, options);
    const Batch batch = colour.assemble(0);
    // The crop is somewhere in the item: find it by matching the first pixel row against the item.
    const std::vector<nlohmann::json> records = readManifest(folder_);
    const nlohmann::json& record = records[size_t(batch.items[0])];
    const Image truth =
        readImage((fs::path(folder_) / record["files"]["truth"]["path"].get<std::string>()).string());
    bool found = false;
    for (int y0 = 0; y0 + 24 <= truth.height && !found; ++y0)
        for (int x0 = 0; x0 + 24 <= truth.width && !found; ++x0) {
            double worst = 0;
            for (int y = 0; y < 24; ++y)
                for (int x = 0; x < 24; ++x)
                    for (int c = 0; c < 3; ++c) {
                        const float want =
                            std::clamp(linearToSrgb(std::max(truth.at(x0 + x, y0 + y, c), 0.0f)), 0.0f, 1.0f);
                        worst = std::max(worst, double(std::abs(batch.target.at(0, c, y, x) - want)));
                    }
            found = worst < 1.0 / 65535 + 1e-6;
        }
    EXPECT_TRUE(found);
    options.grayscale = true;
    PatchSampler grey(folder_, options);
    const Batch g = grey.assemble(0);
    ASSERT_EQ(g.input.dim(1), 1);
    for (int y = 0; y < 24; y += 5)
        for (int x = 0; x < 24; x += 3)
            EXPECT_NEAR(g.input.at(1, 0, y, x),
                        0.21f * batch.input.at(1, 0, y, x) + 0.72f * batch.input.at(1, 1, y, x) +
                            0.07f * batch.input.at(1, 2, y, x),
                        1e-6);
}

// A guide beside the input: channels 3..5 are the guide method's result on the item, cut, flipped and
// scaled with the frame's (here a transform inverting the colours), the frame and the target unchanged.
TEST_F(Patches, AGuideGoesBesideTheFrameAugmentedWithIt) {
    PatchOptions options;
    options.patchSize = 24, options.batchSize = 6, options.seed = 5, options.brightnessJitter = 0.2;
    PatchSampler plain(folder_, options);
    options.guideTransform = [](float* rgb, int width, int height) {
        for (size_t i = 0; i < size_t(width) * size_t(height) * 3; ++i) rgb[i] = 0.5f * (1.0f - rgb[i]);
    };
    PatchSampler guided(folder_, options);
    const Batch a = plain.assemble(3), b = guided.assemble(3);
    ASSERT_EQ(b.input.dim(1), 6);
    EXPECT_TRUE(same(a.target, b.target));
    for (int n = 0; n < 6; ++n)
        for (int y = 0; y < 24; ++y)
            for (int x = 0; x < 24; ++x)
                for (int c = 0; c < 3; ++c) {
                    ASSERT_EQ(b.input.at(n, c, y, x), a.input.at(n, c, y, x));
                    // The gain g scales both: g * 0.5 * (1 - v), where the frame is g * v (unclamped).
                    const float frame = a.input.at(n, c, y, x), guide = b.input.at(n, 3 + c, y, x);
                    if (frame < 0.99f) {
                        const float gain = guide + 0.5f * frame;  // = 0.5 g
                        ASSERT_GT(gain, 0.5f * 0.77f);
                        ASSERT_LT(gain, 0.5f * 1.24f);
                    }
                }
    options.grayscale = true;
    EXPECT_THROW(PatchSampler(folder_, options), Error);
}

// Texture masks (the loss's texharm term): each patch's mask is its item's texture region (data/evaluation.h)
// cut, flipped and turned with the patch; found by matching the target against the item's truth.
TEST_F(Patches, TextureMasksTravelWithTheirPatches) {
    PatchOptions options;
    options.patchSize = 24, options.batchSize = 8, options.seed = 7;
    options.brightnessJitter = 0, options.hueJitter = 0, options.textureMask = true;
    PatchSampler sampler(folder_, options);
    const std::vector<nlohmann::json> records = readManifest(folder_);
    int64_t texturePixels = 0;
    for (uint64_t b = 0; b < 3; ++b) {
        const Batch batch = sampler.assemble(b);
        ASSERT_EQ(batch.texture.shape(), (nn::Shape{8, 1, 24, 24}));
        for (int n = 0; n < 8; ++n) {
            const nlohmann::json& record = records[size_t(batch.items[size_t(n)])];
            const Image input =
                readImage((fs::path(folder_) / record["files"]["input"]["path"].get<std::string>()).string());
            const Image truth =
                readImage((fs::path(folder_) / record["files"]["truth"]["path"].get<std::string>()).string());
            EvaluationItem item;
            item.id = record["id"].get<std::string>();
            item.truth = Image(truth.width, truth.height, Image::defaultChannelNames(3));
            for (int y = 0; y < truth.height; ++y)
                for (int x = 0; x < truth.width; ++x)
                    for (int c = 0; c < 3; ++c)
                        item.truth.pixels[(size_t(y) * size_t(truth.width) + size_t(x)) * 3 + size_t(c)] =
                            std::clamp(linearToSrgb(std::max(truth.at(x, y, c), 0.0f)), 0.0f, 1.0f);
            computeRegionMasks(item, input);
            const Image& mask = item.masks[int(Region::Texture)];
            bool found = false;
            for (int orientation = 0; orientation < 8 && !found; ++orientation)
                for (int y0 = 0; y0 + 24 <= truth.height && !found; ++y0)
                    for (int x0 = 0; x0 + 24 <= truth.width && !found; ++x0) {
                        auto source = [&](int x, int y) {
                            int sx = x, sy = y;
                            if (orientation & 4) std::swap(sx, sy);
                            if (orientation & 1) sx = 23 - sx;
                            if (orientation & 2) sy = 23 - sy;
                            return std::pair{x0 + sx, y0 + sy};
                        };
                        bool match = true;
                        for (int y = 0; y < 24 && match; ++y)
                            for (int x = 0; x < 24 && match; ++x) {
                                const auto [sx, sy] = source(x, y);
                                for (int c = 0; c < 3 && match; ++c)
                                    match = std::abs(batch.target.at(n, c, y, x) - item.truth.at(sx, sy, c)) <
                                            1.0f / 65535 + 1e-6f;
                            }
                        if (!match) continue;
                        found = true;
                        int differ = 0;
                        for (int y = 0; y < 24; ++y)
                            for (int x = 0; x < 24; ++x) {
                                const auto [sx, sy] = source(x, y);
                                differ += batch.texture.at(n, 0, y, x) != mask.at(sx, sy, 0);
                                texturePixels += batch.texture.at(n, 0, y, x) == 1.0f;
                            }
                        // The sampler's truth is 16-bit: a 3x3 luma range within 1e-5 of the threshold may
                        // fall the other side.
                        EXPECT_LE(differ, 2) << "patch " << n << " of batch " << b;
                    }
            EXPECT_TRUE(found) << "patch " << n << " of batch " << b;
        }
    }
    EXPECT_GT(texturePixels, 0);
    options.textureMask = false;
    EXPECT_EQ(PatchSampler(folder_, options).assemble(0).texture.numel(), 0);
}

TEST_F(Patches, SplitsAndErrors) {
    PatchOptions options;
    options.patchSize = 32, options.batchSize = 8;
    options.split = Split::Test;
    PatchSampler test(folder_, options);
    const std::vector<nlohmann::json> records = readManifest(folder_);
    for (int index : test.assemble(0).items) EXPECT_EQ(records[size_t(index)]["split"], "test");
    options.split = Split::Train;
    options.patchSize = 100;  // taller than the 128x96 items
    EXPECT_THROW(PatchSampler(folder_, options), Error);
    options.patchSize = 32;
    // Each refusal names its cause: no dataset at all, or no items of the requested kind.
    const auto messageOf = [&](const std::string& folder) {
        try {
            PatchSampler sampler(folder, options);
        } catch (const Error& e) {
            return std::string(e.what());
        }
        return std::string("no error");
    };
    EXPECT_NE(messageOf(folder_ + "-missing").find("is not a dataset (no manifest.jsonl"), std::string::npos);
    options.families = {"no-such-family"};
    EXPECT_NE(messageOf(folder_).find("has no train items of the families no-such-family"),
              std::string::npos);
}

}  // namespace
}  // namespace dejag::data

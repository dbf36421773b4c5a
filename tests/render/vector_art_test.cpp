// The flat 2D scenes (render/vector_art.h): the fonts they need are installed, the type texture is
// anti-aliased coverage in one colour per line, the scenes depend on their seed only, and sub-pixel
// strokes alias as geometry does (broken into dashes at one sample a pixel, continuous in the truth).
#include "render/vector_art.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <memory>
#include <set>

#include "base/error.h"
#include "render/renderer.h"

namespace dejag::render {
namespace {

const GlContext& context() {
    static const std::unique_ptr<GlContext> instance = createOsMesaContext();
    return *instance;
}

TEST(VectorArt, EveryFontIsInstalledAndDistinct) {
    const std::vector<std::string>& fonts = typeFontFiles();
    EXPECT_GE(fonts.size(), 20u);
    EXPECT_EQ(std::set<std::string>(fonts.begin(), fonts.end()).size(), fonts.size());
    for (const std::string& f : fonts)
        EXPECT_TRUE(std::filesystem::exists(f)) << f << " (scripts/install-deps)";
}

TEST(VectorArt, TypeTextureIsCoverageInOneColourPerRow) {
    const TextureImage t = makeTypeTexture(512, 7, 6, 40);
    ASSERT_EQ(t.rgba.size(), size_t(512) * 512 * 4);
    size_t covered = 0, partial = 0;
    for (int y = 0; y < t.height; ++y) {
        const uint8_t* first = nullptr;
        for (int x = 0; x < t.width; ++x) {
            const uint8_t* p = &t.rgba[(size_t(y) * 512 + size_t(x)) * 4];
            if (p[3] == 0) continue;
            ++covered, partial += p[3] < 255;
            if (!first) first = p;
            // Filtering across a glyph's border never mixes in another colour.
            ASSERT_TRUE(p[0] == first[0] && p[1] == first[1] && p[2] == first[2]) << "row " << y;
        }
    }
    const double share = double(covered) / (512.0 * 512.0);
    EXPECT_GT(share, 0.03);
    EXPECT_LT(share, 0.6);
    EXPECT_GT(partial, covered / 10) << "FreeType's coverage is anti-aliased";
    EXPECT_EQ(makeTypeTexture(512, 7, 6, 40).rgba, t.rgba);
    EXPECT_NE(makeTypeTexture(512, 8, 6, 40).rgba, t.rgba);
    EXPECT_THROW(makeTypeTexture(512, 7, 40, 6), Error);
}

TEST(VectorArt, ScenesDependOnTheirSeedOnly) {
    for (const char* name : {"vector-art", "type"}) {
        SCOPED_TRACE(name);
        const Scene a = buildScene(name, {.seed = 11}), b = buildScene(name, {.seed = 11}),
                    c = buildScene(name, {.seed = 12});
        EXPECT_EQ(a.objects.size(), b.objects.size());
        EXPECT_EQ(a.triangleCount(), b.triangleCount());
        for (const SceneObject& o : a.objects) EXPECT_FALSE(o.material.lit) << o.name;
        Renderer ra(context(), a, 64, 64), rb(context(), b, 64, 64), rc(context(), c, 64, 64);
        const Frame fa = ra.render({}), fb = rb.render({}), fc = rc.render({});
        EXPECT_EQ(fa.pixels, fb.pixels);
        EXPECT_NE(fa.pixels, fc.pixels);
    }
}

// Every seed draws aliasing: the 1-sample frame disagrees with the truth on at least 1 % of the values
// (strokes under a pixel wide break into dashes, every edge steps).
TEST(VectorArt, EverySeedIsAliased) {
    for (const char* name : {"vector-art", "type"})
        for (uint64_t seed = 1; seed <= 4; ++seed) {
            SCOPED_TRACE(std::string(name) + " seed " + std::to_string(seed));
            const Scene scene = buildScene(name, {.seed = seed});
            Renderer renderer(context(), scene, 128, 128);
            const Frame aliased = renderer.render({});
            TruthOptions options;
            options.samples = 32;
            const Frame truth = renderer.renderTruth(0, options);
            size_t differing = 0;
            for (size_t i = 0; i < aliased.pixels.size(); ++i)
                differing += std::abs(aliased.pixels[i] - truth.pixels[i]) > 0.02f;
            EXPECT_GT(differing, aliased.pixels.size() / 100);
        }
}

}  // namespace
}  // namespace dejag::render

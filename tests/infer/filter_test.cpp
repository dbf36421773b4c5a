// The one face of every method (infer/filter.h): the factory builds each method of the table from its
// declared defaults and refuses what no method reads; through the face a method computes exactly what
// its class does; a chain is its stages applied in turn; a temporal method's reset() is a fresh start;
// a missing buffer is named. And frames from any channel names (infer/frame.h).
#include "infer/filter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <filesystem>
#include <functional>
#include <stdexcept>

#include "base/error.h"
#include "base/random.h"
#include "infer/fxaa.h"
#include "infer/taa.h"
#include "nn/model.h"
#include "tests/test_util.h"

namespace dejag::infer {
namespace {

// The shipped models by their models/... paths.
std::string modelPath(const std::string& path) {
    return std::string(DEJAG_SOURCE_DIR) + "/" + path;
}

FilterParameters withModels() {
    FilterParameters p;
    p.setPathResolver(modelPath);
    return p;
}

// A jagged frame: random steps, so FXAA and the CNN have edges to work on.
std::vector<float> jaggedColour(int width, int height, int channels, uint64_t seed) {
    std::vector<float> colour(size_t(width) * size_t(height) * size_t(channels));
    for (int y = 0; y < height; ++y)
        for (int x = 0; x < width; ++x)
            for (int c = 0; c < channels; ++c)
                colour[(size_t(y) * size_t(width) + size_t(x)) * size_t(channels) + size_t(c)] =
                    c == 3 ? 0.5f
                           : ((x + 2 * y) % 7 < 3 ? 0.9f : 0.1f) *
                                 (0.8f + 0.2f * float(unitInterval(
                                                    splitMix64(seed * 1000003 + uint64_t(y * width + x)))));
    return colour;
}

std::string errorOf(const std::function<void()>& f) {
    try {
        f();
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

TEST(Filter, EveryMethodOfTheTableIsMadeFromItsDefaults) {
    ASSERT_GE(filterMethods().size(), 4u);
    for (const MethodSpec& spec : filterMethods()) {
        SCOPED_TRACE(spec.name);
        EXPECT_FALSE(spec.summary.empty());
        std::unique_ptr<Filter> filter = makeFilter(spec.name, withModels());
        EXPECT_EQ(filter->name(), spec.name);
        EXPECT_EQ(filter->needs(), spec.needs);
        EXPECT_EQ(filter->uses(), spec.needs | spec.optional);
        EXPECT_EQ(filter->temporal(), spec.temporal);
        // Each declared parameter, given its own default, is read (none is declared but ignored).
        FilterParameters p = withModels();
        for (const ParameterSpec& parameter : spec.parameters) p.set(parameter.name, parameter.defaultValue);
        EXPECT_NO_THROW(makeFilter(spec.name, p));
    }
    const std::string listing = describeMethods();
    for (const MethodSpec& spec : filterMethods()) {
        EXPECT_NE(listing.find(spec.name + (spec.temporal ? "  (temporal" : "\n")), std::string::npos)
            << spec.name;
        for (const ParameterSpec& parameter : spec.parameters)
            EXPECT_NE(listing.find("    " + parameter.name + " = " + parameter.defaultValue),
                      std::string::npos)
                << spec.name << " " << parameter.name;
    }
}

TEST(Filter, TheFactoryRefusesWhatNoMethodReads) {
    EXPECT_NE(
        errorOf([] { makeFilter("blur", {}); }).find("the methods are none, fxaa, smaa, cnn, taa, taa-sobel"),
        std::string::npos);
    EXPECT_NE(errorOf([] { makeFilter("fxaa,", {}); }).find("empty method"), std::string::npos);
    FilterParameters tile;
    tile.set("tile", "64", "--tile");
    const std::string unused = errorOf([&] { makeFilter("fxaa", tile); });
    EXPECT_NE(unused.find("--tile: fxaa has no parameter 'tile'"), std::string::npos) << unused;
    EXPECT_NE(unused.find("preset"), std::string::npos) << "names what it takes: " << unused;
    // In a chain a parameter is fine if one method reads it.
    FilterParameters chain = withModels();
    chain.set("tile", "64", "--tile");
    chain.set("preset", "12", "--preset");
    EXPECT_NO_THROW(makeFilter("fxaa,cnn", chain));
    FilterParameters twice;
    twice.setAssignment("subpix=0.5");
    EXPECT_THROW(twice.setAssignment("subpix=0.25"), Error);
    EXPECT_THROW(twice.setAssignment("=1"), Error);
    EXPECT_THROW(twice.setAssignment("subpix"), Error);
    for (const char* bad :
         {"subpix=2", "subpix=nan", "subpix=x", "preset=7", "preset=12.5", "green-luma=maybe"}) {
        FilterParameters p;
        p.setAssignment(bad);
        EXPECT_THROW(makeFilter("fxaa", p), Error) << bad;
    }
    FilterParameters gate = withModels();
    gate.setAssignment("gate=1.5");
    EXPECT_NE(errorOf([&] { makeFilter("cnn", gate); }).find("--set gate=1.5"), std::string::npos);
}

TEST(Filter, AMethodThroughTheFaceComputesWhatItsClassDoes) {
    const int W = 61, H = 37;
    for (int channels : {3, 4}) {
        const std::vector<float> colour = jaggedColour(W, H, channels, 7);
        FilterParameters p;
        p.set("preset", "23");
        std::unique_ptr<Filter> face = makeFilter("fxaa", p);
        Frame frame;
        frame.width = W, frame.height = H, frame.channels = channels, frame.colour = colour.data();
        std::vector<float> viaFace(colour.size()), direct(colour.size());
        face->apply(frame, viaFace.data());
        FxaaOptions options;
        options.preset = 23;
        Fxaa fxaa(options);
        fxaa.apply(colour.data(), direct.data(), W, H, channels);
        EXPECT_EQ(viaFace, direct);
        EXPECT_EQ(face->figures().processedFraction, fxaa.processedFraction());
        // In place (out is the frame's colour), as bench filter runs it: the same result.
        std::vector<float> inPlace = colour;
        Frame same = frame;
        same.colour = inPlace.data();
        face->apply(same, inPlace.data());
        EXPECT_EQ(inPlace, direct);
        // "none" is the frame as it came, alpha included.
        std::vector<float> unchanged(colour.size());
        makeFilter("none", {})->apply(frame, unchanged.data());
        EXPECT_EQ(unchanged, colour);
        EXPECT_GE(face->figures().ms, 0.0);
        // A chain is its stages in turn (two and three stages: the ping-pong ends in out either way).
        for (int n : {2, 3}) {
            std::string methods = "fxaa";
            for (int k = 1; k < n; ++k) methods += ",fxaa";
            std::unique_ptr<Filter> chain = makeFilter(methods, p);
            ASSERT_EQ(chain->stages().size(), size_t(n));
            std::vector<float> chained(colour.size()), step = colour, next(colour.size());
            chain->apply(frame, chained.data());
            for (int k = 0; k < n; ++k) {
                fxaa.apply(step.data(), next.data(), W, H, channels);
                step.swap(next);
            }
            EXPECT_EQ(chained, step) << n << " stages";
        }
    }
}

TEST(Filter, ATemporalMethodKeepsItsHistoryUntilReset) {
    const int W = 40, H = 24;
    std::vector<float> depth(size_t(W) * H, 0.5f), motion(size_t(W) * H * 2, 0.0f);
    std::vector<std::vector<float>> colours;
    for (uint64_t k = 0; k < 3; ++k) colours.push_back(jaggedColour(W, H, 4, 100 + k));
    std::unique_ptr<Filter> face = makeFilter("taa", {});
    Taa taa;
    std::vector<float> viaFace(size_t(W) * H * 4), rgb(size_t(W) * H * 3), direct(size_t(W) * H * 3);
    for (int round = 0; round < 2; ++round) {
        for (const std::vector<float>& colour : colours) {
            Frame frame;
            frame.width = W, frame.height = H, frame.channels = 4;
            frame.colour = colour.data(), frame.depth = depth.data(), frame.motion = motion.data();
            face->apply(frame, viaFace.data());
            for (size_t p = 0; p < size_t(W) * H; ++p)
                for (int c = 0; c < 3; ++c) rgb[p * 3 + size_t(c)] = colour[p * 4 + size_t(c)];
            TaaFrame f;
            f.width = W, f.height = H, f.colour = rgb.data(), f.depth = depth.data(),
            f.motion = motion.data();
            taa.apply(f, direct.data());
            for (size_t p = 0; p < size_t(W) * H; ++p) {
                for (int c = 0; c < 3; ++c) ASSERT_EQ(viaFace[p * 4 + size_t(c)], direct[p * 3 + size_t(c)]);
                ASSERT_EQ(viaFace[p * 4 + 3], 0.5f) << "alpha passes through";
            }
        }
        face->reset();  // the second round starts as the first did
        taa.reset();
    }
    // Without the buffers it needs, it names the first one missing.
    Frame bare;
    bare.width = W, bare.height = H, bare.channels = 4, bare.colour = colours[0].data();
    EXPECT_NE(errorOf([&] { face->apply(bare, viaFace.data()); }).find("the depth buffer"),
              std::string::npos);
    EXPECT_THROW(makeFilter("taa", {})->apply(bare, viaFace.data()), Error);
}

TEST(Frame, ChannelsAreFoundByTheNamesGiven) {
    Image image(3, 2, {"C.R", "C.G", "C.B", "Z", "V.X", "V.Y"}, PixelType::Float);
    for (size_t p = 0; p < image.pixelCount(); ++p)
        for (int c = 0; c < 6; ++c) image.pixels[p * 6 + size_t(c)] = float(p) + 0.1f * float(c);
    ChannelMap map;
    map.assign("color=C.R,C.G,C.B");
    map.assign("depth=Z");
    map.assign("motion=-V.X,V.Y");
    FrameOptions options;
    options.channels = map;
    options.required = Buffer::Depth | Buffer::Motion;
    options.depthFar = 4;
    // The colour being the file's first three channels, the others pass through unless told otherwise.
    EXPECT_EQ(frameFromImage(image, options, "f.exr").frame().channels, 6);
    options.keepExtraChannels = false;
    const FrameData data = frameFromImage(image, options, "f.exr");
    const Frame frame = data.frame();
    ASSERT_EQ(frame.channels, 3) << "R G B (and an alpha beside them) only";
    EXPECT_EQ(data.colourNames, (std::vector<std::string>{"C.R", "C.G", "C.B"}));
    EXPECT_FLOAT_EQ(frame.colour[3], std::clamp(linearToSrgb(1.0f), 0.0f, 1.0f)) << "linear light encoded";
    EXPECT_FLOAT_EQ(frame.depth[1], float((1.0f + 0.3f) / 4.0));
    EXPECT_FLOAT_EQ(frame.motion[2], -(1.0f + 0.4f)) << "a leading '-' negates";
    EXPECT_FLOAT_EQ(frame.motion[3], 1.0f + 0.5f);
    EXPECT_EQ(frame.albedo, nullptr);
    EXPECT_FALSE(frame.has(Buffer::Ids));
    // A required buffer missing: the channel and how to name another.
    options.required = options.required | Buffer::Albedo;
    const std::string missing = errorOf([&] { frameFromImage(image, options, "f.exr"); });
    EXPECT_NE(missing.find("'f.exr' has no channel albedo.R for the albedo buffer"), std::string::npos)
        << missing;
    EXPECT_NE(missing.find("--channel albedo=NAME"), std::string::npos);
    EXPECT_NE(errorOf([&] { frameFromImage(image, FrameOptions{}, "f.exr"); }).find("no colour channel R"),
              std::string::npos);
    for (const char* bad : {"depth", "depth=", "depth=A,B", "motion=X", "color=R,G", "normal=N", "id=,"})
        EXPECT_THROW(map.assign(bad), Error) << bad;
    EXPECT_THROW(ChannelMap::preset("maya"), Error);
    EXPECT_EQ(ChannelMap::preset("blender").namesOf(Buffer::Depth),
              (std::vector<std::string>{"ViewLayer.Depth.Z"}));
    EXPECT_DOUBLE_EQ(largestFiniteDepth(image, map), 5.3f);
}

}  // namespace
}  // namespace dejag::infer

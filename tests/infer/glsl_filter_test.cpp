// The methods' GPU forms (infer/glsl_filter.h) against their CPU filters, through OSMesa's llvmpipe, on a
// rendered frame that never leaves the GPU between the renderer and the method: the import matches the
// CPU's sRGB encoding, and each form's output matches its CPU filter's on the same frame within 1/255.
#include "infer/glsl_filter.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "data/frame_image.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "tests/test_util.h"

namespace dejag::infer {
namespace {

constexpr int W = 100, H = 70;  // not a multiple of the networks' strides: the padding is exercised

std::vector<float> readBuffer(render::GlContext& context, unsigned buffer, size_t count) {
    const render::GlFunctions& gl = context.compute();
    std::vector<float> values(count);
    gl.MemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
    gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffer);
    gl.GetBufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(count * sizeof(float)), values.data());
    EXPECT_EQ(gl.GetError(), GLenum(GL_NO_ERROR));
    return values;
}

struct Difference {
    double largest = 0;
    int largest8bit = 0;
};

Difference compare(const std::vector<float>& a, const std::vector<float>& b) {
    Difference d;
    for (size_t i = 0; i < a.size(); ++i) {
        d.largest = std::max(d.largest, std::abs(double(a[i]) - double(b[i])));
        d.largest8bit =
            std::max(d.largest8bit, int(std::abs(std::lround(a[i] * 255.0f) - std::lround(b[i] * 255.0f))));
    }
    return d;
}

// A rendered frame imported on the GPU (and the same frame as the CPU reads it, for the import's check).
struct GpuFrame {
    std::unique_ptr<render::GlContext> context = render::createOsMesaContext();
    std::unique_ptr<GlslFrameImport> import;
    GlslFrame frame;
    std::vector<float> cpuEncoded;

    int width, height;

    explicit GpuFrame(const std::string& sceneName = "pipe", int w = W, int h = H) : width(w), height(h) {
        render::SceneOptions sceneOptions;
        sceneOptions.tiltedCamera = sceneName == "pipe";
        const render::Scene scene = render::buildScene(sceneName, sceneOptions);
        render::Renderer renderer(*context, scene, w, h);
        cpuEncoded = frameChannels(renderer.render({}), 0, 3, true);
        import = std::make_unique<GlslFrameImport>(*context);
        frame = import->run(renderer.textures(), w, h);
    }
};

TEST(GlslFilter, TheImportEncodesTheRenderedColourAsTheCpuDoes) {
    GpuFrame gpu;
    const std::vector<float> imported = readBuffer(*gpu.context, gpu.frame.colour, size_t(W) * H * 3);
    const Difference d = compare(imported, gpu.cpuEncoded);
    std::printf("import: largest |GPU - CPU| %.3g\n", d.largest);
    EXPECT_EQ(d.largest, 0);  // the same curve in the same float operations
    // Rows are flipped: the top row of the frame is the top of the picture (the pipe's sky is bright).
    EXPECT_EQ(d.largest8bit, 0);
}

// Runs each case's GPU form and CPU filter on the frame; returns how many values lie apart by more than
// 1e-5, summed over the cases (for the check that the frame exercises them).
struct Case {
    std::string method;
    FilterParameters parameters;
    double bound;
};

void expectMatches(GpuFrame& gpu, const std::vector<Case>& cases, const std::string& what) {
    const int w = gpu.width, h = gpu.height;
    const std::vector<float> frame = readBuffer(*gpu.context, gpu.frame.colour, size_t(w) * h * 3);
    for (const Case& c : cases) {
        std::string whyNot;
        const std::unique_ptr<GlslFilter> glsl =
            makeGlslFilter(*gpu.context, c.method, c.parameters, &whyNot);
        ASSERT_TRUE(glsl) << c.method << ": " << whyNot;
        EXPECT_EQ(glsl->differences(), "") << c.method;  // ungated: the two forms compute the same
        GlslBuffer out(*gpu.context);
        glsl->run(gpu.frame, out.ensure(frame.size()));
        const std::vector<float> gl = readBuffer(*gpu.context, out.id(), frame.size());
        const std::unique_ptr<Filter> cpuFilter = makeFilter(c.method, c.parameters);
        Frame cpuFrame;
        cpuFrame.width = w, cpuFrame.height = h, cpuFrame.channels = 3, cpuFrame.colour = frame.data();
        std::vector<float> cpu(frame.size());
        cpuFilter->apply(cpuFrame, cpu.data());
        const Difference d = compare(gl, cpu);
        size_t changed = 0;
        for (size_t i = 0; i < cpu.size(); ++i) changed += std::abs(cpu[i] - frame[i]) > 1.0f / 255;
        std::printf("%s, %s: largest |GPU - CPU| %.3g, 8-bit %d; %zu values changed by the method\n",
                    what.c_str(), c.method.c_str(), d.largest, d.largest8bit, changed);
        EXPECT_LE(d.largest, c.bound) << what << ", " << c.method;
        EXPECT_LE(d.largest8bit, 1) << what << ", " << c.method;
        // The method did change the frame, so the match says something.
        if (c.method != "none") {
            EXPECT_GT(changed, size_t(w * h) / 200) << what << ", " << c.method;
        }
    }
}

TEST(GlslFilter, EachGpuFormMatchesItsCpuFilter) {
    GpuFrame gpu;
    const std::string models = testing::sourcePath("models/");
    std::vector<Case> cases;
    cases.push_back({"none", {}, 0.0});
    cases.push_back({"fxaa", {}, 1e-6});
    cases.push_back({"fxaa", {{"preset", "39"}, {"green-luma", "true"}}, 1e-6});
    for (const char* model : {"dejag-fast", "seed2020-gray", "dejag-guided"})
        cases.push_back({"cnn",
                         {{"model", models + model + ".safetensors"}, {"gate", "off"}, {"precision", "fp32"}},
                         1e-4});
    expectMatches(gpu, cases, "pipe");
}

// SMAA on frames with long runs, diagonals and corners: the edges and weights are the CPU's; the blend
// may round apart where the CPU's SIMD kernels fuse multiply-adds.
TEST(GlslFilter, SmaaMatchesTheCpuFilterForEveryPreset) {
    for (const char* scene : {"hard-edges", "text-wall", "vector-art"}) {
        GpuFrame gpu(scene, 200, 150);
        std::vector<Case> cases;
        for (const char* preset : {"low", "medium", "high", "ultra"})
            cases.push_back({"smaa", {{"preset", preset}}, 1e-5});
        cases.push_back({"smaa", {{"edges", "colour"}, {"linear", "off"}}, 1e-5});
        cases.push_back({"smaa", {{"corner-rounding", "0"}, {"search-steps", "3"}}, 1e-5});
        expectMatches(gpu, cases, scene);
    }
}

// A rendered sequence with every buffer, read back for the CPU and imported on the GPU: the import equals
// frameFromImage's buffers bit for bit, and taa-hq's GPU form follows its CPU filter frame after frame
// within 1/255 (its history stays on the GPU; the two round apart where the CPU's kernels fuse
// multiply-adds).
TEST(GlslFilter, EveryTaaFollowsItsCpuFilterOverAMovingSequence) {
    const auto context = render::createOsMesaContext();
    constexpr int w = 96, h = 64, frames = 10;
    struct Method {
        std::string name;
        FilterParameters parameters;
        std::unique_ptr<GlslFilter> gpu;
        std::unique_ptr<Filter> cpu;
        std::unique_ptr<GlslBuffer> out;
    };
    std::vector<Method> methods;
    for (auto& [name, parameters] : std::vector<std::pair<std::string, FilterParameters>>{
             {"taa-hq", {}},
             {"taa-hq", {{"sharpen", "0.5"}, {"history-filter", "bilinear"}}},
             {"taa", {}},
             {"taa", {{"unjitter", "false"}, {"sharpen", "false"}}},
             {"taa-sobel", {}},
             {"taa-sobel", {{"unjitter", "false"}, {"feedback-min", "0.5"}}},
             {"cnn-temporal",
              {{"model", testing::sourcePath("models/dejag-temporal.safetensors")},
               {"gate", "off"},
               {"precision", "fp32"}}}}) {
        Method m{name, parameters, nullptr, makeFilter(name, parameters),
                 std::make_unique<GlslBuffer>(*context)};
        std::string whyNot;
        m.gpu = makeGlslFilter(*context, name, parameters, &whyNot);
        ASSERT_TRUE(m.gpu) << whyNot;
        EXPECT_TRUE(m.gpu->temporal());
        methods.push_back(std::move(m));
    }
    GlslFrameImport import(*context);
    for (const char* sceneName : {"corridor", "atrium", "hairball-rotating"}) {
        const render::Scene scene = render::buildScene(sceneName);
        render::Renderer renderer(*context, scene, w, h);
        std::vector<double> largest(methods.size(), 0.0);
        std::vector<int> largest8bit(methods.size(), 0);
        for (Method& m : methods) m.gpu->reset(), m.cpu->reset();
        for (int t = 0; t < frames; ++t) {
            render::FrameRequest request;
            request.time = t, request.previousTime = t - 1;
            request.jitter = render::jitterPixels(unsigned(t % 16), 1.0);
            request.previousJitter = render::jitterPixels(unsigned((t + 15) % 16), 1.0);
            request.buffers = render::BufferSet::all();
            const render::Frame rendered = renderer.render(request);
            FrameOptions options;
            options.wanted =
                Buffer::Albedo | Buffer::Depth | Buffer::Motion | Buffer::Ids | Buffer::PreviousDepth;
            options.depthFar = scene.far;
            options.keepExtraChannels = false;  // the colour alone, as the GPU frame holds it
            FrameData data = frameFromImage(imageFromFrame(rendered), options, "frame");
            data.hasJitter = true, data.jitter[0] = float(request.jitter.x),
            data.jitter[1] = float(-request.jitter.y);
            GlslFrame frame = import.run(renderer.textures(), w, h, options.wanted, float(scene.far));
            frame.hasJitter = true, frame.jitter[0] = data.jitter[0], frame.jitter[1] = data.jitter[1];
            if (t == 3) {  // the import, buffer by buffer
                const std::pair<unsigned, const std::vector<float>*> buffers[] = {
                    {frame.colour, &data.colour}, {frame.albedo, &data.albedo},
                    {frame.depth, &data.depth},   {frame.motion, &data.motion},
                    {frame.ids, &data.ids},       {frame.previousDepth, &data.previousDepth}};
                for (const auto& [buffer, values] : buffers)
                    EXPECT_EQ(readBuffer(*context, buffer, values->size()), *values) << sceneName;
            }
            for (size_t k = 0; k < methods.size(); ++k) {
                Method& m = methods[k];
                std::vector<float> cpuOut(data.colour.size());
                m.cpu->apply(data.frame(), cpuOut.data());
                m.gpu->run(frame, m.out->ensure(cpuOut.size()));
                const Difference d = compare(readBuffer(*context, m.out->id(), cpuOut.size()), cpuOut);
                largest[k] = std::max(largest[k], d.largest),
                largest8bit[k] = std::max(largest8bit[k], d.largest8bit);
            }
        }
        for (size_t k = 0; k < methods.size(); ++k) {
            std::printf("%s, %s%s: over %d frames, largest |GPU - CPU| %.3g, 8-bit %d\n", sceneName,
                        methods[k].name.c_str(), k % 2 ? " (variant)" : "", frames, largest[k],
                        largest8bit[k]);
            EXPECT_LE(largest[k], 1e-4) << sceneName << ", " << methods[k].name;
            EXPECT_LE(largest8bit[k], 1) << sceneName << ", " << methods[k].name;
        }
    }
}

// taa-hq on made-up buffers that reject the history both ways: where the previous depths are all nearer
// than the current ones, and where they are all farther; with motion that reads between texels.
TEST(GlslFilter, TaaHqRejectsADisoccludedHistoryAsTheCpuDoes) {
    const auto context = render::createOsMesaContext();
    constexpr int w = 24, h = 16;
    const size_t pixels = size_t(w) * h;
    const std::unique_ptr<GlslFilter> gpu = makeGlslFilter(*context, "taa-hq", {}, nullptr);
    const std::unique_ptr<Filter> cpu = makeFilter("taa-hq", {});
    GlslBuffer colourBuffer(*context), motionBuffer(*context), depthBuffer(*context),
        previousBuffer(*context), out(*context);
    const auto upload = [&](GlslBuffer& buffer, const std::vector<float>& values) {
        const render::GlFunctions& gl = context->compute();
        gl.BindBuffer(GL_SHADER_STORAGE_BUFFER, buffer.ensure(values.size()));
        gl.BufferSubData(GL_SHADER_STORAGE_BUFFER, 0, GLsizeiptr(values.size() * sizeof(float)),
                         values.data());
        return buffer.id();
    };
    double largest = 0;
    for (int t = 0; t < 6; ++t) {
        std::vector<float> colour(pixels * 3), motion(pixels * 2), depth(pixels), previous(pixels);
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                const size_t p = size_t(y) * w + size_t(x);
                for (int k = 0; k < 3; ++k)
                    colour[3 * p + k] = float((x * 7 + y * 3 + k * 5 + t * 11) % 17) / 16.0f;
                motion[2 * p] = y < h / 2 ? 0.0f : 0.37f * float(t % 3);
                motion[2 * p + 1] = x < w / 2 ? 0.0f : -0.21f;
                depth[p] = 1.0f;
                // Columns 4-7: the previous depths all nearer (a disocclusion); 14-17: all farther.
                previous[p] = (x >= 4 && x < 8 && t % 2)          ? 0.5f
                              : (x >= 14 && x < 18 && t % 2 == 0) ? 2.0f
                                                                  : 1.0f;
            }
        GlslFrame frame;
        frame.width = w, frame.height = h;
        frame.colour = upload(colourBuffer, colour), frame.motion = upload(motionBuffer, motion);
        frame.depth = upload(depthBuffer, depth), frame.previousDepth = upload(previousBuffer, previous);
        frame.hasJitter = true, frame.jitter[0] = 0.3f * float(t % 2), frame.jitter[1] = -0.2f;
        Frame cpuFrame;
        cpuFrame.width = w, cpuFrame.height = h, cpuFrame.colour = colour.data(),
        cpuFrame.motion = motion.data();
        cpuFrame.depth = depth.data(), cpuFrame.previousDepth = previous.data();
        cpuFrame.hasJitter = true, cpuFrame.jitter[0] = frame.jitter[0], cpuFrame.jitter[1] = frame.jitter[1];
        std::vector<float> cpuOut(pixels * 3);
        cpu->apply(cpuFrame, cpuOut.data());
        gpu->run(frame, out.ensure(cpuOut.size()));
        const Difference d = compare(readBuffer(*context, out.id(), cpuOut.size()), cpuOut);
        largest = std::max(largest, d.largest);
    }
    std::printf("made-up disocclusions: largest |GPU - CPU| %.3g over 6 frames\n", largest);
    EXPECT_LE(largest, 1e-5);
}

// The files `dejag export --glsl METHOD` writes: every pass compiles, the description names each pass's
// shader and bindings, the tables are the sizes the passes index; a network or a chain is refused.
TEST(GlslFilter, MethodFilesCompileAndDescribeTheirPasses) {
    const auto context = render::createOsMesaContext();
    const std::pair<std::string, FilterParameters> cases[] = {{"fxaa", {}},
                                                              {"smaa", {{"preset", "high"}}},
                                                              {"taa", {}},
                                                              {"taa-sobel", {}},
                                                              {"taa-hq", {{"sharpen", "0.5"}}}};
    const size_t passes[] = {1, 3, 3, 5, 3};
    for (size_t k = 0; k < std::size(cases); ++k) {
        const auto& [method, parameters] = cases[k];
        const GlslMethodFiles files = glslMethodFiles(method, parameters);
        EXPECT_EQ(files.passes.size(), passes[k]) << method;
        ASSERT_EQ(files.description["passes"].size(), files.passes.size()) << method;
        for (size_t i = 0; i < files.passes.size(); ++i) {
            EXPECT_EQ(files.description["passes"][i]["shader"], files.passes[i].first) << method;
            EXPECT_FALSE(files.description["passes"][i]["bindings"].empty()) << method;
            context->gl().DeleteProgram(render::compileComputeProgram(
                context->compute(), files.passes[i].second, files.passes[i].first));
        }
    }
    const GlslMethodFiles smaa = glslMethodFiles("smaa", {{"preset", "high"}});  // 16 search steps
    ASSERT_EQ(smaa.tables.size(), 2u);
    EXPECT_EQ(smaa.tables[0].second.size(), size_t(16 * 33 * 33 * 2));
    EXPECT_EQ(smaa.tables[1].second.size(), size_t(16 * 20 * 20 * 2));
    EXPECT_THROW(glslMethodFiles("cnn", {}), Error);
    EXPECT_THROW(glslMethodFiles("fxaa,smaa", {}), Error);
    EXPECT_THROW(glslMethodFiles("smaa", {{"predication", "on"}}), Error);
    EXPECT_THROW(glslMethodFiles("fxaa", {{"gate", "off"}}), Error);
}

TEST(GlslFilter, MethodsWithoutAGpuFormSayWhyAndBadParametersAreRefused) {
    const auto context = render::createOsMesaContext();
    std::string whyNot;
    const std::string temporal = testing::sourcePath("models/dejag-temporal.safetensors");
    EXPECT_EQ(makeGlslFilter(*context, "cnn-temporal", {{"model", temporal}, {"clip", "on"}}, &whyNot),
              nullptr);
    EXPECT_NE(whyNot.find("no GPU form"), std::string::npos) << whyNot;
    whyNot.clear();
    EXPECT_EQ(makeGlslFilter(*context, "taa", {{"motion-blur", "true"}}, &whyNot), nullptr);
    EXPECT_NE(whyNot.find("motion blur"), std::string::npos) << whyNot;
    EXPECT_EQ(makeGlslFilter(*context, "smaa", {{"predication", "on"}}, &whyNot), nullptr);
    EXPECT_NE(whyNot.find("depth"), std::string::npos) << whyNot;
    EXPECT_THROW(makeGlslFilter(*context, "smaa", {{"search-steps", "0"}}, &whyNot), Error);
    EXPECT_THROW(makeGlslFilter(*context, "fxaa", {{"preset", "7"}}, &whyNot), Error);
    EXPECT_THROW(makeGlslFilter(*context, "fxaa", {{"gate", "off"}}, &whyNot), Error);
    EXPECT_THROW(makeGlslFilter(*context, "no-such-method", {}, &whyNot), Error);
    EXPECT_THROW(makeGlslFilter(*context, "fxaa,cnn", {}, &whyNot), Error);
    // The gated CPU form and the whole-frame GPU form differ, and the GPU form says so.
    const std::unique_ptr<GlslFilter> gated = makeGlslFilter(
        *context, "cnn", {{"model", testing::sourcePath("models/dejag-fast.safetensors")}}, &whyNot);
    ASSERT_TRUE(gated);
    EXPECT_NE(gated->differences().find("gate"), std::string::npos);
}

}  // namespace
}  // namespace dejag::infer

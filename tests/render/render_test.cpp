// The renderer on OSMesa: jitter, buffers, motion vectors against analytic reprojection, IDs,
// determinism, and the accumulated truth (converged, and every scene actually aliased).
#include "render/renderer.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <set>

#include "base/error.h"
#include "render/fourier_texture.h"
#include "render/halton.h"
#include "render/scene.h"

namespace dejag::render {
namespace {

// One OSMesa context for the whole test program.
const GlContext& context() {
    static const std::unique_ptr<GlContext> instance = createOsMesaContext();
    return *instance;
}

double psnr(const Frame& a, const Frame& b) {
    EXPECT_EQ(a.pixels.size(), b.pixels.size());
    double squared = 0;
    for (size_t i = 0; i < a.pixels.size(); ++i) {
        const double d = double(a.pixels[i]) - double(b.pixels[i]);
        squared += d * d;
    }
    const double mse = squared / double(a.pixels.size());
    return mse > 0 ? 10 * std::log10(1.0 / mse) : INFINITY;
}

float channel(const Frame& f, int x, int y, const std::string& name) {
    const auto it = std::find(f.channelNames.begin(), f.channelNames.end(), name);
    EXPECT_NE(it, f.channelNames.end()) << name;
    return f.pixels[(size_t(y) * size_t(f.width) + size_t(x)) * size_t(f.channels()) +
                    size_t(it - f.channelNames.begin())];
}

TEST(Halton, FirstSixteenPointsAreTheThesisTable) {
    const double table[16][2] = {{0, 0},           {.5, .666667},    {.25, .333333},   {.75, .222222},
                                 {.125, .888889},  {.625, .555556},  {.375, .111111},  {.875, .777778},
                                 {.0625, .444444}, {.5625, .074074}, {.3125, .740741}, {.8125, .407407},
                                 {.1875, .296296}, {.6875, .962963}, {.4375, .629630}, {.9375, .185185}};
    for (unsigned i = 0; i < 16; ++i) {
        const Vec2 p = haltonPoint(i);
        EXPECT_NEAR(p.x, table[i][0], 1e-6) << i;
        EXPECT_NEAR(p.y, table[i][1], 1e-6) << i;
    }
    EXPECT_DOUBLE_EQ(jitterPixels(1, 1.7).x, 0.0);  // x = 0.5 is the pixel centre
    EXPECT_NEAR(jitterPixels(0, 1.7).x, -0.85, 1e-12);
}

TEST(Buffers, ParseNamesAndRefuseUnknownOnes) {
    const BufferSet all = BufferSet::parse("color,albedo,depth,motion,id,prevdepth");
    EXPECT_EQ(all.channelNames().size(), 11u);
    EXPECT_EQ(BufferSet::parse("depth").channelNames(), std::vector<std::string>{"depth.Z"});
    EXPECT_THROW(BufferSet::parse("colour,normals"), Error);
    EXPECT_THROW(BufferSet::parse(""), Error);
}

TEST(Scenes, EveryCatalogueSceneBuildsWithUniqueIds) {
    for (const SceneInfo& info : sceneCatalogue()) {
        SCOPED_TRACE(info.name);
        const Scene scene = buildScene(info.name);
        ASSERT_FALSE(scene.objects.empty());
        std::set<uint32_t> ids;
        for (const SceneObject& o : scene.objects) {
            ids.insert(o.id);
            ASSERT_LT(size_t(o.mesh), scene.meshes.size());
            EXPECT_GT(scene.meshes[size_t(o.mesh)].triangleCount(), 0u);
        }
        EXPECT_EQ(ids.size(), scene.objects.size());
        EXPECT_EQ(*ids.begin(), 1u);
    }
    EXPECT_THROW(buildScene("teapot"), Error);
    EXPECT_THROW(parseSampler("cubic"), Error);
}

TEST(Render, OnlyTheRequestedBuffersAndTheSameBitsEveryTime) {
    const Scene scene = buildScene("random", {.seed = 3});
    FrameRequest request;
    request.time = 5, request.previousTime = 4, request.jitter = jitterPixels(5, 1.7);
    request.buffers = BufferSet::all();
    Renderer first(context(), scene, 96, 72);
    const Frame a = first.render(request), b = first.render(request);
    Renderer second(context(), scene, 96, 72);
    const Frame c = second.render(request);
    EXPECT_EQ(a.channels(), 11);
    EXPECT_EQ(a.pixels, b.pixels);
    EXPECT_EQ(a.pixels, c.pixels);
    request.buffers = BufferSet::parse("depth,id");
    const Frame d = first.render(request);
    EXPECT_EQ(d.channelNames, (std::vector<std::string>{"depth.Z", "id.ID"}));
    for (int y = 0; y < 72; y += 7)
        for (int x = 0; x < 96; x += 5) {
            EXPECT_EQ(channel(d, x, y, "depth.Z"), channel(a, x, y, "depth.Z"));
            EXPECT_EQ(channel(d, x, y, "id.ID"), channel(a, x, y, "id.ID"));
        }
}

TEST(Render, IdsCountTheObjects) {
    const Scene scene = buildScene("sphere");  // floor + sphere + background
    Renderer renderer(context(), scene, 160, 120);
    FrameRequest request;
    request.buffers = BufferSet::parse("id");
    const Frame f = renderer.render(request);
    std::set<float> ids(f.pixels.begin(), f.pixels.end());
    EXPECT_EQ(ids, (std::set<float>{0.0f, 1.0f, 2.0f}));
}

// Follows each interior pixel's motion vector back and compares it with where the same surface point was
// in the previous frame: the point comes from this frame's depth buffer (unprojected with the pose at
// `time`), `previousWorld` moves it to where it was one frame earlier, and `previousViewProjection`
// projects it. Interior: an object's pixel whose 3x3 has one object ID and no depth jump. Returns the
// worst difference in pixels and how many pixels were checked.
std::pair<double, int> motionError(const Frame& f, const Scene& scene, double time,
                                   const std::function<Vec3(const Vec3&)>& previousWorld,
                                   const Mat4& previousViewProjection) {
    const int W = f.width, H = f.height;
    const CameraPose now = scene.cameraAt(time);
    const Vec3 forward = normalize(now.target - now.eye), side = normalize(cross(forward, now.up)),
               up = cross(side, forward);
    const double tanHalf = std::tan(now.fovY / 2), aspect = double(W) / H;
    double worst = 0;
    int checked = 0;
    for (int y = 1; y < H - 1; ++y)
        for (int x = 1; x < W - 1; ++x) {
            const float id = channel(f, x, y, "id.ID"), depth = channel(f, x, y, "depth.Z");
            bool interior = id != 0;  // not the background
            for (int dy = -1; dy <= 1 && interior; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    interior = interior && channel(f, x + dx, y + dy, "id.ID") == id &&
                               std::abs(channel(f, x + dx, y + dy, "depth.Z") - depth) < 0.05 * depth;
            if (!interior) continue;
            const double ndcX = 2 * (x + 0.5) / W - 1, ndcY = 1 - 2 * (y + 0.5) / H;
            const Vec3 world = now.eye + side * (ndcX * depth * tanHalf * aspect) +
                               up * (ndcY * depth * tanHalf) + forward * double(depth);
            const auto clip = previousViewProjection.apply(previousWorld(world));
            const double px = (clip[0] / clip[3] + 1) / 2 * W, py = (1 - clip[1] / clip[3]) / 2 * H;
            worst = std::max({worst, std::abs((x + 0.5) - px - channel(f, x, y, "motion.X")),
                              std::abs((y + 0.5) - py - channel(f, x, y, "motion.Y"))});
            ++checked;
        }
    return {worst, checked};
}

Mat4 viewProjection(const CameraPose& pose, double aspect, const Scene& scene) {
    return Mat4::perspective(pose.fovY, aspect, scene.near, scene.far) *
           Mat4::lookAt(pose.eye, pose.target, pose.up);
}

// A static scene seen by a moving camera: the point did not move, the camera did.
TEST(Render, MotionVectorsReprojectThePreviousFrame) {
    Scene scene;
    scene.addObject("floor", scene.addMesh(makeBox({30, 0.2, 30})), Material{}, [](double) {
        return Mat4::translation({0, -0.1, 0});
    });
    scene.addObject("box", scene.addMesh(makeBox({1, 2, 1.5})), Material{}, [](double) {
        return Mat4::translation({0.5, 1, -1}) * Mat4::rotation({0, 1, 0}, 0.4);
    });
    scene.addObject("wall", scene.addMesh(makeQuad(30, 10)), Material{}, [](double) {
        return Mat4::translation({0, 5, -8});
    });
    scene.camera = [](double t) {
        return CameraPose{
            {0.4 * t, 2.0 + 0.15 * t, 6 - 0.3 * t}, {0.2 * t, 0.8, 0}, {0, 1, 0}, 50 * kPi / 180};
    };
    const int W = 200, H = 150;
    Renderer renderer(context(), scene, W, H);
    FrameRequest request;
    request.time = 1, request.previousTime = 0, request.buffers = BufferSet::parse("depth,motion,id");
    const Frame f = renderer.render(request);
    const auto [worst, checked] = motionError(
        f, scene, 1, [](const Vec3& p) { return p; },
        viewProjection(scene.cameraAt(0), double(W) / H, scene));
    EXPECT_GT(checked, W * H / 2);
    EXPECT_LT(worst, 0.01) << "pixels";
}

// A moving object seen by a still camera: its motion comes from its own previous transform.
TEST(Render, MotionVectorsFollowAMovingObject) {
    Scene scene;
    auto translation = [](double t) { return Vec3{-1.0 + 0.15 * t, 0.2 * t, -0.1 * t}; };
    auto angle = [](double t) { return 0.3 + 0.05 * t; };
    scene.addObject("box", scene.addMesh(makeBox({1.5, 1.2, 1.0})), Material{}, [=](double t) {
        return Mat4::translation(translation(t)) * Mat4::rotation({0, 1, 0}, angle(t));
    });
    scene.camera = [](double) { return CameraPose{{0, 1, 5}, {0, 0, 0}, {0, 1, 0}, 45 * kPi / 180}; };
    const int W = 160, H = 120;
    Renderer renderer(context(), scene, W, H);
    FrameRequest request;
    request.time = 3, request.previousTime = 2, request.buffers = BufferSet::parse("depth,motion,id");
    const Frame f = renderer.render(request);
    // Back to object space at t = 3, then out again with the transform of t = 2.
    auto previousWorld = [&](const Vec3& world) {
        const Vec3 local = Mat4::rotation({0, 1, 0}, -angle(3)).transformPoint(world - translation(3));
        return translation(2) + Mat4::rotation({0, 1, 0}, angle(2)).transformPoint(local);
    };
    const auto [worst, checked] =
        motionError(f, scene, 3, previousWorld, viewProjection(scene.cameraAt(3), double(W) / H, scene));
    EXPECT_GT(checked, 500);
    EXPECT_LT(worst, 0.01) << "pixels";
}

// A one-pixel-wide line: the camera jitter moves it by the expected sub-pixel offset (+x right, +y up).
TEST(Render, JitterMovesALineByTheExpectedSubPixelOffset) {
    const int size = 64;
    const double pixel = 2 * 10.0 * std::tan(kPi / 4) / size;  // world units per pixel at distance 10
    Scene scene;
    scene.background = {0, 0, 0};
    Material white;
    white.colour = {1, 1, 1}, white.lit = false;
    // A vertical line over pixel column 32 and a horizontal one over row 31 (just above the centre).
    scene.addObject("vertical", scene.addMesh(makeQuad(pixel, 8 * pixel)), white, [=](double) {
        return Mat4::translation({pixel / 2, -12 * pixel, -10});
    });
    scene.addObject("horizontal", scene.addMesh(makeQuad(8 * pixel, pixel)), white, [=](double) {
        return Mat4::translation({-12 * pixel, pixel / 2, -10});
    });
    scene.camera = [](double) { return CameraPose{{0, 0, 0}, {0, 0, -1}, {0, 1, 0}, kPi / 2}; };
    Renderer renderer(context(), scene, size, size);
    auto litColumn = [&](double jitterX) {
        FrameRequest r;
        r.jitter = {jitterX, 0};
        const Frame f = renderer.render(r);
        std::vector<int> columns;
        for (int x = 0; x < size; ++x)
            if (channel(f, x, 44, "R") > 0.5f) columns.push_back(x);
        return columns;
    };
    auto litRow = [&](double jitterY) {
        FrameRequest r;
        r.jitter = {0, jitterY};
        const Frame f = renderer.render(r);
        std::vector<int> rows;
        for (int y = 0; y < size; ++y)
            if (channel(f, 20, y, "R") > 0.5f) rows.push_back(y);
        return rows;
    };
    EXPECT_EQ(litColumn(0.0), std::vector<int>{32});
    EXPECT_EQ(litColumn(0.4), std::vector<int>{32});
    EXPECT_EQ(litColumn(0.6), std::vector<int>{33});
    EXPECT_EQ(litColumn(-0.4), std::vector<int>{32});
    EXPECT_EQ(litColumn(-0.6), std::vector<int>{31});
    EXPECT_EQ(litRow(0.0), std::vector<int>{31});
    EXPECT_EQ(litRow(0.4), std::vector<int>{31});
    EXPECT_EQ(litRow(0.6), std::vector<int>{30});  // +y is up: the line moves to the row above
    EXPECT_EQ(litRow(-0.6), std::vector<int>{32});
}

// Every scene is aliased: the 1-sample frame is far from the truth, while 128 and 256 samples agree
// (their difference moves the aliased frame's PSNR by < 0.1 dB).
class EveryScene : public ::testing::TestWithParam<std::string> {};

TEST_P(EveryScene, IsAliasedAndItsTruthConverged) {
    const Scene scene = buildScene(GetParam());
    Renderer renderer(context(), scene, 96, 72);
    const Frame aliased = renderer.render({});
    TruthOptions options;
    options.samples = 128;
    const Frame truth128 = renderer.renderTruth(0, options);
    options.samples = 256;
    const Frame truth256 = renderer.renderTruth(0, options);
    const double aliasedPsnr = psnr(aliased, truth256), truthPsnr = psnr(truth128, truth256);
    EXPECT_LT(std::abs(psnr(aliased, truth128) - aliasedPsnr), 0.1);
    EXPECT_LT(aliasedPsnr + 10, truthPsnr)
        << "aliased " << aliasedPsnr << " dB, 128 vs 256 samples " << truthPsnr;
}

// The rotating hairballs are the static ones at time 0, so they are not drawn twice here.
std::vector<std::string> sceneNames() {
    std::vector<std::string> names;
    for (const SceneInfo& info : sceneCatalogue())
        if (info.name.find("-rotating") == std::string::npos) names.push_back(info.name);
    return names;
}

INSTANTIATE_TEST_SUITE_P(Scenes, EveryScene, ::testing::ValuesIn(sceneNames()),
                         [](const ::testing::TestParamInfo<std::string>& param) {
                             std::string name = param.param;
                             std::replace(name.begin(), name.end(), '-', '_');
                             return name;
                         });

// Adaptive truth: scores against it within 0.1 dB of the full truth, with at least 3x fewer tile-samples
// on scenes with open areas.
TEST(Truth, AdaptiveMatchesFullTruthWithFewerSamples) {
    for (const std::string name : {"pipe", "sphere"}) {
        SCOPED_TRACE(name);
        const Scene scene = buildScene(name);
        Renderer renderer(context(), scene, 200, 150);
        const Frame aliased = renderer.render({});
        TruthOptions options;
        const Frame full = renderer.renderTruth(0, options);
        options.adaptive = true;
        TruthStats stats;
        const Frame adaptive = renderer.renderTruth(0, options, &stats);
        EXPECT_LT(std::abs(psnr(aliased, full) - psnr(aliased, adaptive)), 0.1);
        EXPECT_GE(stats.saving(), 3.0);
        EXPECT_EQ(stats.samples, 128);
        EXPECT_EQ(stats.fullTileSamples, int64_t(stats.tiles) * 128);
    }
}

TEST(Truth, GaussianFilterIsAConvergedTruthToo) {
    const Scene scene = buildScene("pipe");
    Renderer renderer(context(), scene, 96, 72);
    TruthOptions options;
    options.filter = PixelFilter::Gaussian;
    const Frame a = renderer.renderTruth(0, options);
    options.samples = 256;
    const Frame b = renderer.renderTruth(0, options);
    EXPECT_GT(psnr(a, b), 50.0);
}

TEST(Render, Msaa4xIsCloserToTheTruthOnEdgesAndLeavesTheOtherBuffersAlone) {
    const Scene scene = buildScene("pipe");
    Renderer renderer(context(), scene, 128, 96);
    FrameRequest request;
    request.buffers = BufferSet::parse("color");
    const Frame aliased = renderer.render(request);
    request.msaa = 4;
    const Frame msaa = renderer.render(request);
    const Frame truth = renderer.renderTruth(0, TruthOptions{});
    EXPECT_GT(psnr(msaa, truth), psnr(aliased, truth) + 3.0);
    request.buffers = BufferSet::parse("color,depth,id");
    const Frame withBuffers = renderer.render(request);
    request.msaa = 1;
    const Frame single = renderer.render(request);
    for (int y = 0; y < 96; y += 3)
        for (int x = 0; x < 128; x += 3) {
            EXPECT_EQ(channel(withBuffers, x, y, "depth.Z"), channel(single, x, y, "depth.Z"));
            EXPECT_EQ(channel(withBuffers, x, y, "id.ID"), channel(single, x, y, "id.ID"));
            EXPECT_EQ(channel(withBuffers, x, y, "R"), channel(msaa, x, y, "R"));
        }
    request.msaa = 3;
    EXPECT_THROW(renderer.render(request), Error);
}

// A square quad filling a square view, facing the camera, turned by `angle` about the view axis (and made
// 1.5 times larger when turned, so it still fills the view), its uv repeating `repeats` times across it:
// uv is affine in the pixel, so the CPU reference of a sampler can be evaluated at every pixel.
struct FrontQuad {
    Scene scene;
    double half = 1, angle = 0;
    Vec2 repeats;
    // uv at pixel (x, row) of a size x size frame, and its derivatives a pixel.
    Vec2 uv(double x, double row, int size) const {
        const double X = 2 * (x + 0.5) / size - 1, Y = 1 - 2 * (row + 0.5) / size;
        const double c = std::cos(angle), s = std::sin(angle);
        const double local[2] = {c * X + s * Y, -s * X + c * Y};
        return {(local[0] + half) / (2 * half) * repeats.x, (half - local[1]) / (2 * half) * repeats.y};
    }
};

FrontQuad frontQuad(const TextureImage& texture, Sampler sampler, Vec2 repeats, double angle) {
    FrontQuad q;
    q.angle = angle, q.repeats = repeats, q.half = angle == 0 ? 1.0 : 1.5;
    q.scene.name = "front quad";
    q.scene.textures = {texture};
    q.scene.sampler = sampler;
    Mesh quad;
    quad.append(makeQuad(2 * q.half, 2 * q.half, repeats.x, repeats.y), Mat4::rotation({0, 0, 1}, angle));
    Material m;
    m.colour = {1, 1, 1}, m.lit = false, m.pattern = Pattern::Texture, m.texture = 0;
    q.scene.addObject("quad", q.scene.addMesh(std::move(quad)), m);
    q.scene.camera = [](double) {
        CameraPose pose;
        pose.eye = {0, 0, 2}, pose.target = {0, 0, 0}, pose.fovY = 2 * std::atan(0.5);
        return pose;
    };
    return q;
}

// The renderer's Fourier sampler (the shader) against FourierTexture::sample (double) at every pixel of
// a front-facing quad, magnified, minified, anisotropic and turned.
// Where a set holds too little of its energy (noise), the pixels read trilinearly: the same values as the
// trilinear sampler's.
TEST(Render, FourierSamplerMatchesItsCpuReference) {
    const int size = 64;
    struct Case {
        const char* texture;
        Vec2 repeats;
        double angle;
        int fallbacks[2];  // pixels that read the MIP chain with 1 and with 8 probes
    };
    // (No footprint at a whole level of detail, where float and double may pick different levels.) One
    // probe reads the bands isotropically (the thesis); eight along the major axis (the default).
    for (const int probes : {1, 8})
        for (const Case& c :
             {Case{"bricks", {0.3, 0.3}, 0, {0, 0}}, Case{"bricks", {1.3, 1.3}, 0, {0, 0}},
              Case{"bricks", {4.4, 4.4}, 0, {0, 0}}, Case{"bricks", {7.1, 1.9}, 0.5, {0, 0}},
              Case{"bricks", {3.3, 1.3}, 1.2, {0, 0}}, Case{"bricks", {5.5, 3.3}, 2.0, {0, 0}},
              Case{"bricks", {40.3, 40.3}, 0.3, {0, 0}},
              Case{"noise", {2.7, 2.7}, 0.2, {size * size, size * size}},
              Case{"noise", {9.7, 2.3}, 0.4, {0, size * size}}}) {
            SCOPED_TRACE(std::string(c.texture) + ", " + std::to_string(c.repeats.x) + " x " +
                         std::to_string(c.repeats.y) + " repeats, turned " + std::to_string(c.angle) + ", " +
                         std::to_string(probes) + " probes");
            const TextureImage texture = makeTexture(c.texture, 128, 1);
            FrontQuad q = frontQuad(texture, Sampler::Fourier, c.repeats, c.angle);
            q.scene.fourier.probes = probes;
            Renderer renderer(context(), q.scene, size, size);
            const Frame frame = renderer.render({});
            const FourierTexture reference(texture, q.scene.fourier);
            double worst = 0, sum = 0;
            int fallbacks = 0;
            for (int row = 0; row < size; ++row)
                for (int x = 0; x < size; ++x) {
                    const Vec2 uv = q.uv(x, row, size), right = q.uv(x + 1, row, size),
                               down = q.uv(x, row + 1, size);
                    const Vec2 dx{right.x - uv.x, right.y - uv.y}, dy{down.x - uv.x, down.y - uv.y};
                    fallbacks += reference.fallsBack(dx, dy);
                    const std::array<double, 4> expected = reference.sample(uv, dx, dy);
                    for (int ch = 0; ch < 3; ++ch) {
                        const double d =
                            std::abs(frame.pixels[(size_t(row) * size + size_t(x)) * 3 + size_t(ch)] -
                                     expected[size_t(ch)]);
                        worst = std::max(worst, d), sum += d;
                    }
                }
            const double mean = sum / (3.0 * size * size);
            std::printf("worst %.2e, mean %.2e, %d pixels read the MIP chain\n", worst, mean, fallbacks);
            EXPECT_LT(worst, 1e-4);
            EXPECT_LT(mean, 1e-5);
            EXPECT_EQ(fallbacks, c.fallbacks[probes == 1 ? 0 : 1]);
        }
}

// Every sampler gives a constant texture back, on the receding planes (every footprint from magnified to
// grazing).
TEST(Render, EverySamplerKeepsAConstantTexture) {
    TextureImage constant;
    constant.name = "constant", constant.width = constant.height = 64;
    for (int i = 0; i < 64 * 64; ++i) constant.rgba.insert(constant.rgba.end(), {150, 90, 200, 255});
    const auto decode = [](double c) {
        c /= 255;
        return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
    };
    for (const Sampler sampler :
         {Sampler::Point, Sampler::Bilinear, Sampler::Trilinear, Sampler::Anisotropic16, Sampler::Fourier}) {
        SCOPED_TRACE(samplerName(sampler));
        Scene scene = buildScene("planes", {.sampler = sampler});
        scene.textures = {constant};
        Renderer renderer(context(), scene, 96, 96);
        FrameRequest request;
        request.buffers = BufferSet::parse("color,id");
        const Frame frame = renderer.render(request);
        double worst = 0;
        int textured = 0;
        for (int y = 0; y < 96; ++y)
            for (int x = 0; x < 96; ++x) {
                if (channel(frame, x, y, "id.ID") == 0) continue;
                ++textured;
                worst = std::max({worst, std::abs(channel(frame, x, y, "R") - decode(150)),
                                  std::abs(channel(frame, x, y, "G") - decode(90)),
                                  std::abs(channel(frame, x, y, "B") - decode(200))});
            }
        EXPECT_GT(textured, 96 * 40);
        // OpenGL's own samplers decode sRGB bytes within 1.1e-3 of the formula here (llvmpipe); the
        // Fourier sampler decodes them with it.
        EXPECT_LT(worst, sampler == Sampler::Fourier ? 1e-6 : 1.1e-3);
    }
}

// Super bump mapping of a flat normal map is standard normal mapping: one lobe of weight 1 and no spread
// at every level, lit as the standard chain's normal is.
TEST(Render, SuperBumpMappingOfAFlatMapIsStandardNormalMapping) {
    std::vector<Frame> frames;
    for (const Bump bump : {Bump::Standard, Bump::Super}) {
        Scene scene = buildScene("normal-map", {.bump = bump});
        ASSERT_EQ(scene.normalMaps.size(), 1u);
        scene.normalMaps[0] = makeNormalMap("flat", 64, 1);
        Renderer renderer(context(), scene, 128, 96);
        frames.push_back(renderer.render({}));
    }
    double worst = 0;
    for (size_t i = 0; i < frames[0].pixels.size(); ++i)
        worst = std::max(worst, double(std::abs(frames[0].pixels[i] - frames[1].pixels[i])));
    EXPECT_LT(worst, 1e-5);
}

// On a bumpy map seen from afar (a front-facing quad at 4 and 12 texels a pixel, the light towards the
// viewer), standard normal mapping lights the averaged normal and turns too glossy; super bump mapping
// lights the lobes and stays near the supersampled truth (the surface read at level 0).
TEST(Render, SuperBumpMappingKeepsTheGlossOfADistantBumpySurface) {
    for (const double repeats : {1.0, 3.0}) {
        SCOPED_TRACE(repeats);
        std::vector<Frame> frames;
        for (const Bump bump : {Bump::Standard, Bump::Standard, Bump::Super}) {
            Scene scene;
            scene.name = "bumpy quad";
            scene.bump = bump;
            scene.sampler = frames.empty() ? Sampler::Bilinear : Sampler::Trilinear;  // the truth: level 0
            scene.normalMaps = {makeNormalMap("dimples", 256, 1)};
            Mesh quad;
            quad.append(makeQuad(2, 2, repeats, repeats));
            Material m;
            m.colour = {0.55, 0.57, 0.6}, m.specular = 1, m.shininess = 200;
            m.pattern = Pattern::Bumps, m.normalMap = 0;
            scene.addObject("quad", scene.addMesh(std::move(quad)), m);
            scene.lightDirection = {0.1, 0.3, 1.0};
            scene.camera = [](double) {
                CameraPose pose;
                pose.eye = {0, 0, 2}, pose.target = {0, 0, 0}, pose.fovY = 2 * std::atan(0.5);
                return pose;
            };
            Renderer renderer(context(), scene, 64, 64);
            TruthOptions truth;
            truth.samples = 256;
            frames.push_back(frames.empty() ? renderer.renderTruth(0, truth) : renderer.render({}));
        }
        double error[2] = {0, 0}, bias[2] = {0, 0};
        for (size_t i = 0; i < frames[0].pixels.size(); ++i)
            for (int k = 0; k < 2; ++k) {
                const double d = frames[size_t(k) + 1].pixels[i] - frames[0].pixels[i];
                error[k] += std::abs(d), bias[k] += d;
            }
        const double n = double(frames[0].pixels.size());
        std::printf("standard: error %.4f, bias %+.4f; super: error %.4f, bias %+.4f\n", error[0] / n,
                    bias[0] / n, error[1] / n, bias[1] / n);
        EXPECT_GT(bias[0] / n, 0.005);                 // standard: too glossy
        EXPECT_LT(std::abs(bias[1]), 0.25 * bias[0]);  // super: far less
        EXPECT_LT(error[1], 0.5 * error[0]);
    }
}

// On the receding plate of the normal-map scene (anisotropic footprints, grazing light), super bump
// mapping is closer to the supersampled truth than standard normal mapping read trilinearly, and aliases
// less (docs/texture-aa.md has the full-size figures).
TEST(Render, SuperBumpMappingBeatsStandardOnTheRecedingPlate) {
    const auto frameOf = [](Bump bump, Sampler sampler, int truthSamples) {
        const Scene scene = buildScene("normal-map", {.sampler = sampler, .bump = bump});
        Renderer renderer(context(), scene, 160, 160);
        TruthOptions truth;
        truth.samples = truthSamples;
        return truthSamples > 0 ? renderer.renderTruth(0, truth) : renderer.render({});
    };
    const Frame truth = frameOf(Bump::Standard, Sampler::Bilinear, 128);
    const double standard = psnr(frameOf(Bump::Standard, Sampler::Trilinear, 0), truth);
    const double super = psnr(frameOf(Bump::Super, Sampler::Trilinear, 0), truth);
    std::printf("PSNR standard %.2f dB, super %.2f dB\n", standard, super);
    EXPECT_GT(super, standard + 3);
}

TEST(Render, RefusesImpossibleSizes) {
    const Scene scene = buildScene("sphere");
    EXPECT_THROW(Renderer(context(), scene, 0, 10), Error);
    EXPECT_THROW(Renderer(context(), scene, 20000, 10), Error);
}

}  // namespace
}  // namespace dejag::render

// U-TAA and T-TAA: constant frames pass unchanged, a static scene converges towards its truth, a moving
// square leaves no ghost trail, and threads do not change the result.
#include "infer/taa.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/random.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "data/frame_image.h"
#include "data/image.h"
#include "render/halton.h"
#include "render/renderer.h"
#include "tests/alloc_counter.h"
#include "tests/infer/taa_reference.h"

namespace dejag::infer {
namespace {

struct Buffers {
    int width = 0, height = 0;
    std::vector<float> colour, albedo, depth, motion, ids, previousDepth;
    TaaFrame frame() const {
        TaaFrame f;
        f.width = width, f.height = height;
        f.colour = colour.data(), f.albedo = albedo.data(), f.depth = depth.data(), f.motion = motion.data();
        f.ids = ids.data(), f.previousDepth = previousDepth.data();
        return f;
    }
};

double psnr(const std::vector<float>& a, const std::vector<float>& b) {
    double squared = 0;
    for (size_t i = 0; i < a.size(); ++i) squared += double(a[i] - b[i]) * double(a[i] - b[i]);
    return 10 * std::log10(double(a.size()) / std::max(squared, 1e-30));
}

TEST(Taa, ConstantFramesPassUnchanged) {
    for (const bool improved : {false, true}) {
        Buffers b;
        b.width = 21, b.height = 13;
        const size_t n = 21 * 13;
        b.colour.assign(n * 3, 0.37f), b.albedo.assign(n * 3, 0.5f), b.depth.assign(n, 0.2f);
        b.motion.assign(n * 2, 0.0f), b.ids.assign(n, 1.0f), b.previousDepth.assign(n, 0.2f);
        TaaOptions options;
        options.improved = improved;
        Taa taa(options);
        std::vector<float> out(n * 3);
        for (int frame = 0; frame < 5; ++frame) {
            taa.apply(b.frame(), out.data());
            for (float v : out)
                ASSERT_NEAR(v, 0.37f, 1e-6f) << "frame " << frame << (improved ? " T-TAA" : " U-TAA");
        }
    }
}

// A white square moving 2 pixels per frame to the right over black: no trail behind it.
Buffers squareFrame(int t) {
    Buffers b;
    b.width = 64, b.height = 32;
    const size_t n = 64 * 32;
    b.colour.assign(n * 3, 0.0f), b.albedo.assign(n * 3, 0.0f), b.depth.assign(n, 0.9f),
        b.motion.assign(n * 2, 0.0f);
    b.ids.assign(n, 0.0f), b.previousDepth.assign(n, 0.9f);
    const int x0 = 4 + 2 * t;
    for (int y = 10; y < 22; ++y)
        for (int x = x0; x < x0 + 12 && x < 64; ++x) {
            const size_t i = size_t(y) * 64 + size_t(x);
            for (int c = 0; c < 3; ++c) b.colour[i * 3 + size_t(c)] = b.albedo[i * 3 + size_t(c)] = 1.0f;
            b.depth[i] = 0.3f, b.ids[i] = 1.0f, b.motion[i * 2] = 2.0f;
        }
    for (int y = 10; y < 22; ++y)
        for (int x = x0 - 2; x < x0 + 10; ++x)
            if (x >= 0) b.previousDepth[size_t(y) * 64 + size_t(x)] = 0.3f;
    return b;
}

TEST(Taa, AMovingSquareLeavesNoGhostTrail) {
    for (const bool improved : {false, true}) {
        TaaOptions options;
        options.improved = improved;
        Taa taa(options);
        std::vector<float> out(64 * 32 * 3);
        for (int t = 0; t < 14; ++t) taa.apply(squareFrame(t).frame(), out.data());
        // The square now covers x in [30, 42); everything left of x = 28 was covered earlier.
        float worst = 0;
        for (int y = 10; y < 22; ++y)
            for (int x = 4; x < 28; ++x) worst = std::max(worst, out[(size_t(y) * 64 + size_t(x)) * 3]);
        EXPECT_LT(worst, 0.05f) << (improved ? "T-TAA" : "U-TAA");
        // and the square itself is still there.
        EXPECT_GT(out[(size_t(16) * 64 + 36) * 3], 0.9f);
    }
}

// The renderer's jittered frames of a static scene: 16 frames of history beat the first frame; without
// the final sharpen, the accumulated history also beats the aliased frame itself.
TEST(Taa, StaticSceneConvergesTowardsTheTruth) {
    const auto context = render::createOsMesaContext();
    render::SceneOptions sceneOptions;
    sceneOptions.tiltedCamera = true;
    const render::Scene scene = render::buildScene("pipe", sceneOptions);
    const int W = 128, H = 96;
    render::Renderer renderer(*context, scene, W, H);
    const std::vector<float> truth =
        frameChannels(renderer.renderTruth(0, render::TruthOptions{}), 0, 3, true);
    render::FrameRequest still;
    still.buffers = render::BufferSet::parse("color");
    const double single = psnr(frameChannels(renderer.render(still), 0, 3, true), truth);
    for (const int variant : {0, 1, 2, 3}) {
        const bool improved = variant % 2 == 1, sharpen = variant < 2;
        TaaOptions options;
        options.improved = improved, options.sharpen = sharpen;
        Taa taa(options);
        std::vector<float> out(size_t(W * H * 3));
        double first = 0;
        for (int t = 0; t < 16; ++t) {
            render::FrameRequest request;
            request.time = 0, request.previousTime = 0;
            request.jitter = render::jitterPixels(unsigned(t), 1.7);
            request.previousJitter = render::jitterPixels(unsigned((t + 15) % 16), 1.7);
            request.buffers = render::BufferSet::all();
            const render::Frame f = renderer.render(request);
            Buffers b;
            b.width = W, b.height = H;
            const float toUnit = float(1.0 / scene.far);  // depth / far
            b.colour = frameChannels(f, 0, 3, true), b.albedo = frameChannels(f, 3, 3, true);
            b.depth = frameChannels(f, 6, 1, false, toUnit), b.motion = frameChannels(f, 7, 2, false);
            b.ids = frameChannels(f, 9, 1, false), b.previousDepth = frameChannels(f, 10, 1, false, toUnit);
            taa.apply(b.frame(), out.data());
            if (t == 0) first = psnr(out, truth);
        }
        const double last = psnr(out, truth);
        SCOPED_TRACE(std::string(improved ? "T-TAA" : "U-TAA") + (sharpen ? "" : " without sharpen"));
        EXPECT_GT(last, first + 1.0) << last << " dB after 16 frames, " << first << " after 1";
        if (!sharpen) {
            EXPECT_GT(last, single) << last << " dB vs the aliased frame's " << single;
        }
    }
}

// How the pixels of a test frame move: random per pixel (sub-pixel, some of it pointing outside the
// frame: the kernel's gathers), smooth like a camera's (its windowed reads), by whole pixels (a still
// camera and objects moving a pixel or two: the reads of single taps), or not at all (rows without
// motion read the history where they are).
enum class Motion { Random, Smooth, WholePixels, None };

// A frame of blocks (objects with their own IDs, depths and colours) over fine noise, with a depth step
// per block and the given motion.
Buffers randomFrame(int W, int H, uint64_t seed, Motion motion) {
    uint64_t state = seed;
    auto uniform = [&] { return float(unitInterval(state = splitMix64(state))); };
    Buffers b;
    b.width = W, b.height = H;
    const size_t n = size_t(W) * size_t(H);
    b.colour.resize(n * 3), b.albedo.resize(n * 3), b.depth.resize(n), b.motion.resize(n * 2);
    b.ids.resize(n), b.previousDepth.resize(n);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * size_t(W) + size_t(x);
            const int block = (x / 7 + y / 5) % 4;
            for (int c = 0; c < 3; ++c) {
                b.colour[3 * i + size_t(c)] = float(block) * 0.2f + 0.3f * uniform();
                b.albedo[3 * i + size_t(c)] = float(block) * 0.25f + 0.05f * uniform();
            }
            b.depth[i] = 0.01f * float(block + 1) + 0.0005f * uniform();
            b.previousDepth[i] = b.depth[i] + 0.003f * (uniform() - 0.5f);
            b.ids[i] = float(block);
            if (motion == Motion::Smooth) {
                b.motion[2 * i] = 0.7f + 0.043f * float(x), b.motion[2 * i + 1] = -0.4f + 0.021f * float(y);
            } else if (motion == Motion::None) {
                b.motion[2 * i] = 0.0f, b.motion[2 * i + 1] = (x + y) % 2 ? -0.0f : 0.0f;
            } else if (motion == Motion::WholePixels) {
                b.motion[2 * i] = block == 3 ? 2.0f : 0.0f, b.motion[2 * i + 1] = block == 2 ? -1.0f : 0.0f;
            } else {
                b.motion[2 * i] = 3.0f * (uniform() - 0.5f) + (x < 3 ? 4.0f : 0.0f);
                b.motion[2 * i + 1] = 2.0f * (uniform() - 0.5f) - (y > H - 3 ? 3.0f : 0.0f);
            }
        }
    return b;
}

// One object over a depth ramp with nearly flat colours and a noisy previous depth: T-TAA's box is then
// sized by the previous depth's pseudo-variance (not saturated by IDs or a strong Sobel), so a wrong read
// of the previous depth shows in the output.
Buffers rampFrame(int W, int H, uint64_t seed, Motion motion) {
    Buffers b = randomFrame(W, H, seed, motion);  // its motion
    uint64_t state = seed ^ 0x9e3779b97f4a7c15ull;
    auto uniform = [&] { return float(unitInterval(state = splitMix64(state))); };
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * size_t(W) + size_t(x);
            for (int c = 0; c < 3; ++c) {
                b.colour[3 * i + size_t(c)] = 0.5f + 0.02f * uniform();
                b.albedo[3 * i + size_t(c)] = 0.4f + 0.01f * uniform();
            }
            b.depth[i] = 0.02f + 0.003f * float(x) + 0.002f * float(y);
            b.previousDepth[i] = b.depth[i] + 0.006f * (uniform() - 0.5f);
            b.ids[i] = 1.0f;
        }
    return b;
}

// The SIMD band kernel against the scalar reference (the first implementation, kept in tests/), frame by
// frame with the history carried, on every SIMD path, at sizes that leave partial vectors.
TEST(Taa, EverySimdPathMatchesTheScalarReference) {
    const SimdLevel original = activeSimdLevel();
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        for (const int variant : {0, 1, 2, 3}) {
            const bool improved = variant % 2 == 1, sharpen = variant < 2;
            for (const auto& [W, H] :
                 {std::pair{37, 23}, std::pair{16, 5}, std::pair{1, 3}, std::pair{70, 1}}) {
                TaaOptions options;
                options.improved = improved, options.sharpen = sharpen;
                Taa taa(options);
                reference::ReferenceTaa oracle(options);
                std::vector<float> out(size_t(W * H * 3)), expected(out.size());
                float worst = 0;
                for (int t = 0; t < 12; ++t) {
                    const Motion motion = t % 4 == 0   ? Motion::Random
                                          : t % 4 == 1 ? Motion::Smooth
                                          : t % 4 == 2 ? Motion::WholePixels
                                                       : Motion::None;
                    const Buffers frame = t < 9 ? randomFrame(W, H, uint64_t(100 * W + t), motion)
                                                : rampFrame(W, H, uint64_t(100 * W + t), motion);
                    taa.apply(frame.frame(), out.data());
                    oracle.apply(frame.frame(), expected.data());
                    for (size_t i = 0; i < out.size(); ++i)
                        worst = std::max(worst, std::abs(out[i] - expected[i]));
                }
                EXPECT_LE(worst, 2e-5f) << simdLevelName(SimdLevel(level)) << (improved ? " T-TAA" : " U-TAA")
                                        << (sharpen ? "" : " unsharpened") << " " << W << "x" << H;
            }
        }
    }
    setSimdLevel(original);
}

// Un-jittering (TaaOptions::unjitter) is the TAA of the frame read bilinearly at p + jitter — computed here
// directly — for colour and albedo; a frame without its jitter is used as it is.
TEST(Taa, UnjitterFiltersTheFrameReadAtItsSamplePositions) {
    const int W = 37, H = 29;
    const float jx = 0.6f, jy = -1.3f;  // the image's shift: p's centre was sampled at p + (jx, jy)
    for (const bool improved : {false, true}) {
        TaaOptions with, without;
        with.improved = without.improved = improved;
        with.unjitter = true, without.unjitter = false;
        Taa unjittered(with), plain(without);
        std::vector<float> a(size_t(W * H * 3)), b(a.size());
        for (int t = 0; t < 3; ++t) {
            Buffers frame = randomFrame(W, H, 40 + uint64_t(t), Motion::Smooth);
            Buffers shifted = frame;
            for (std::vector<float>* plane : {&shifted.colour, &shifted.albedo}) {
                const std::vector<float>& source = plane == &shifted.colour ? frame.colour : frame.albedo;
                for (int y = 0; y < H; ++y)
                    for (int x = 0; x < W; ++x)
                        for (int c = 0; c < 3; ++c) {
                            const double sx = x + jx, sy = y + jy;
                            const int x0 = int(std::floor(sx)), y0 = int(std::floor(sy));
                            const double fx = sx - x0, fy = sy - y0;
                            auto at = [&](int xx, int yy) {
                                xx = std::clamp(xx, 0, W - 1), yy = std::clamp(yy, 0, H - 1);
                                return double(source[(size_t(yy) * size_t(W) + size_t(xx)) * 3 + size_t(c)]);
                            };
                            const double top = at(x0, y0) + fx * (at(x0 + 1, y0) - at(x0, y0));
                            const double bottom = at(x0, y0 + 1) + fx * (at(x0 + 1, y0 + 1) - at(x0, y0 + 1));
                            (*plane)[(size_t(y) * size_t(W) + size_t(x)) * 3 + size_t(c)] =
                                float(top + fy * (bottom - top));
                        }
            }
            TaaFrame f = frame.frame();
            f.hasJitter = true, f.jitter[0] = jx, f.jitter[1] = jy;
            unjittered.apply(f, a.data());
            plain.apply(shifted.frame(), b.data());
            for (size_t i = 0; i < a.size(); ++i)
                ASSERT_NEAR(a[i], b[i], 2e-5f) << "frame " << t << " at " << i;
        }
        // A frame without its jitter is used as it is.
        TaaOptions off = without;
        Taa a1(with), a2(off);
        const Buffers plainFrame = randomFrame(W, H, 1, Motion::Smooth);
        a1.apply(plainFrame.frame(), a.data());
        a2.apply(plainFrame.frame(), b.data());
        EXPECT_EQ(a, b);
    }
}

TEST(Taa, SameResultForEveryThreadCount) {
    std::vector<std::vector<float>> results;
    for (const int threads : {1, 2, 3}) {
        setThreadCount(threads);
        TaaOptions options;
        options.improved = true;
        Taa taa(options);
        std::vector<float> out(64 * 32 * 3);
        for (int t = 0; t < 6; ++t) taa.apply(squareFrame(t).frame(), out.data());
        results.push_back(out);
    }
    setThreadCount(0);
    EXPECT_EQ(results[0], results[1]);
    EXPECT_EQ(results[0], results[2]);
}

TEST(Taa, NoAllocationPerFrameAfterWarmUp) {
    for (const bool improved : {false, true}) {
        TaaOptions options;
        options.improved = improved;
        Taa taa(options);
        std::vector<Buffers> frames;
        for (int t = 0; t < 5; ++t) frames.push_back(squareFrame(t));
        std::vector<float> out(64 * 32 * 3);
        taa.apply(frames[0].frame(), out.data());
        taa.apply(frames[1].frame(), out.data());  // warm-up: history and scratch exist now
        const int64_t before = testing::allocationCount();
        for (int t = 2; t < 5; ++t) taa.apply(frames[size_t(t)].frame(), out.data());
        EXPECT_EQ(testing::allocationCount() - before, 0) << (improved ? "T-TAA" : "U-TAA");
    }
}

TEST(Taa, RefusesMissingBuffers) {
    TaaOptions options;
    options.improved = true;
    Taa taa(options);
    Buffers b = squareFrame(0);
    TaaFrame f = b.frame();
    f.ids = nullptr;
    std::vector<float> out(64 * 32 * 3);
    EXPECT_THROW(taa.apply(f, out.data()), Error);
    options.feedbackMin = 0.99f;
    EXPECT_THROW(Taa{options}, Error);
    TaaOptions blur;
    blur.motionBlurMaxSamples = 0;
    EXPECT_THROW(Taa{blur}, Error);
    blur.motionBlurMaxSamples = 32, blur.motionBlurScale = -1.0f;
    EXPECT_THROW(Taa{blur}, Error);
}

// A frame of a vertical step (0 left of column 32, 1 from it), 61 x 6 (a partial last vector), whose
// pixels move by motion(x, y).
template <class Motion>
Buffers stepFrame(const Motion& motion) {
    Buffers b;
    b.width = 61, b.height = 6;
    const size_t n = size_t(b.width) * size_t(b.height);
    b.colour.resize(n * 3), b.albedo.resize(n * 3, 0.5f), b.depth.resize(n, 0.5f), b.motion.resize(n * 2);
    b.ids.resize(n, 1.0f), b.previousDepth.resize(n, 0.5f);
    for (int y = 0; y < b.height; ++y)
        for (int x = 0; x < b.width; ++x) {
            const size_t i = size_t(y) * size_t(b.width) + size_t(x);
            for (int c = 0; c < 3; ++c) b.colour[3 * i + size_t(c)] = x >= 32 ? 1.0f : 0.0f;
            const auto [vx, vy] = motion(x, y);
            b.motion[2 * i] = vx, b.motion[2 * i + 1] = vy;
        }
    return b;
}
Buffers stepFrame(float vx) {
    return stepFrame([vx](int, int) { return std::pair{vx, 0.0f}; });
}

TEST(Taa, MotionBlurIsOffByDefaultAndLeavesStillPixelsAlone) {
    EXPECT_FALSE(TaaOptions{}.motionBlur);
    for (const bool improved : {false, true}) {
        TaaOptions plain, blurred;
        plain.improved = blurred.improved = improved;
        blurred.motionBlur = true;
        Taa a(plain), b(blurred);
        std::vector<float> outA(size_t(61 * 6 * 3)), outB(outA.size());
        for (const float motion : {0.0f, 1.5f}) {  // under 2 pixels: one sample
            const Buffers frame = stepFrame(motion);
            a.apply(frame.frame(), outA.data());
            b.apply(frame.frame(), outB.data());
            EXPECT_EQ(outA, outB) << improved << " " << motion;
        }
    }
}

// Each pixel averages itself and n - 1 bilinear samples spread over half its motion each way, n its
// speed in whole pixels (Chapman's per-object blur), computed here directly from the unblurred output,
// on every SIMD path, for one motion and for a different motion per pixel; the history is not blurred,
// so a next still frame is the same with the blur on or off.
TEST(Taa, MotionBlurAveragesAlongTheMotionAndKeepsTheHistory) {
    const SimdLevel original = activeSimdLevel();
    uint64_t state = 5;
    auto uniform = [&] { return float(unitInterval(state = splitMix64(state), -6.0, 6.0)); };
    std::vector<std::pair<float, float>> field(61 * 6);
    for (auto& v : field) v = {uniform(), uniform()};
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        for (const bool perPixel : {false, true}) {
            const Buffers moving = perPixel
                                       ? stepFrame([&](int x, int y) { return field[size_t(y * 61 + x)]; })
                                       : stepFrame([](int, int) {
                                             return std::pair{8.0f, 3.0f};
                                         });
            TaaOptions plain, blurred;
            blurred.motionBlur = true;
            Taa a(plain), b(blurred);
            std::vector<float> sharp(size_t(61 * 6 * 3)), out(sharp.size());
            a.apply(moving.frame(), sharp.data());
            b.apply(moving.frame(), out.data());
            auto bilinear = [&](float px, float py, int c) {  // clamp to edge
                const float fx = px - 0.5f, fy = py - 0.5f;
                const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
                const float tx = fx - float(x0), ty = fy - float(y0);
                auto v = [&](int x, int y) {
                    return sharp[3 * (size_t(std::clamp(y, 0, 5)) * 61 + size_t(std::clamp(x, 0, 60))) +
                                 size_t(c)];
                };
                const float top = v(x0, y0) + tx * (v(x0 + 1, y0) - v(x0, y0));
                const float bottom = v(x0, y0 + 1) + tx * (v(x0 + 1, y0 + 1) - v(x0, y0 + 1));
                return top + ty * (bottom - top);
            };
            float worst = 0;
            int blurredPixels = 0;
            for (int y = 0; y < 6; ++y)
                for (int x = 0; x < 61; ++x) {
                    const size_t i = size_t(y) * 61 + size_t(x);
                    const float vx = moving.motion[2 * i], vy = moving.motion[2 * i + 1];
                    const float speed = std::sqrt(vx * vx + vy * vy);
                    const int n = speed < 2.0f ? 1 : std::min(int(speed), 32);
                    for (int c = 0; c < 3; ++c) {
                        float expected = sharp[3 * i + size_t(c)];
                        for (int k = 1; k < n; ++k) {
                            const float t = float(k) / float(n - 1) - 0.5f;
                            expected += bilinear(float(x) + 0.5f + vx * t, float(y) + 0.5f + vy * t, c);
                        }
                        expected /= float(n);
                        worst = std::max(worst, std::abs(out[3 * i + size_t(c)] - expected));
                        if (c == 0 && std::abs(expected - sharp[3 * i]) > 0.05f) ++blurredPixels;
                    }
                }
            EXPECT_LE(worst, 1e-5f) << simdLevelName(SimdLevel(level)) << " per pixel " << perPixel;
            EXPECT_GT(blurredPixels, 10) << simdLevelName(SimdLevel(level));
            const Buffers still = stepFrame(0.0f);
            a.apply(still.frame(), sharp.data());
            b.apply(still.frame(), out.data());
            EXPECT_EQ(sharp, out);
        }
    }
    setSimdLevel(original);
    // A scale of 0 (an infinitely short shutter) blurs nothing.
    TaaOptions plain, blurred;
    blurred.motionBlur = true, blurred.motionBlurScale = 0.0f;
    Taa c(blurred), d(plain);
    const Buffers moving = stepFrame(8.0f);
    std::vector<float> sharp(size_t(61 * 6 * 3)), out(sharp.size());
    c.apply(moving.frame(), out.data());
    d.apply(moving.frame(), sharp.data());
    EXPECT_EQ(sharp, out);
}

}  // namespace
}  // namespace dejag::infer

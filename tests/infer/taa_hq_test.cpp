// taa-hq (infer/taa_hq.h) on synthetic sequences sampled exactly: a constant sequence passes unchanged, a
// static view converges to the mean of its jittered samples, a disocclusion takes the current frame at
// once, a moving edge stays as sharp as its truth, and threads do not change the result.
#include "infer/taa_hq.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <functional>

#include "base/error.h"
#include "base/random.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "data/image.h"
#include "infer/taa_hq_kernels.h"
#include "tests/infer/taa_hq_reference.h"

namespace dejag::infer {
namespace {

// A scene in linear RGB at a point of the image plane (pixel p covers [p, p + 1)).
using Scene = std::function<void(double x, double y, float* rgb)>;

// Discs, a slanted edge and a gradient: edges in every direction, no feature thinner than a pixel.
void shapes(double x, double y, float* rgb) {
    const bool disc = (x - 14.3) * (x - 14.3) + (y - 11.7) * (y - 11.7) < 7.2 * 7.2;
    const bool edge = y > 0.37 * x + 3.1;
    rgb[0] = disc ? 0.9f : edge ? 0.05f : 0.4f;
    rgb[1] = disc ? 0.2f : edge ? 0.6f : 0.1f + 0.01f * float(x);
    rgb[2] = edge && disc ? 1.0f : 0.3f;
}

// A frame of `scene` moved by (shiftX, shiftY): pixel q samples it at q + 0.5 - jitter, sRGB-encoded.
std::vector<float> sample(const Scene& scene, int W, int H, double jx, double jy, double shiftX = 0,
                          double shiftY = 0) {
    std::vector<float> out(size_t(W * H * 3));
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            float* p = out.data() + (size_t(y) * size_t(W) + size_t(x)) * 3;
            scene(x + 0.5 - jx - shiftX, y + 0.5 - jy - shiftY, p);
            for (int k = 0; k < 3; ++k) p[k] = linearToSrgb(p[k]);
        }
    return out;
}

// 16 offsets spread over a square of side `spread` pixels (a 4x4 grid, shuffled).
std::vector<std::pair<float, float>> offsets(double spread) {
    std::vector<std::pair<float, float>> list;
    const int order[16] = {0, 10, 5, 15, 2, 8, 7, 13, 1, 11, 4, 14, 3, 9, 6, 12};
    for (int i : order)
        list.push_back(
            {float(spread * ((i % 4 + 0.5) / 4 - 0.5)), float(spread * ((i / 4 + 0.5) / 4 - 0.5))});
    return list;
}

TEST(TaaHq, AConstantSequencePassesUnchanged) {
    const int W = 29, H = 23;
    const std::vector<float> frame = sample(shapes, W, H, 0, 0);
    const std::vector<float> motion(size_t(W * H * 2), 0.0f), depth(size_t(W * H), 0.3f);
    TaaHq taa;
    std::vector<float> out(frame.size());
    for (int t = 0; t < 40; ++t) {
        taa.apply(W, H, frame.data(), motion.data(), depth.data(), depth.data(), 0, 0, out.data());
        for (size_t i = 0; i < out.size(); ++i)
            ASSERT_NEAR(out[i], frame[i], 1e-4f) << "frame " << t << " at " << i;
    }
}

// The mean, in linear light, of the samples that fall in each pixel's box over the N frames.
std::vector<float> inPixelMean(const Scene& scene, int W, int H,
                               const std::vector<std::pair<float, float>>& jitters) {
    std::vector<double> sum(size_t(W * H * 3), 0.0);
    for (const auto& [jx, jy] : jitters) {
        // The sample of the frame inside pixel p's box: p + 0.5 - j moved by whole pixels into [p, p + 1).
        const double ox = -jx - std::floor(-jx + 0.5), oy = -jy - std::floor(-jy + 0.5);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                // (the frame's own sample there, clamped to the image at its border)
                const int qx = std::clamp(x - int(std::floor(-jx + 0.5)), 0, W - 1);
                const int qy = std::clamp(y - int(std::floor(-jy + 0.5)), 0, H - 1);
                float rgb[3];
                if (qx == x - int(std::floor(-jx + 0.5)) && qy == y - int(std::floor(-jy + 0.5)))
                    scene(x + 0.5 + ox, y + 0.5 + oy, rgb);
                else
                    scene(qx + 0.5 - jx, qy + 0.5 - jy, rgb);
                for (int k = 0; k < 3; ++k)
                    sum[(size_t(y) * size_t(W) + size_t(x)) * 3 + size_t(k)] += rgb[k];
            }
    }
    std::vector<float> mean(sum.size());
    for (size_t i = 0; i < sum.size(); ++i) mean[i] = linearToSrgb(float(sum[i] / double(jitters.size())));
    return mean;
}

TEST(TaaHq, AStaticViewConvergesToTheMeanOfItsJitteredSamples) {
    const int W = 31, H = 27;
    const std::vector<float> motion(size_t(W * H * 2), 0.0f), depth(size_t(W * H), 0.3f);
    // Within the pixel (the truth's box) and wider than it (the in-pixel sample comes from a neighbour).
    for (const double spread : {1.0, 1.7}) {
        const auto jitters = offsets(spread);
        const std::vector<float> want = inPixelMean(shapes, W, H, jitters);
        TaaHqOptions options;
        TaaHq taa(options);
        std::vector<float> out(want.size());
        double worst = 0;
        for (int cycle = 0; cycle < 2; ++cycle)
            for (const auto& [jx, jy] : jitters) {
                const std::vector<float> frame = sample(shapes, W, H, jx, jy);
                taa.apply(W, H, frame.data(), motion.data(), depth.data(), depth.data(), jx, jy, out.data());
            }
        for (size_t i = 0; i < out.size(); ++i) worst = std::max(worst, double(std::abs(out[i] - want[i])));
        EXPECT_LT(worst, 0.5 / 255) << "spread " << spread << ": the largest difference from the mean";
    }
}

TEST(TaaHq, ADisoccludedRegionTakesTheCurrentFrameAtOnce) {
    // A near square (depth 0.2) moves 4 px a frame to the right over the still scene (depth 0.5); the
    // background it uncovers takes the current frame at once.
    const int W = 48, H = 24, side = 10, speed = 4;
    const auto jitters = offsets(1.0);
    auto covered = [&](int t, int x, int y) {
        return x >= 4 + speed * t && x < 4 + speed * t + side && y >= 7 && y < 7 + side;
    };
    TaaHq taa;
    std::vector<float> out(size_t(W * H * 3)), previousDepth(size_t(W * H), 0.5f);
    const int last = 6;
    for (int t = 0; t <= last; ++t) {
        const auto& [jx, jy] = jitters[size_t(t)];
        std::vector<float> frame = sample(shapes, W, H, jx, jy), motion(size_t(W * H * 2), 0.0f),
                           depth(size_t(W * H), 0.5f);
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x)
                if (covered(t, x, y)) {
                    const size_t p = size_t(y * W + x);
                    for (int k = 0; k < 3; ++k) frame[p * 3 + size_t(k)] = 0.95f;
                    depth[p] = 0.2f, motion[p * 2] = t > 0 ? float(speed) : 0.0f;
                }
        taa.apply(W, H, frame.data(), motion.data(), depth.data(), previousDepth.data(), jx, jy, out.data());
        previousDepth = depth;
        if (t < last) continue;
        // Uncovered now, covered in the previous frame with its whole 3x3: the current frame, nothing of
        // the square.
        int checked = 0;
        for (int y = 0; y < H; ++y)
            for (int x = 0; x < W; ++x) {
                bool wasInside = true;
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) wasInside = wasInside && covered(t - 1, x + dx, y + dy);
                if (!wasInside || covered(t, x, y) || covered(t, x + 1, y)) continue;
                ++checked;
                for (int k = 0; k < 3; ++k) {
                    const size_t i = size_t(y * W + x) * 3 + size_t(k);
                    ASSERT_NEAR(out[i], frame[i], 1e-4f) << x << "," << y;
                }
            }
        EXPECT_GE(checked, 8 * 2);
    }
}

// The profile of a vertical edge (0 left, 1 right) across a row: its 10-90 % rise in pixels.
double riseWidth(const std::vector<float>& rgb, int W, int y) {
    double low = -1, high = -1;
    for (int x = 0; x < W; ++x) {
        const double v = srgbToLinear(rgb[(size_t(y) * size_t(W) + size_t(x)) * 3]);
        if (low < 0 && v > 0.1)
            low = x - 1 +
                  (0.1 - srgbToLinear(rgb[(size_t(y) * size_t(W) + size_t(x - 1)) * 3])) /
                      (v - srgbToLinear(rgb[(size_t(y) * size_t(W) + size_t(x - 1)) * 3]));
        if (high < 0 && v > 0.9)
            high = x - 1 +
                   (0.9 - srgbToLinear(rgb[(size_t(y) * size_t(W) + size_t(x - 1)) * 3])) /
                       (v - srgbToLinear(rgb[(size_t(y) * size_t(W) + size_t(x - 1)) * 3]));
    }
    return high - low;
}

// The 10-90 % rise of a vertical edge (0 left, 1 right) moving right at a sub-pixel speed, averaged over
// the rows, after `frames` frames of the sequence.
double movingEdgeWidth(bool catmullRom, int frames) {
    const int W = 48, H = 8;
    const Scene edge = [](double x, double, float* rgb) { rgb[0] = rgb[1] = rgb[2] = x > 8.0 ? 1.0f : 0.0f; };
    const double speed = 0.37;  // pixels per frame
    std::vector<float> motion(size_t(W * H * 2), 0.0f);
    for (size_t i = 0; i < motion.size(); i += 2) motion[i] = float(speed);
    const std::vector<float> depth(size_t(W * H), 0.4f);
    const auto jitters = offsets(1.0);
    TaaHqOptions options;
    options.catmullRom = catmullRom;
    TaaHq taa(options);
    std::vector<float> out(size_t(W * H * 3));
    for (int t = 0; t < frames; ++t) {
        const auto& [jx, jy] = jitters[size_t(t) % jitters.size()];
        const std::vector<float> frame = sample(edge, W, H, jx, jy, speed * t, 0);
        taa.apply(W, H, frame.data(), motion.data(), depth.data(), depth.data(), jx, jy, out.data());
    }
    double sum = 0;
    for (int y = 0; y < H; ++y) sum += riseWidth(out, W, y);
    return sum / H;
}

TEST(TaaHq, AnEdgeMovingAtASubPixelSpeedKeepsItsSharpness) {
    // The truth's edge (a box filter) rises over 0.8 px. Resampled with Catmull-Rom, the history's edge
    // stays about as wide from frame 30 to frame 90; bilinear resampling widens it.
    const double at30 = movingEdgeWidth(true, 30), at90 = movingEdgeWidth(true, 90);
    const double bilinear = movingEdgeWidth(false, 90);
    EXPECT_GT(at90, 0.5);
    EXPECT_LT(at90, 1.8);
    EXPECT_LT(at90 - at30, 0.1) << "the edge widens frame after frame";
    EXPECT_LT(at90, bilinear - 0.1) << "Catmull-Rom " << at90 << " px, bilinear " << bilinear << " px";
}

TEST(TaaHq, ThreadsDoNotChangeTheResult) {
    const int W = 64, H = 45;
    std::vector<float> motion(size_t(W * H * 2));
    for (size_t i = 0; i < motion.size(); ++i) motion[i] = 0.3f * float(std::sin(double(i) * 0.37));
    std::vector<float> depth(size_t(W * H)), previous(size_t(W * H));
    for (size_t i = 0; i < depth.size(); ++i)
        depth[i] = 0.2f + 0.1f * float(i % 7), previous[i] = depth[i] * (i % 11 == 0 ? 0.5f : 1.0f);
    std::vector<float> results[2];
    for (int threads : {1, 2}) {
        setThreadCount(threads);
        TaaHqOptions options;
        options.sharpen = 0.3f;
        TaaHq taa(options);
        std::vector<float> out(size_t(W * H * 3));
        const auto jitters = offsets(1.7);
        for (int t = 0; t < 12; ++t) {
            const std::vector<float> frame =
                sample(shapes, W, H, jitters[size_t(t)].first, jitters[size_t(t)].second, 0.3 * t);
            taa.apply(W, H, frame.data(), motion.data(), depth.data(), previous.data(),
                      jitters[size_t(t)].first, jitters[size_t(t)].second, out.data());
        }
        results[threads - 1] = out;
    }
    setThreadCount(0);
    EXPECT_EQ(results[0], results[1]);
}

// A random frame for the SIMD checks: smooth colours with noise and hard steps, depth in two layers (so
// some pixels are disoccluded), and the motion of the kind asked: none, a pan, a smooth zoom (rows and
// columns drift across the lanes), random per-pixel (the gather paths), or whole pixels.
struct RandomFrame {
    std::vector<float> colour, motion, depth, previousDepth;
};
enum class MotionKind { None, Pan, Zoom, Random, WholePixels };
RandomFrame randomFrame(int W, int H, uint64_t seed, MotionKind kind) {
    RandomFrame f;
    const size_t pixels = size_t(W) * size_t(H);
    f.colour.resize(pixels * 3), f.motion.resize(pixels * 2), f.depth.resize(pixels),
        f.previousDepth.resize(pixels);
    uint64_t state = seed;
    auto uniform = [&] { return float(unitInterval(state = splitMix64(state))); };
    const float panX = 2 * uniform() - 1, panY = 2 * uniform() - 1;
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t i = size_t(y) * size_t(W) + size_t(x);
            const bool near = (x / 5 + y / 4) % 3 == 0;
            for (int c = 0; c < 3; ++c)
                f.colour[3 * i + size_t(c)] =
                    std::clamp(0.5f + 0.3f * std::sin(0.4f * float(x + c) + 0.3f * float(y)) +
                                   (near ? 0.3f : -0.2f) + 0.05f * uniform(),
                               -0.1f, 1.1f);
            f.depth[i] = near ? 0.2f + 0.01f * uniform() : 0.7f + 0.01f * uniform();
            f.previousDepth[i] = uniform() < 0.1f ? 0.05f : f.depth[i];
            float mx = 0, my = 0;
            switch (kind) {
                case MotionKind::None:
                    break;
                case MotionKind::Pan:
                    mx = panX, my = panY;
                    break;
                case MotionKind::Zoom:
                    mx = 0.03f * float(x - W / 2), my = 0.03f * float(y - H / 2);
                    break;
                case MotionKind::Random:
                    mx = 6 * uniform() - 3, my = 6 * uniform() - 3;
                    break;
                case MotionKind::WholePixels:
                    mx = float(int(4 * uniform()) - 2), my = float(int(4 * uniform()) - 2);
                    break;
            }
            f.motion[2 * i] = mx, f.motion[2 * i + 1] = my;
        }
    return f;
}

// The band kernel against the scalar reference (the first implementation, kept in tests/), frame by frame
// with the history carried, on every SIMD path, at sizes that leave partial vectors, with every option
// that changes the kernel's path. (Measured: mean differences near 2e-7, the largest below 5e-5 but for
// one clipping decision taken differently.)
TEST(TaaHq, EverySimdPathMatchesTheScalarReference) {
    const SimdLevel original = activeSimdLevel();
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        for (const int variant : {0, 1, 2, 3, 4}) {
            TaaHqOptions options;
            if (variant == 1) options.sharpen = 0.5f;
            if (variant == 2) options.catmullRom = false;
            if (variant == 3) options.staticLock = false, options.movingSamples = 5;
            const bool withDepth = variant != 4;
            for (const auto& [W, H] : {std::pair{37, 23}, std::pair{16, 5}, std::pair{1, 3}, std::pair{70, 1},
                                       std::pair{100, 41}}) {
                TaaHq taa(options);
                reference::ReferenceTaaHq oracle(options);
                std::vector<float> out(size_t(W * H * 3)), expected(out.size());
                double sum = 0;
                size_t count = 0, apart = 0;
                for (int t = 0; t < 14; ++t) {
                    const MotionKind kind = MotionKind(t % 5);
                    const RandomFrame f = randomFrame(W, H, uint64_t(1000 * W + 10 * variant + t), kind);
                    const float jx = float(t % 3) * 0.45f - 0.45f, jy = float(t % 4) * 0.3f - 0.5f;
                    const float* depth = withDepth ? f.depth.data() : nullptr;
                    const float* previous = withDepth ? f.previousDepth.data() : nullptr;
                    taa.apply(W, H, f.colour.data(), f.motion.data(), depth, previous, jx, jy, out.data());
                    oracle.apply(W, H, f.colour.data(), f.motion.data(), depth, previous, jx, jy,
                                 expected.data());
                    for (size_t i = 0; i < out.size(); ++i) {
                        const float e = std::abs(out[i] - expected[i]);
                        sum += e, ++count, apart += e > 1e-4f;
                    }
                }
                const std::string what = std::string(simdLevelName(SimdLevel(level))) + " variant " +
                                         std::to_string(variant) + " " + std::to_string(W) + "x" +
                                         std::to_string(H);
                // Rounding differs (multiply-adds, a reciprocal for a division, polynomials for the sRGB
                // curves), so a history exactly at the clipping box's edge may be clipped on one side and not
                // the other: a rare pixel apart, the rest within rounding.
                EXPECT_LE(sum / double(count), 1e-6) << what;
                EXPECT_LE(double(apart), 1e-3 * double(count)) << what;
            }
        }
    }
    setSimdLevel(original);
}

// The kernel's sRGB curves (a polynomial in the mantissa, a factor per exponent) against the formulas, on
// every SIMD path: within 3e-6 over [0, 1], clamped outside it, and a NaN reads 0.
TEST(TaaHq, TheSrgbCurvesMatchTheFormulas) {
    const SimdLevel original = activeSimdLevel();
    std::vector<float> in;
    for (int i = 0; i <= 200000; ++i) in.push_back(float(i) / 200000);
    for (const float v : {-1.0f, -0.0f, 2.0f, 1e30f, -1e30f, std::nanf("")}) in.push_back(v);
    std::vector<float> out(in.size());
    for (int level = 0; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        DEJAG_SIMD_CALL(srgbToLinearRow, in.data(), out.data(), int(in.size()));
        float worst = 0;
        for (size_t i = 0; i < in.size(); ++i) {
            const float v = std::isnan(in[i]) ? 0.0f : std::clamp(in[i], 0.0f, 1.0f);
            worst = std::max(worst, std::abs(out[i] - srgbToLinear(v)));
        }
        EXPECT_LE(worst, 3e-6f) << simdLevelName(SimdLevel(level)) << " decoding";
        DEJAG_SIMD_CALL(linearToSrgbRow, in.data(), out.data(), int(in.size()));
        worst = 0;
        for (size_t i = 0; i < in.size(); ++i) {
            const float v = std::isnan(in[i]) ? 0.0f : std::clamp(in[i], 0.0f, 1.0f);
            worst = std::max(worst, std::abs(out[i] - linearToSrgb(v)));
        }
        EXPECT_LE(worst, 3e-6f) << simdLevelName(SimdLevel(level)) << " encoding";
    }
    setSimdLevel(original);
}

TEST(TaaHq, TheJitterListIsParsedOrRefusedInOneLine) {
    const auto list = parseJitterList("0.25,-0.25  -0.5,0.125");
    ASSERT_EQ(list.size(), 2u);
    EXPECT_EQ(list[1].first, -0.5f);
    EXPECT_EQ(list[1].second, 0.125f);
    for (const char* bad : {"0.25", "a,b", "1,2,3", "0.1,nan", "100,0"})
        EXPECT_THROW(parseJitterList(bad), Error) << bad;
}

}  // namespace
}  // namespace dejag::infer

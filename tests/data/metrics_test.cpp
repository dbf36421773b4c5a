// Properties of the metrics that hold whatever the reference implementation says.
#include "data/metrics.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "tests/test_util.h"

namespace dejag {
namespace {

Image noiseImage(int width, int height, int channels, uint32_t seed, PixelType storage = PixelType::UInt8) {
    Image image(width, height, Image::defaultChannelNames(channels), storage);
    std::mt19937 rng(seed);
    for (float& sample : image.pixels) sample = float(rng() % 256) / 255.0f;
    return image;
}

Image constantImage(int width, int height, int channels, float value) {
    Image image(width, height, Image::defaultChannelNames(channels), PixelType::UInt8);
    image.pixels.assign(image.sampleCount(), value);
    return image;
}

TEST(Metrics, IdenticalImagesArePerfect) {
    const Image a = noiseImage(64, 40, 3, 1);
    const ImageMetrics m = compareImages(a, a);
    EXPECT_EQ(m.mse, 0.0);
    EXPECT_EQ(m.rmse, 0.0);
    EXPECT_TRUE(std::isinf(m.psnr) && m.psnr > 0);
    EXPECT_TRUE(std::isinf(m.snr) && m.snr > 0);
    EXPECT_NEAR(m.ssim, 1.0, 1e-6);
    EXPECT_LE(m.ssim, 1.0);
}

TEST(Metrics, KnownMseAndPsnrOnTheEightBitScale) {
    // Every sample off by exactly 10/255: MSE 100 on the 0-255 scale, PSNR 10 log10(255^2/100).
    const Image a = constantImage(20, 20, 3, 100.0f / 255.0f);
    const Image b = constantImage(20, 20, 3, 110.0f / 255.0f);
    const ImageMetrics m = compareImages(a, b);
    EXPECT_NEAR(m.mse, 100.0, 1e-3);
    EXPECT_NEAR(m.rmse, 10.0, 1e-4);
    EXPECT_NEAR(m.psnr, 10.0 * std::log10(255.0 * 255.0 / 100.0), 1e-4);
    EXPECT_NEAR(m.snr, 10.0 * std::log10(100.0 * 100.0 / 100.0), 1e-4);
    EXPECT_EQ(m.dataRange, 255.0);
}

TEST(Metrics, ConstantImagesHaveFiniteSsim) {
    // Zero variance everywhere: SSIM reduces to the luminance term; C1/C2 keep it finite.
    const Image a = constantImage(32, 32, 1, 0.5f);
    const Image b = constantImage(32, 32, 1, 0.52f);
    const ImageMetrics m = compareImages(a, b);
    ASSERT_TRUE(std::isfinite(m.ssim));
    const double mx = 0.5, my = 0.52, c1 = 1e-4;
    EXPECT_NEAR(m.ssim, (2 * mx * my + c1) / (mx * mx + my * my + c1), 1e-6);
    const Image black = constantImage(32, 32, 1, 0.0f);
    EXPECT_NEAR(compareImages(black, black).ssim, 1.0, 1e-6);
}

TEST(Metrics, ScaleInvariantMetricsAgreeBetweenEightBitAndFloat) {
    const Image a = noiseImage(48, 30, 3, 2), b = noiseImage(48, 30, 3, 3);
    Image af = a, bf = b;
    af.storage = bf.storage = PixelType::Float;
    const ImageMetrics eight = compareImages(a, b);
    const ImageMetrics floating = compareImages(af, bf);  // data range 1
    EXPECT_NEAR(eight.psnr, floating.psnr, 1e-9);
    EXPECT_NEAR(eight.snr, floating.snr, 1e-9);
    EXPECT_NEAR(eight.ssim, floating.ssim, 1e-9);
    EXPECT_NEAR(eight.mse, floating.mse * 255.0 * 255.0, 1e-6 * eight.mse);
}

TEST(Metrics, DataRangeOptionChangesPsnrAndSsim) {
    const Image a = noiseImage(40, 40, 1, 4), b = noiseImage(40, 40, 1, 5);
    MetricOptions options;
    options.dataRange = 510.0;
    const ImageMetrics wide = compareImages(a, b, options);
    const ImageMetrics normal = compareImages(a, b);
    EXPECT_NEAR(wide.psnr - normal.psnr, 20.0 * std::log10(2.0), 1e-9);
    EXPECT_NE(wide.ssim, normal.ssim);
    EXPECT_EQ(wide.mse, normal.mse);
}

TEST(Metrics, MaskRestrictsEveryMetric) {
    // Left half identical, right half different: masked to the left, the images are perfect.
    Image a = noiseImage(60, 40, 3, 6), b = a;
    for (int y = 0; y < 40; ++y)
        for (int x = 30; x < 60; ++x)
            for (int c = 0; c < 3; ++c) b.at(x, y, c) = 1.0f - a.at(x, y, c);
    Image left(60, 40, {"Y"}, PixelType::UInt8), right = left;
    for (int y = 0; y < 40; ++y)
        for (int x = 0; x < 60; ++x) (x < 20 ? left : right).at(x, y, 0) = 1.0f;
    MetricOptions options;
    options.mask = &left;
    const ImageMetrics masked = compareImages(a, b, options);
    EXPECT_EQ(masked.scoredPixels, 20 * 40);
    EXPECT_EQ(masked.mse, 0.0);
    EXPECT_TRUE(std::isinf(masked.psnr));
    EXPECT_NEAR(masked.ssim, 1.0, 1e-6);  // x < 20: the window (radius 5) never reaches x >= 30
    options.mask = &right;
    const ImageMetrics other = compareImages(a, b, options);
    EXPECT_GT(other.mse, compareImages(a, b).mse);
    EXPECT_LT(other.ssim, compareImages(a, b).ssim);
}

TEST(Metrics, EmptyMaskIsAnError) {
    const Image a = noiseImage(30, 30, 1, 7);
    const Image empty = constantImage(30, 30, 1, 0.0f);
    MetricOptions options;
    options.mask = &empty;
    EXPECT_THROW(compareImages(a, a, options), Error);
    const Image wrongSize = constantImage(31, 30, 1, 1.0f);
    options.mask = &wrongSize;
    EXPECT_THROW(compareImages(a, a, options), Error);
}

TEST(Metrics, MismatchedImagesAreErrors) {
    EXPECT_THROW(compareImages(noiseImage(30, 30, 3, 1), noiseImage(31, 30, 3, 1)), Error);
    EXPECT_THROW(compareImages(noiseImage(30, 30, 3, 1), noiseImage(30, 30, 4, 1)), Error);
    EXPECT_THROW(compareImages(noiseImage(10, 30, 1, 1), noiseImage(10, 30, 1, 1)), Error);  // < 11 wide
}

TEST(Metrics, SameResultForEveryThreadCount) {
    const Image a = noiseImage(203, 117, 3, 8), b = noiseImage(203, 117, 3, 9);
    setThreadCount(1);
    const ImageMetrics one = compareImages(a, b, {0.0, nullptr, true});
    for (int threads : {2, 3, 5}) {
        setThreadCount(threads);
        const ImageMetrics many = compareImages(a, b, {0.0, nullptr, true});
        EXPECT_EQ(one.mse, many.mse) << threads << " threads";
        EXPECT_EQ(one.ssim, many.ssim) << threads << " threads";
        EXPECT_EQ(one.ssimMap, many.ssimMap) << threads << " threads";
    }
    setThreadCount(0);
}

TEST(Metrics, SimdPathsAgree) {
    const Image a = noiseImage(211, 97, 3, 10), b = noiseImage(211, 97, 3, 11);
    const SimdLevel original = activeSimdLevel();
    setSimdLevel(SimdLevel::Scalar);
    const ImageMetrics scalar = compareImages(a, b);
    for (int level = 1; level <= int(cpuSimdLevel()); ++level) {
        setSimdLevel(SimdLevel(level));
        const ImageMetrics vector = compareImages(a, b);
        EXPECT_NEAR(vector.ssim, scalar.ssim, 1e-6) << simdLevelName(SimdLevel(level));
        EXPECT_NEAR(vector.psnr, scalar.psnr, 1e-6) << simdLevelName(SimdLevel(level));
    }
    setSimdLevel(original);
}

TEST(Metrics, FloatImagesFarOutsideTheUnitRangeStayFinite) {
    Image a(40, 40, {"R", "G", "B"}, PixelType::Float), b = a;
    std::mt19937 rng(12);
    for (size_t i = 0; i < a.pixels.size(); ++i) {
        a.pixels[i] = std::uniform_real_distribution<float>(0.0f, 1e4f)(rng);
        b.pixels[i] = a.pixels[i] * 1.01f;
    }
    MetricOptions options;
    options.dataRange = 1e4;
    const ImageMetrics m = compareImages(a, b, options);
    EXPECT_TRUE(std::isfinite(m.ssim) && std::isfinite(m.psnr) && std::isfinite(m.snr));
    EXPECT_GT(m.ssim, 0.99);
    Image tiny = a, tinier = b;
    for (float& v : tiny.pixels) v *= 1e-12f;
    for (float& v : tinier.pixels) v *= 1e-12f;
    const ImageMetrics t = compareImages(tiny, tinier);
    EXPECT_TRUE(std::isfinite(t.ssim) && std::isfinite(t.psnr));
}

TEST(Metrics, SsimMapIsTheMeanOverChannelsAndAveragesToSsim) {
    const Image a = noiseImage(50, 40, 2, 13), b = noiseImage(50, 40, 2, 14);
    const SsimResult r = structuralSimilarity(a, b, 1.0, nullptr, true);
    ASSERT_EQ(r.map.size(), size_t(50 * 40));
    double sum = 0.0;
    for (int y = 5; y < 35; ++y)
        for (int x = 5; x < 45; ++x) sum += r.map[size_t(y) * 50 + x];
    EXPECT_NEAR(sum / (30.0 * 40.0), r.mean, 1e-6);
}

TEST(Metrics, SsimMapPngIsWritten) {
    testing::TempDir dir;
    const Image a = noiseImage(30, 20, 3, 15);
    const SsimResult r = structuralSimilarity(a, noiseImage(30, 20, 3, 16), 1.0, nullptr, true);
    writeSsimMapPng(dir.file("map.png"), r.map, 30, 20);
    const Image map = readImage(dir.file("map.png"));
    EXPECT_EQ(map.width, 30);
    EXPECT_EQ(map.channels(), 3);
}

}  // namespace
}  // namespace dejag

// data/spectrum.h: the FFT against the plain DFT, and the aliasing measure's invariants: none for an
// image equal to its truth or a smooth filtering of it, none for a band-limited signal sampled at the
// pixels against its box-filtered truth; some for folded energy; the sampler ordering is checked on
// rendered frames by Cli.MetricsAliasingOrdersTheTextureSamplers.
#include "data/spectrum.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <functional>
#include <numbers>
#include <vector>

#include "base/error.h"
#include "base/random.h"

namespace dejag {
namespace {

using Complex = std::complex<double>;

std::vector<Complex> naiveDft(const std::vector<Complex>& v) {
    const size_t n = v.size();
    std::vector<Complex> out(n);
    for (size_t k = 0; k < n; ++k)
        for (size_t j = 0; j < n; ++j)
            out[k] += v[j] * std::polar(1.0, -2 * std::numbers::pi * double(k * j % n) / double(n));
    return out;
}

TEST(Spectrum, FftIsTheDiscreteFourierTransform) {
    uint64_t state = 3;
    const auto random = [&] { return unitInterval(state = splitMix64(state), -1.0, 1.0); };
    for (int n : {1, 2, 4, 8, 64}) {
        std::vector<Complex> v(static_cast<size_t>(n));
        for (Complex& c : v) c = Complex(random(), random());
        const std::vector<Complex> expected = naiveDft(v);
        fft(v.data(), n);
        for (int k = 0; k < n; ++k)
            EXPECT_LT(std::abs(v[size_t(k)] - expected[size_t(k)]), 1e-12) << n << " " << k;
    }
    std::vector<Complex> three(3);
    EXPECT_THROW(fft(three.data(), 3), Error);
    // 2D: a DFT along each axis.
    const int h = 4, w = 8;
    std::vector<Complex> grid(size_t(h * w));
    for (Complex& c : grid) c = Complex(random(), 0.0);
    std::vector<Complex> expected(grid.size());
    for (int ky = 0; ky < h; ++ky)
        for (int kx = 0; kx < w; ++kx)
            for (int y = 0; y < h; ++y)
                for (int x = 0; x < w; ++x)
                    expected[size_t(ky * w + kx)] +=
                        grid[size_t(y * w + x)] *
                        std::polar(1.0, -2 * std::numbers::pi * (double(ky * y) / h + double(kx * x) / w));
    fft2d(grid, h, w);
    for (size_t i = 0; i < grid.size(); ++i) EXPECT_LT(std::abs(grid[i] - expected[i]), 1e-12);
}

Image greyImage(int w, int h, const std::function<double(double, double)>& f, int supersample = 1) {
    Image image(w, h, {"Y"});
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            double sum = 0;
            for (int j = 0; j < supersample; ++j)
                for (int i = 0; i < supersample; ++i)
                    sum += f(x + (i + 0.5) / supersample, y + (j + 0.5) / supersample);
            image.at(x, y, 0) = float(sum / (supersample * supersample));
        }
    return image;
}

// A sum of cosines below the Nyquist limit.
double smooth(double x, double y) {
    return 0.5 + 0.2 * std::cos(2 * std::numbers::pi * (0.11 * x + 0.05 * y)) +
           0.1 * std::cos(2 * std::numbers::pi * (-0.2 * x + 0.31 * y));
}

TEST(Spectrum, ABandLimitedImageAndSmoothFiltersOfTheTruthAreNoAliasing) {
    // (A size that is no power of two: padded.)
    const Image truth = greyImage(100, 60, smooth, 16);  // the box filter of the pixel
    const AliasingScore same = aliasingScore(truth, truth);
    EXPECT_EQ(same.aliasing, 0.0);
    EXPECT_DOUBLE_EQ(same.detailKept, 1.0);
    // Point samples of the band-limited signal: sharper than the box-filtered truth, but no aliasing.
    const AliasingScore sampled = aliasingScore(greyImage(100, 60, smooth), truth);
    EXPECT_LT(sampled.aliasing, 1e-4) << sampled.aliasing;
    // A blur of the truth: detail lost, no aliasing.
    Image blurred = truth;
    for (int y = 0; y < truth.height; ++y)
        for (int x = 0; x < truth.width; ++x) {
            double sum = 0;
            for (int d = -1; d <= 1; ++d) sum += truth.at(std::clamp(x + d, 0, truth.width - 1), y, 0);
            blurred.at(x, y, 0) = float(sum / 3);
        }
    const AliasingScore blur = aliasingScore(blurred, truth);
    EXPECT_LT(blur.aliasing, 1e-3) << blur.aliasing;
    EXPECT_LT(blur.detailKept, 0.99);
}

TEST(Spectrum, FoldedEnergyIsAliasing) {
    // A pattern far above the Nyquist limit (3.93 cycles a pixel): the box filter of the truth leaves 2 %
    // of it, its point samples fold all of it back to a low frequency (0.07) that the truth hardly holds.
    // (What the truth's own filter lets fold, the measure counts as the truth's: it measures aliasing
    // beyond its truth's.)
    const auto fine = [](double x, double y) {
        return smooth(x, y) + 0.3 * std::cos(2 * std::numbers::pi * (3.93 * x + 0.02 * y));
    };
    const Image truth = greyImage(64, 64, fine, 16);
    const AliasingScore point = aliasingScore(greyImage(64, 64, fine), truth);
    EXPECT_GT(point.aliasing, 0.5) << point.aliasing;
    EXPECT_GT(point.aliasingDb(), -3.0);
    // Half the folded pattern's amplitude, a quarter of its energy.
    const auto half = [](double x, double y) {
        return smooth(x, y) + 0.15 * std::cos(2 * std::numbers::pi * (3.93 * x + 0.02 * y));
    };
    const AliasingScore weaker = aliasingScore(greyImage(64, 64, half), truth);
    EXPECT_NEAR(weaker.aliasing / point.aliasing, 0.25, 0.03);
}

TEST(Spectrum, BadInputIsRefused) {
    const Image a = greyImage(32, 16, smooth), b = greyImage(16, 32, smooth);
    EXPECT_THROW(aliasingScore(a, b), Error);
    const Image flat = greyImage(32, 16, [](double, double) { return 0.5; });
    EXPECT_THROW(aliasingScore(a, flat), Error);
    Image buffers(32, 16, {"depth.Z", "motion.X"});
    EXPECT_THROW(aliasingScore(buffers, a), Error);
}

}  // namespace
}  // namespace dejag

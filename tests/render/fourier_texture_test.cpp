// render/fourier_texture.h on the CPU (the shader's arithmetic in double;
// Render.FourierSamplerMatchesItsCpuReference ties the two together): the band-limited levels against a plain
// DFT, the removed sinusoids rebuilding the texture, and the sampler's behaviour (docs/texture-aa.md): a
// constant stays constant, a texture well inside the footprint's passband passes unchanged, a sinusoid beyond
// it fades to the pixel filter's response instead of aliasing.
#include "render/fourier_texture.h"

#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <functional>
#include <numbers>

#include "base/error.h"
#include "base/random.h"

namespace dejag::render {
namespace {

using Complex = std::complex<double>;
constexpr double kTau = 2 * std::numbers::pi;

// Deterministic numbers for the tests (base/random.h).
struct Numbers {
    uint64_t state;
    double uniform(double low, double high) { return unitInterval(splitMix64(state++), low, high); }
    uint8_t byte() { return uint8_t(splitMix64(state++) >> 56); }
};

double decode(uint8_t v) {
    const double c = v / 255.0;
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}
double encode(double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x <= 0.0031308 ? 12.92 * x : 1.055 * std::pow(x, 1 / 2.4) - 0.055;
}

// A grey texture whose linear value at texel (x, y) is value(x, y), stored as sRGB bytes.
TextureImage greyTexture(int n, const std::function<double(int, int)>& value) {
    TextureImage t;
    t.name = "test", t.width = n, t.height = n;
    t.rgba.resize(size_t(n) * size_t(n) * 4);
    for (int y = 0; y < n; ++y)
        for (int x = 0; x < n; ++x) {
            const uint8_t g = uint8_t(std::lround(255 * encode(value(x, y))));
            uint8_t* p = &t.rgba[(size_t(y) * size_t(n) + size_t(x)) * 4];
            p[0] = p[1] = p[2] = g, p[3] = 255;
        }
    return t;
}

TextureImage randomTexture(int n, uint64_t seed) {
    TextureImage t;
    t.name = "random", t.width = n, t.height = n;
    Numbers random{seed};
    for (int i = 0; i < n * n; ++i)
        for (int c = 0; c < 4; ++c) t.rgba.push_back(c == 3 ? 255 : random.byte());
    return t;
}

// The plain DFT of one channel in linear light.
std::vector<Complex> spectrum(const TextureImage& t, int channel) {
    const int n = t.width;
    std::vector<Complex> out(size_t(n) * size_t(n));
    for (int ky = 0; ky < n; ++ky)
        for (int kx = 0; kx < n; ++kx) {
            Complex sum;
            for (int y = 0; y < n; ++y)
                for (int x = 0; x < n; ++x)
                    sum += decode(t.rgba[(size_t(y) * size_t(n) + size_t(x)) * 4 + size_t(channel)]) *
                           std::polar(1.0, -kTau * double((kx * x + ky * y) % n) / n);
            out[size_t(ky) * size_t(n) + size_t(kx)] = sum;
        }
    return out;
}

// The plain inverse DFT of the frequencies of `spectrum` (n x n) with max(|kx|, |ky|) < cut, at texel
// coordinate (x, y) (texel centres at whole numbers); none at the Nyquist frequency n / 2.
double bandBelow(const std::vector<Complex>& spectrum, int n, double cut, double x, double y) {
    double value = 0;
    for (int ky = -n / 2 + 1; ky < n / 2; ++ky)
        for (int kx = -n / 2 + 1; kx < n / 2; ++kx)
            if (std::max(std::abs(kx), std::abs(ky)) < cut)
                value += (spectrum[size_t((ky + n) % n) * n + size_t((kx + n) % n)] *
                          std::polar(1.0, kTau * (kx * x + ky * y) / n))
                             .real() /
                         (n * n);
    return value;
}

// A footprint of `texels` texels a pixel along x and `texels / anisotropy` along y, turned by `angle`.
struct Derivatives {
    Vec2 dx, dy;
};
Derivatives footprint(int n, double texels, double anisotropy = 1, double angle = 0) {
    const double c = std::cos(angle), s = std::sin(angle), major = texels / n,
                 minor = texels / anisotropy / n;
    return {{c * major, s * major}, {-s * minor, c * minor}};
}

TEST(FourierTexture, LevelsHoldTheBandBelowTheirCutoffAtTheirTexelCentres) {
    const int n = 16;
    const TextureImage t = randomTexture(n, 7);
    const FourierTexture f(t, {.frequencies = 8, .cutoff = 0.75, .sigma = 0.35, .minCaptured = 0});
    ASSERT_EQ(f.levels(), 5);
    const std::vector<Complex> red = spectrum(t, 0);
    double worst = 0;
    for (int m = 1; m < f.levels(); ++m) {
        const int nm = n >> (m - 1);
        ASSERT_EQ(f.levelSize(m), nm);
        const double cut = f.cutoffOf(m), centre = 0.5 * ((1 << (m - 1)) - 1);
        EXPECT_DOUBLE_EQ(cut, 0.75 * (n >> m) / 2);
        for (int j = 0; j < nm; ++j)
            for (int i = 0; i < nm; ++i) {
                const double x = (1 << (m - 1)) * i + centre, y = (1 << (m - 1)) * j + centre;
                const double expected = bandBelow(red, n, cut, x, y);
                worst = std::max(worst, std::abs(f.level(m)[(size_t(j) * nm + size_t(i)) * 4] - expected));
            }
    }
    EXPECT_LT(worst, 1e-6);
    // Level 0 is the texture, decoded.
    EXPECT_FLOAT_EQ(f.level(0)[4 * 5 + 1], float(decode(t.rgba[4 * 5 + 1])));
}

TEST(FourierTexture, TheRemovedSinusoidsRebuildTheTexture) {
    // With no pixel filter and room for every sinusoid, set (0, 0, 0) holds all of those level 1 lacks:
    // with level 1's band (a plain inverse DFT here) they give every texel back.
    const int n = 16;
    const TextureImage t = randomTexture(n, 3);
    const FourierTexture f(t, {.frequencies = 256, .cutoff = 0.5, .sigma = 0, .minCaptured = 0});
    const double cut = f.cutoffOf(1);
    const float* row = f.detail().data() + size_t(f.setIndex(0, 0, 0)) * 256 * 8;
    for (int channel = 0; channel < 3; ++channel) {
        const std::vector<Complex> s = spectrum(t, channel);
        double worst = 0;
        int waves = 0;
        for (int y = 0; y < n; ++y)
            for (int x = 0; x < n; ++x) {
                double value = bandBelow(s, n, cut, x, y);
                waves = 0;
                for (int j = 0; j < 256; ++j) {
                    const float* e = row + j * 8;
                    if (e[0] == 0 && e[1] == 0) continue;
                    ++waves;
                    EXPECT_GE(std::max(std::abs(e[0]), std::abs(e[1])), cut);
                    const Complex c(e[2 + 2 * channel], e[3 + 2 * channel]);
                    value += (c * std::polar(1.0, kTau * (e[0] * x + e[1] * y) / n)).real();
                }
                worst = std::max(worst,
                                 std::abs(value - decode(t.rgba[(size_t(y) * n + size_t(x)) * 4 + channel])));
            }
        EXPECT_LT(worst, 1e-5) << "channel " << channel;
        // Of the 16 x 16 frequencies, the 3 x 3 below the cut-off (2) are not there, the three Nyquist
        // ones are their own conjugates, and the others come in conjugate pairs, one wave each.
        EXPECT_EQ(waves, (n * n - 3 * 3 - 3) / 2 + 3);
        EXPECT_NEAR(f.captured(f.setIndex(0, 0, 0)), 1.0, 1e-12);
    }
}

TEST(FourierTexture, AConstantTextureSamplesToTheConstant) {
    const TextureImage t = greyTexture(64, [](int, int) { return 0.3; });
    const FourierTexture f(t, {});
    const double expected = decode(uint8_t(std::lround(255 * encode(0.3))));
    Numbers random{5};
    for (int i = 0; i < 200; ++i) {
        const Derivatives d = footprint(64, std::exp2(random.uniform(-2, 8)), std::exp2(random.uniform(0, 5)),
                                        random.uniform(0, 7));
        const std::array<double, 4> s = f.sample({random.uniform(-3, 3), random.uniform(-3, 3)}, d.dx, d.dy);
        for (int c = 0; c < 3; ++c) ASSERT_NEAR(s[size_t(c)], expected, 1e-6);
        ASSERT_NEAR(s[3], 1.0, 1e-6);
    }
}

// The largest difference, in sRGB 8-bit steps, between the sampler and the texture's own formula over a
// grid of places, for a footprint.
double worstSteps(const FourierTexture& f, const std::function<double(double, double)>& truth,
                  Derivatives d) {
    double worst = 0;
    for (int j = 0; j < 37; ++j)
        for (int i = 0; i < 37; ++i) {
            const Vec2 uv{i / 37.0 + 0.013, j / 37.0 + 0.029};
            const double got = f.sample(uv, d.dx, d.dy)[0];
            worst = std::max(worst, 255 * std::abs(encode(got) - encode(truth(uv.x, uv.y))));
        }
    return worst;
}

TEST(FourierTexture, ATextureWellInsideThePassbandPassesUnchanged) {
    // Sinusoids of at most 1/16 cycle a pixel (an eighth of the Nyquist limit) for every footprint tried,
    // up to 16 texels a pixel and 4:1 anisotropy, linear values 0.25 .. 0.75; the texels hold them rounded
    // to 8 bits, so the texture's own formula is itself within half a step. (Nearer the limit any pixel
    // filter attenuates, the truth's box as well: docs/texture-aa.md.)
    const int n = 256;
    const auto twoAndThree = [](double u, double v) {
        return 0.5 + 0.15 * std::cos(kTau * 2 * u) + 0.1 * std::sin(kTau * (3 * u + 2 * v));
    };
    const auto one = [](double u, double v) {
        return 0.5 + 0.15 * std::cos(kTau * u) + 0.1 * std::sin(kTau * (u + v) + 1);
    };
    for (const auto& [value, most] :
         {std::pair<std::function<double(double, double)>, double>{twoAndThree, 4.0}, {one, 16.0}}) {
        const TextureImage t =
            greyTexture(n, [&](int x, int y) { return value((x + 0.5) / n, (y + 0.5) / n); });
        for (const int probes : {1, 8}) {
            const FourierTexture f(t, {.probes = probes});
            for (const double texels : {0.5, 1.0, 2.7, 4.0, 8.0, 16.0})
                for (const double anisotropy : {1.0, 4.0})
                    if (texels <= most) {
                        EXPECT_LT(worstSteps(f, value, footprint(n, texels, anisotropy, 0.4)), 1.0)
                            << texels << " texels a pixel, anisotropy " << anisotropy << ", " << probes
                            << " probes";
                    }
        }
    }
}

TEST(FourierTexture, ASinusoidBeyondThePixelsNyquistLimitFadesToTheFiltersResponse) {
    // 48 cycles across 128 texels, seen at 0.6, 1 and 2.25 cycles a pixel, beyond the 0.5 a pixel can
    // hold: point sampling would fold it back at full amplitude. The sampler leaves the amplitude a
    // Gaussian pixel filter of sigma 0.35 px passes, exp(-sigma^2 (2 pi cycles)^2 / 2), around the mean:
    // isotropic footprints, and along the long axis of a 4:1 footprint read with one probe.
    const int n = 128;
    const auto value = [](double u, double) { return 0.5 + 0.3 * std::cos(kTau * 48 * u); };
    const TextureImage t = greyTexture(n, [&](int x, int y) { return value((x + 0.5) / n, (y + 0.5) / n); });
    for (const int probes : {1, 8}) {
        const FourierTexture f(t, {.probes = probes});
        for (const double anisotropy : {1.0, 4.0})
            for (const double cycles : {0.6, 1.0, 2.25}) {
                const double response = std::exp(-0.5 * 0.35 * 0.35 * std::pow(kTau * cycles, 2));
                const Derivatives d = footprint(n, cycles * n / 48, anisotropy);
                double lowest = 1, highest = 0;
                for (int i = 0; i < 1000; ++i) {
                    const double s = f.sample({i / 1000.0 + 0.0003, 0.3}, d.dx, d.dy)[0];
                    lowest = std::min(lowest, s), highest = std::max(highest, s);
                }
                SCOPED_TRACE(std::to_string(cycles) + " cycles a pixel, anisotropy " +
                             std::to_string(anisotropy) + ", " + std::to_string(probes) + " probes");
                const double amplitude = (highest - lowest) / 2;
                EXPECT_NEAR((highest + lowest) / 2, 0.5, 2e-3);
                if (probes == 1 || anisotropy == 1) {
                    // Within 10 %: the bilinear read of level 0, from which the attenuation is taken
                    // away below one texel a pixel, is itself a little softer than the texels (0.114
                    // against 0.126 at 0.6 cycles).
                    EXPECT_NEAR(amplitude, 0.3 * response, 0.1 * 0.3 * response + 2e-3);
                } else {
                    // Eight probes along the long axis read level 0 bilinearly near its Nyquist limit,
                    // where the reads do not cancel as the band's would (docs/texture-aa.md): the wave
                    // stays within what the truth's own box filter can pass, 1 / (pi cycles) of it.
                    EXPECT_LT(amplitude, 0.3 / (std::numbers::pi * cycles));
                }
            }
    }
}

TEST(FourierTexture, StripesAreAllCapturedAndSizesAreChecked) {
    const FourierTexture stripes(makeTexture("stripes", 256, 1), {});
    for (int set = 0; set < stripes.setCount(); ++set) EXPECT_GT(stripes.captured(set), 0.999) << set;
    EXPECT_EQ(stripes.setCount(), 8 * 9 / 2 * 4);
    EXPECT_EQ(stripes.detailTexels().size(), size_t(stripes.setCount()) * (2 * 64 + 1) * 4);
    TextureImage odd = greyTexture(4, [](int, int) { return 0.5; });
    odd.width = 2, odd.height = 8;
    EXPECT_THROW(FourierTexture(odd, {}), Error);
    EXPECT_THROW(FourierTexture(greyTexture(12, [](int, int) { return 0.5; }), {}), Error);
    EXPECT_THROW(FourierTexture(greyTexture(8, [](int, int) { return 0.5; }), {.frequencies = 0}), Error);
    EXPECT_THROW(FourierTexture(greyTexture(8, [](int, int) { return 0.5; }), {.cutoff = 0}), Error);
    for (const int probes : {0, 3, 32})
        EXPECT_THROW(FourierTexture(greyTexture(8, [](int, int) { return 0.5; }), {.probes = probes}), Error);
}

}  // namespace
}  // namespace dejag::render

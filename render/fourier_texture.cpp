#include "render/fourier_texture.h"

#include <algorithm>
#include <cmath>
#include <complex>
#include <numbers>
#include <string>

#include "base/error.h"
#include "base/fft.h"
#include "base/thread_pool.h"

namespace dejag::render {
namespace {

using Complex = std::complex<double>;
constexpr double kTau = 2 * std::numbers::pi;

double srgbToLinear(uint8_t v) {
    const double c = v / 255.0;
    return c <= 0.04045 ? c / 12.92 : std::pow((c + 0.055) / 1.055, 2.4);
}

int wrap(int i, int n) {
    return ((i % n) + n) % n;
}

// A removed sinusoid: its frequency and its RGB amplitudes.
struct Sinusoid {
    int kx = 0, ky = 0;
    Complex c[3];
    double magnitude = 0;
};

// The response of the mean of n probes spaced one unit apart (a Dirichlet kernel) at x cycles a unit;
// at whole cycles, its limit.
double probeResponse(double x, int n) {
    if (n == 1) return 1;
    const double d = std::sin(std::numbers::pi * x);
    return std::abs(d) < 1e-4 ? std::cos(n * std::numbers::pi * x) / std::cos(std::numbers::pi * x)
                              : std::sin(n * std::numbers::pi * x) / (n * d);
}

}  // namespace

Footprint footprintOf(Vec2 a, Vec2 b) {
    // The ellipse a pixel covers in texels: the covariance J J^T of the derivatives' columns.
    const double c00 = a.x * a.x + b.x * b.x, c01 = a.x * a.y + b.x * b.y, c11 = a.y * a.y + b.y * b.y;
    const double half = 0.5 * (c00 + c11), spread = std::sqrt(0.25 * (c00 - c11) * (c00 - c11) + c01 * c01);
    const double major = half + spread, minor = std::max(half - spread, 0.0);
    Footprint f;
    f.majorLod = 0.5 * std::log2(std::max(major, 1e-30));
    f.minorLod = 0.5 * std::log2(std::max(minor, 1e-30));
    f.angle = 0.5 * std::atan2(2 * c01, c00 - c11);
    if (f.angle < 0) f.angle += std::numbers::pi;
    return f;
}

FourierTexture::FourierTexture(const TextureImage& image, const FourierOptions& options) : options_(options) {
    const int n = image.width;
    if (n < 2 || image.height != n || (n & (n - 1)) != 0)
        throw Error("the Fourier sampler needs a square power-of-two texture, not " +
                    std::to_string(image.width) + "x" + std::to_string(image.height) + " ('" + image.name +
                    "')");
    if (image.rgba.size() != size_t(n) * size_t(n) * 4)
        throw Error("texture '" + image.name + "' holds " + std::to_string(image.rgba.size()) +
                    " bytes, not " + std::to_string(size_t(n) * size_t(n) * 4));
    if (options.frequencies < 1 || options.frequencies > 1024)
        throw Error("the Fourier sampler keeps 1 to 1024 frequencies a set, not " +
                    std::to_string(options.frequencies));
    if (!(options.cutoff > 0 && options.cutoff <= 1))
        throw Error("the Fourier sampler's cut-off is a fraction of the Nyquist limit in (0, 1], not " +
                    std::to_string(options.cutoff));
    if (options.probes < 1 || options.probes > 16 || (options.probes & (options.probes - 1)) != 0)
        throw Error("the Fourier sampler reads its bands at 1, 2, 4, 8 or 16 probes, not " +
                    std::to_string(options.probes));
    if (!(options.sigma >= 0 && options.sigma <= 4))
        throw Error("the Fourier sampler's pixel filter sigma is 0 to 4 pixels, not " +
                    std::to_string(options.sigma));
    size_ = n;
    levels_ = 1;
    while ((1 << (levels_ - 1)) < n) ++levels_;

    // The spectrum of each channel in linear light.
    const size_t pixels = size_t(n) * size_t(n);
    std::vector<std::vector<Complex>> spectra(4, std::vector<Complex>(pixels));
    bands_.assign(size_t(levels_), {});
    bands_[0].resize(pixels * 4);
    for (size_t i = 0; i < pixels; ++i)
        for (int c = 0; c < 4; ++c) {
            const uint8_t v = image.rgba[i * 4 + size_t(c)];
            const double linear = c < 3 ? srgbToLinear(v) : v / 255.0;
            bands_[0][i * 4 + size_t(c)] = float(linear);
            spectra[size_t(c)][i] = linear;
        }
    // The box MIP chain the fallback reads: each level the mean of 2 x 2 texels of the one before.
    mipmaps_.assign(size_t(levels_), {});
    for (int j = 1; j < levels_; ++j) {
        const std::vector<float>& finer = mipmap(j - 1);
        const int nj = n >> j, nf = n >> (j - 1);
        std::vector<float>& level = mipmaps_[size_t(j)];
        level.resize(size_t(nj) * size_t(nj) * 4);
        for (int y = 0; y < nj; ++y)
            for (int x = 0; x < nj; ++x)
                for (size_t c = 0; c < 4; ++c) {
                    const auto texel = [&](int dx, int dy) {
                        return finer[(size_t(2 * y + dy) * size_t(nf) + size_t(2 * x + dx)) * 4 + c];
                    };
                    level[(size_t(y) * size_t(nj) + size_t(x)) * 4 + c] =
                        0.25f * (texel(0, 0) + texel(1, 0) + texel(0, 1) + texel(1, 1));
                }
    }
    for (auto& s : spectra) fft2d(s, n, n);
    const auto at = [&](int c, int kx, int ky) -> Complex {
        return spectra[size_t(c)][size_t(wrap(ky, n)) * size_t(n) + size_t(wrap(kx, n))];
    };
    const auto signedOf = [n](int k) { return k <= n / 2 ? k : k - n; };

    // Level m >= 1: the frequencies below its cut-off, evaluated at the texel centres of the grid twice
    // as fine as its MIP size (levelSize), which sit at level-0 texel coordinate 2^(m-1) j + (2^(m-1) - 1)
    // / 2: an inverse transform of that size with that half-texel phase.
    for (int m = 1; m < levels_; ++m) {
        const int nm = levelSize(m);
        const double cut = cutoffOf(m), delta = 0.5 * ((1 << (m - 1)) - 1);
        std::vector<float>& band = bands_[size_t(m)];
        band.assign(size_t(nm) * size_t(nm) * 4, 0.0f);
        for (int c = 0; c < 4; ++c) {
            std::vector<Complex> g(size_t(nm) * size_t(nm));
            for (int ky = 0; ky < n; ++ky)
                for (int kx = 0; kx < n; ++kx) {
                    const int sx = signedOf(kx), sy = signedOf(ky);
                    if (std::max(std::abs(sx), std::abs(sy)) >= cut) continue;
                    g[size_t(wrap(sy, nm)) * size_t(nm) + size_t(wrap(sx, nm))] +=
                        at(c, sx, sy) * std::polar(1.0, kTau * (sx + sy) * delta / n);
                }
            inverseFft2d(g, nm, nm);
            const double scale = double(nm) * nm / (double(n) * n);
            for (size_t i = 0; i < g.size(); ++i) band[i * 4 + size_t(c)] = float(g[i].real() * scale);
        }
    }

    // Every sinusoid (a frequency and its conjugate as one real wave), strongest first.
    std::vector<Sinusoid> waves;
    for (int ky = 0; ky < n; ++ky)
        for (int kx = 0; kx < n; ++kx) {
            const size_t index = size_t(ky) * size_t(n) + size_t(kx);
            const size_t conjugate = size_t(wrap(-ky, n)) * size_t(n) + size_t(wrap(-kx, n));
            if (index == 0 || index > conjugate) continue;
            const double factor = (index == conjugate ? 1.0 : 2.0) / double(pixels);
            Sinusoid w;
            w.kx = signedOf(kx), w.ky = signedOf(ky);
            for (int c = 0; c < 3; ++c) {
                w.c[c] = factor * at(c, kx, ky);
                w.magnitude += std::norm(w.c[c]);
            }
            w.magnitude = std::sqrt(w.magnitude);
            if (w.magnitude > 1e-7) waves.push_back(w);
        }
    std::stable_sort(waves.begin(), waves.end(),
                     [](const Sinusoid& a, const Sinusoid& b) { return a.magnitude > b.magnitude; });

    // Each set: the strongest after attenuation by the smallest footprint that reads it, among those its
    // upper level (m + 1) lacks.
    const int perSet = options_.frequencies;
    detail_.assign(size_t(setCount()) * size_t(perSet) * 8, 0.0f);
    captured_.assign(size_t(setCount()), 0.0);
    const double sigma2 = options_.sigma * options_.sigma;
    parallelFor(0, setCount(), 1, [&](int64_t first, int64_t last) {
        std::vector<std::pair<double, size_t>> best;  // (score, wave), a min-heap of the kept
        const auto worse = [](const std::pair<double, size_t>& a, const std::pair<double, size_t>& b) {
            return a.first > b.first || (a.first == b.first && a.second < b.second);
        };
        for (int64_t set = first; set < last; ++set) {
            const int orientation = int(set % kOrientations);
            int m = 0, s = int(set / kOrientations);
            while (s > m) s -= ++m;
            const double cut = cutoffOf(bandLevel(m, s) + 1), angle = orientation * std::numbers::pi / 4;
            const double major = std::ldexp(1.0, m), minor = std::ldexp(1.0, s);
            const double dx = std::cos(angle), dy = std::sin(angle), unit = kTau / n;
            best.clear();
            double total = 0;
            for (size_t i = 0; i < waves.size(); ++i) {
                const Sinusoid& w = waves[i];
                if (std::max(std::abs(w.kx), std::abs(w.ky)) < cut) continue;
                const double along = unit * (w.kx * dx + w.ky * dy) * major;
                const double across = unit * (-w.kx * dy + w.ky * dx) * minor;
                const double score =
                    w.magnitude * std::exp(-0.5 * sigma2 * (along * along + across * across));
                total += score * score;
                if (best.size() < size_t(perSet)) {
                    best.emplace_back(score, i);
                    std::push_heap(best.begin(), best.end(), worse);
                } else if (score > best.front().first) {
                    std::pop_heap(best.begin(), best.end(), worse);
                    best.back() = {score, i};
                    std::push_heap(best.begin(), best.end(), worse);
                }
            }
            double kept = 0;
            for (const auto& [score, wave] : best) kept += score * score;
            // What the set misses counts only above half an 8-bit step of RMS amplitude (a real wave of
            // amplitude |c| has RMS |c| / sqrt 2): a set of rounding noise is summed, not replaced.
            const double negligible = 2 * (0.5 / 255) * (0.5 / 255);
            captured_[size_t(set)] = total - kept > negligible ? kept / total : 1.0;
            // Stored by frequency, so a set's order does not depend on the heap's.
            std::sort(best.begin(), best.end(),
                      [](const auto& a, const auto& b) { return a.second < b.second; });
            float* row = detail_.data() + size_t(set) * size_t(perSet) * 8;
            for (size_t j = 0; j < best.size(); ++j) {
                const Sinusoid& w = waves[best[j].second];
                float* e = row + j * 8;
                e[0] = float(w.kx), e[1] = float(w.ky);
                for (int c = 0; c < 3; ++c)
                    e[2 + 2 * c] = float(w.c[c].real()), e[3 + 2 * c] = float(w.c[c].imag());
            }
        }
    });
}

std::vector<float> FourierTexture::detailTexels() const {
    const size_t entries = size_t(frequencies()) * 8;
    std::vector<float> texels;
    texels.reserve(size_t(setCount()) * (entries + 4));
    for (int set = 0; set < setCount(); ++set) {
        const float* row = detail_.data() + size_t(set) * entries;
        texels.insert(texels.end(), row, row + entries);
        texels.insert(texels.end(), {float(captured(set)), 0.0f, 0.0f, 0.0f});
    }
    return texels;
}

int FourierTexture::setCount() const {
    return (levels_ - 1) * levels_ / 2 * kOrientations;
}

int FourierTexture::setIndex(int level, int subLevel, int orientation) const {
    return (level * (level + 1) / 2 + subLevel) * kOrientations + orientation;
}

double FourierTexture::cutoffOf(int m) const {
    return m == 0 ? INFINITY : options_.cutoff * 0.5 * double(size_ >> m);
}

std::array<double, 4> FourierTexture::bilinearOf(const std::vector<float>& texels, int size, Vec2 uv) {
    const double x = uv.x * size - 0.5, y = uv.y * size - 0.5;
    const double fx = std::floor(x), fy = std::floor(y), tx = x - fx, ty = y - fy;
    std::array<double, 4> out{};
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            const double weight = (i ? tx : 1 - tx) * (j ? ty : 1 - ty);
            const size_t texel =
                size_t(wrap(int(fy) + j, size)) * size_t(size) + size_t(wrap(int(fx) + i, size));
            for (int c = 0; c < 4; ++c) out[size_t(c)] += weight * texels[texel * 4 + size_t(c)];
        }
    return out;
}

std::array<double, 4> FourierTexture::bilinear(int m, Vec2 uv) const {
    return bilinearOf(bands_[size_t(m)], levelSize(m), uv);
}

// The fallback: at each probe, the box MIP chain read trilinearly at the probe's level.
std::array<double, 4> FourierTexture::mipmapped(const Reading& r, Vec2 uv) const {
    const double lod = r.m + r.f;
    const int j = std::min(int(std::floor(lod)), levels_ - 2);
    const double t = lod - j;
    std::array<double, 4> out{};
    for (int i = 0; i < r.probes; ++i) {
        const double offset = (i + 0.5) - 0.5 * r.probes;
        const Vec2 at{uv.x + offset * r.step.x, uv.y + offset * r.step.y};
        const std::array<double, 4> lower = bilinearOf(mipmap(j), size_ >> j, at),
                                    upper = bilinearOf(mipmap(j + 1), size_ >> (j + 1), at);
        for (size_t c = 0; c < 4; ++c) out[c] += ((1 - t) * lower[c] + t * upper[c]) / r.probes;
    }
    return out;
}

FourierTexture::Reading FourierTexture::readingOf(Vec2 a, Vec2 b) const {
    const Footprint footprint = footprintOf(a, b);
    Reading r;
    const double lod = std::clamp(footprint.majorLod, 0.0, double(levels_ - 1));
    r.level = std::min(int(std::floor(lod)), levels_ - 2);
    r.f = lod - r.level;
    r.s = std::clamp(int(std::floor(footprint.minorLod)), 0, r.level);
    r.orientation = int(std::floor(footprint.angle / (std::numbers::pi / 4) + 0.5)) % kOrientations;
    r.m = bandLevel(r.level, r.s);
    r.probes = 1 << (r.level - r.m);
    const double length = std::exp2(lod) / size_ / r.probes;
    r.step = {std::cos(footprint.angle) * length, std::sin(footprint.angle) * length};
    return r;
}

int FourierTexture::bandLevel(int level, int subLevel) const {
    int most = 0;
    while ((2 << most) <= options_.probes) ++most;
    return level - std::min(level - subLevel, most);
}

bool FourierTexture::fallsBack(Vec2 dUvdx, Vec2 dUvdy) const {
    const double n = size_;
    const Reading r = readingOf({dUvdx.x * n, dUvdx.y * n}, {dUvdy.x * n, dUvdy.y * n});
    if (r.m == 0) return false;  // level 0 holds everything: no sum to ring
    return captured(setIndex(r.level, r.s, r.orientation)) < options_.minCaptured;
}

std::array<double, 4> FourierTexture::sample(Vec2 uv, Vec2 dUvdx, Vec2 dUvdy) const {
    const double n = size_;
    const Vec2 a{dUvdx.x * n, dUvdx.y * n}, b{dUvdy.x * n, dUvdy.y * n};
    const Reading r = readingOf(a, b);
    const int m = r.m;
    const double f = r.f;
    if (m > 0 && captured(setIndex(r.level, r.s, r.orientation)) < options_.minCaptured)
        return mipmapped(r, uv);
    std::array<double, 4> out{};
    for (int i = 0; i < r.probes; ++i) {
        const double t = (i + 0.5) - 0.5 * r.probes;
        const Vec2 at{uv.x + t * r.step.x, uv.y + t * r.step.y};
        const std::array<double, 4> lower = bilinear(m, at), upper = bilinear(m + 1, at);
        for (size_t c = 0; c < 4; ++c) out[c] += ((1 - f) * lower[c] + f * upper[c]) / r.probes;
    }
    const float* row =
        detail_.data() + size_t(setIndex(r.level, r.s, r.orientation)) * size_t(frequencies()) * 8;
    const double cut = cutoffOf(m), sigma2 = options_.sigma * options_.sigma, unit = kTau / n;
    const Vec2 at{uv.x - std::floor(uv.x), uv.y - std::floor(uv.y)};
    for (int j = 0; j < frequencies(); ++j) {
        const float* e = row + size_t(j) * 8;
        const double kx = e[0], ky = e[1];
        const double qx = unit * (kx * a.x + ky * a.y), qy = unit * (kx * b.x + ky * b.y);
        const double response = std::exp(-0.5 * sigma2 * (qx * qx + qy * qy));
        // Level 0 holds every sinusoid whole: what its share (1 - f) should lose is taken away.
        const double attenuation =
            m == 0 ? response - (1 - f) * probeResponse(kx * r.step.x + ky * r.step.y, r.probes)
            : std::max(std::abs(kx), std::abs(ky)) < cut ? f * response
                                                         : response;
        const double turns = kx * at.x + ky * at.y - (kx + ky) * 0.5 / n;
        const double phase = kTau * (turns - std::floor(turns));
        const double cosine = std::cos(phase), sine = std::sin(phase);
        for (size_t c = 0; c < 3; ++c) out[c] += attenuation * (e[2 + 2 * c] * cosine - e[3 + 2 * c] * sine);
    }
    for (size_t c = 0; c < 3; ++c) out[c] = std::clamp(out[c], 0.0, 1.0);
    return out;
}

}  // namespace dejag::render

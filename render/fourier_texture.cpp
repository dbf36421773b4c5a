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
            const double cut = cutoffOf(m + 1), angle = orientation * std::numbers::pi / 4;
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
            captured_[size_t(set)] = total > 0 ? kept / total : 1.0;
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

std::array<double, 4> FourierTexture::bilinear(int m, Vec2 uv) const {
    const int nm = levelSize(m);
    const double x = uv.x * nm - 0.5, y = uv.y * nm - 0.5;
    const double fx = std::floor(x), fy = std::floor(y), tx = x - fx, ty = y - fy;
    const std::vector<float>& band = bands_[size_t(m)];
    std::array<double, 4> out{};
    for (int j = 0; j < 2; ++j)
        for (int i = 0; i < 2; ++i) {
            const double weight = (i ? tx : 1 - tx) * (j ? ty : 1 - ty);
            const size_t texel = size_t(wrap(int(fy) + j, nm)) * size_t(nm) + size_t(wrap(int(fx) + i, nm));
            for (int c = 0; c < 4; ++c) out[size_t(c)] += weight * band[texel * 4 + size_t(c)];
        }
    return out;
}

bool FourierTexture::usesTrilinear(Vec2 dUvdx, Vec2 dUvdy) const {
    const double n = size_;
    const Footprint footprint = footprintOf({dUvdx.x * n, dUvdx.y * n}, {dUvdy.x * n, dUvdy.y * n});
    const double lod = std::clamp(footprint.majorLod, 0.0, double(levels_ - 1));
    const int m = std::min(int(std::floor(lod)), levels_ - 2);
    if (m == 0) return false;  // level 0 holds everything: no sum to ring
    const int s = std::clamp(int(std::floor(footprint.minorLod)), 0, m);
    const int orientation = int(std::floor(footprint.angle / (std::numbers::pi / 4) + 0.5)) % kOrientations;
    return captured(setIndex(m, s, orientation)) < options_.minCaptured;
}

std::array<double, 4> FourierTexture::sample(Vec2 uv, Vec2 dUvdx, Vec2 dUvdy) const {
    const double n = size_;
    const Vec2 a{dUvdx.x * n, dUvdx.y * n}, b{dUvdy.x * n, dUvdy.y * n};
    const Footprint footprint = footprintOf(a, b);
    const double lod = std::clamp(footprint.majorLod, 0.0, double(levels_ - 1));
    const int m = std::min(int(std::floor(lod)), levels_ - 2);
    const double f = lod - m;
    const int s = std::clamp(int(std::floor(footprint.minorLod)), 0, m);
    const int orientation = int(std::floor(footprint.angle / (std::numbers::pi / 4) + 0.5)) % kOrientations;
    const std::array<double, 4> lower = bilinear(m, uv), upper = bilinear(m + 1, uv);
    std::array<double, 4> out;
    for (size_t c = 0; c < 4; ++c) out[c] = (1 - f) * lower[c] + f * upper[c];
    const float* row = detail_.data() + size_t(setIndex(m, s, orientation)) * size_t(frequencies()) * 8;
    const double cut = cutoffOf(m), sigma2 = options_.sigma * options_.sigma, unit = kTau / n;
    const Vec2 at{uv.x - std::floor(uv.x), uv.y - std::floor(uv.y)};
    for (int j = 0; j < frequencies(); ++j) {
        const float* e = row + size_t(j) * 8;
        const double kx = e[0], ky = e[1];
        const double qx = unit * (kx * a.x + ky * a.y), qy = unit * (kx * b.x + ky * b.y);
        const double response = std::exp(-0.5 * sigma2 * (qx * qx + qy * qy));
        // Level 0 holds every sinusoid whole: what its share (1 - f) should lose is taken away.
        const double attenuation = m == 0                                       ? response - (1 - f)
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

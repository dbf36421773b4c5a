#include "data/spectrum.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "base/error.h"
#include "base/fft.h"
#include "base/luma.h"

namespace dejag {
namespace {

using Complex = std::complex<double>;

// The most a smooth filter of the truth may amplify a band: undoing the pixel's box filter at the
// Nyquist corner, 1 / sinc(1/2)^2 = (pi / 2)^2 (point samples against a box-filtered truth). More is no
// filter but energy the truth does not hold: folded.
constexpr double kMostGain = std::numbers::pi * std::numbers::pi / 4;

int nextPowerOfTwo(int n) {
    int p = 1;
    while (p < n) p *= 2;
    return p;
}

// The luma of the colour channels (R, G, B; or the one channel of a grey image).
std::vector<double> lumaOf(const Image& image, const char* role) {
    const int r = image.findChannel("R"), g = image.findChannel("G"), b = image.findChannel("B");
    const int y = image.findChannel("Y");
    if ((r < 0 || g < 0 || b < 0) && y < 0 && image.channels() != 1)
        throw Error(std::string("the ") + role + " image has no colour channels (R, G, B or Y)");
    std::vector<double> out(image.pixelCount());
    for (int row = 0; row < image.height; ++row)
        for (int x = 0; x < image.width; ++x) {
            const size_t at = size_t(row) * size_t(image.width) + size_t(x);
            if (r >= 0 && g >= 0 && b >= 0) {
                const float rgb[3] = {image.at(x, row, r), image.at(x, row, g), image.at(x, row, b)};
                out[at] = luma(rgb);
            } else {
                out[at] = image.at(x, row, y >= 0 ? y : 0);
            }
        }
    return out;
}

// The luma minus its mean, under a separable Hann window, in the top-left corner of a padded array.
std::vector<Complex> windowed(const std::vector<double>& values, int h, int w, int H, int W) {
    double mean = 0;
    for (double v : values) mean += v;
    mean /= double(values.size());
    const auto hann = [](int i, int n) {
        return n < 2 ? 1.0 : 0.5 - 0.5 * std::cos(2 * std::numbers::pi * (i + 0.5) / n);
    };
    std::vector<Complex> out(size_t(H) * size_t(W));
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            out[size_t(y) * size_t(W) + size_t(x)] =
                (values[size_t(y) * size_t(w) + size_t(x)] - mean) * hann(y, h) * hann(x, w);
    return out;
}

}  // namespace

double AliasingScore::aliasingDb() const {
    return aliasing > 0 ? 10 * std::log10(aliasing) : -INFINITY;
}

AliasingScore aliasingScore(const Image& test, const Image& truth, int rings, int sectors) {
    if (test.width != truth.width || test.height != truth.height)
        throw Error("the aliasing measure compares images of one size (" + std::to_string(test.width) + "x" +
                    std::to_string(test.height) + " against " + std::to_string(truth.width) + "x" +
                    std::to_string(truth.height) + ")");
    if (rings < 1 || sectors < 1) throw Error("the aliasing measure needs at least one ring and one sector");
    const int h = truth.height, w = truth.width, H = nextPowerOfTwo(h), W = nextPowerOfTwo(w);
    std::vector<Complex> X = windowed(lumaOf(test, "test"), h, w, H, W);
    std::vector<Complex> T = windowed(lumaOf(truth, "reference"), h, w, H, W);
    fft2d(X, H, W);
    fft2d(T, H, W);
    // Each frequency's band: ring by |f| (cycles a pixel) and sector by orientation over [0, pi).
    const int bands = rings * sectors;
    std::vector<int> band(X.size());
    const double outer = std::sqrt(0.5);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const double fy = double(y < H / 2 ? y : y - H) / H, fx = double(x < W / 2 ? x : x - W) / W;
            const int ring = std::min(rings - 1, int(std::hypot(fx, fy) / outer * rings));
            double angle = std::atan2(fy, fx);
            if (angle < 0) angle += std::numbers::pi;
            const int sector = std::min(sectors - 1, int(angle / std::numbers::pi * sectors));
            band[size_t(y) * size_t(W) + size_t(x)] = ring * sectors + sector;
        }
    std::vector<double> cross(size_t(bands), 0.0), power(size_t(bands), 0.0);
    double truthEnergy = 0, kept = 0;
    for (size_t i = 0; i < X.size(); ++i) {
        cross[size_t(band[i])] += (X[i] * std::conj(T[i])).real();
        const double t = std::norm(T[i]);
        power[size_t(band[i])] += t;
        truthEnergy += t;
        kept += std::min(std::norm(X[i]), t);
    }
    if (!(truthEnergy > 0))
        throw Error("the reference image is constant: it has no detail to measure aliasing against");
    double residual = 0;
    for (size_t i = 0; i < X.size(); ++i) {
        const size_t b = size_t(band[i]);
        const double gain = power[b] > 0 ? std::clamp(cross[b] / power[b], 0.0, kMostGain) : 0.0;
        residual += std::norm(X[i] - gain * T[i]);
    }
    AliasingScore score;
    score.aliasing = residual / truthEnergy, score.detailKept = kept / truthEnergy;
    score.rings = rings, score.sectors = sectors;
    return score;
}

}  // namespace dejag

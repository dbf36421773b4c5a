// Losses: value and gradient side by side (see nn/losses.h).
#include "nn/losses.h"

#include <array>
#include <utility>

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "base/error.h"
#include "base/thread_pool.h"

namespace dejag::nn {
namespace {

constexpr int kRadius = 5, kTaps = 11;
constexpr double kK1 = 0.01, kK2 = 0.03, kSigma = 1.5;

struct GaussianWindow {
    double w[kTaps];
    GaussianWindow() {
        double sum = 0.0;
        for (int k = 0; k < kTaps; ++k) {
            const double x = k - kRadius;
            w[k] = std::exp(-0.5 * x * x / (kSigma * kSigma));
            sum += w[k];
        }
        for (double& v : w) v /= sum;
    }
};

const GaussianWindow& window() {
    static const GaussianWindow g;
    return g;
}

// Valid separable filter of `count` planes of (H, W) into (H - 10, W - 10).
void filterValid(const double* in, double* tmp, double* out, int64_t H, int64_t W) {
    const double* w = window().w;
    const int64_t OH = H - 2 * kRadius, OW = W - 2 * kRadius;
    for (int64_t y = 0; y < H; ++y)
        for (int64_t x = 0; x < OW; ++x) {
            double s = 0.0;
            for (int k = 0; k < kTaps; ++k) s += w[k] * in[y * W + x + k];
            tmp[y * OW + x] = s;
        }
    for (int64_t y = 0; y < OH; ++y)
        for (int64_t x = 0; x < OW; ++x) {
            double s = 0.0;
            for (int k = 0; k < kTaps; ++k) s += w[k] * tmp[(y + k) * OW + x];
            out[y * OW + x] = s;
        }
}

// Transpose of filterValid: (H - 10, W - 10) -> (H, W), adding.
void filterValidTransposed(const double* in, double* tmp, double* out, int64_t H, int64_t W) {
    const double* w = window().w;
    const int64_t OH = H - 2 * kRadius, OW = W - 2 * kRadius;
    for (int64_t i = 0; i < H * OW; ++i) tmp[i] = 0.0;
    for (int64_t y = 0; y < OH; ++y)
        for (int k = 0; k < kTaps; ++k)
            for (int64_t x = 0; x < OW; ++x) tmp[(y + k) * OW + x] += w[k] * in[y * OW + x];
    for (int64_t y = 0; y < H; ++y)
        for (int64_t x = 0; x < OW; ++x)
            for (int k = 0; k < kTaps; ++k) out[y * W + x + k] += w[k] * tmp[y * OW + x];
}

// Per plane: the five moment maps, and the SSIM map (valid region).
struct PlaneMoments {
    std::vector<double> x, y, mx, my, exx, eyy, exy, tmp, product, ssim;
    // x, y: the planes shifted by -shift (moments are shift-invariant; the shift tames cancellation).
    void compute(const double c1, const double c2, int64_t H, int64_t W, double shift) {
        const int64_t valid = (H - 2 * kRadius) * (W - 2 * kRadius);
        mx.resize(valid), my.resize(valid), exx.resize(valid), eyy.resize(valid), exy.resize(valid),
            ssim.resize(valid);
        tmp.resize(H * (W - 2 * kRadius));
        product.resize(H * W);
        filterValid(x.data(), tmp.data(), mx.data(), H, W);
        filterValid(y.data(), tmp.data(), my.data(), H, W);
        for (int64_t i = 0; i < H * W; ++i) product[i] = x[i] * x[i];
        filterValid(product.data(), tmp.data(), exx.data(), H, W);
        for (int64_t i = 0; i < H * W; ++i) product[i] = y[i] * y[i];
        filterValid(product.data(), tmp.data(), eyy.data(), H, W);
        for (int64_t i = 0; i < H * W; ++i) product[i] = x[i] * y[i];
        filterValid(product.data(), tmp.data(), exy.data(), H, W);
        for (int64_t i = 0; i < valid; ++i) {
            const double vx = exx[i] - mx[i] * mx[i], vy = eyy[i] - my[i] * my[i],
                         cxy = exy[i] - mx[i] * my[i];
            const double ux = mx[i] + shift, uy = my[i] + shift;
            ssim[i] = ((2 * ux * uy + c1) * (2 * cxy + c2)) / ((ux * ux + uy * uy + c1) * (vx + vy + c2));
        }
    }
};

template <class T>
void loadPlane(std::vector<double>& out, const T* in, int64_t count, double shift) {
    out.resize(count);
    for (int64_t i = 0; i < count; ++i) out[i] = double(in[i]) - shift;
}

}  // namespace

void SsimLossDesc::validate() const {
    if (batch < 1 || channels < 1) throw Error("SSIM loss: batch and channels must be >= 1");
    if (height < kTaps || width < kTaps)
        throw Error("SSIM loss: planes are " + std::to_string(height) + "x" + std::to_string(width) +
                    ", smaller than the 11x11 window");
    if (!(dataRange > 0.0) || !std::isfinite(dataRange))
        throw Error("SSIM loss: the data range must be positive");
}

template <class T>
double l1Loss(const T* pred, const T* target, int64_t n) {
    double sum = 0.0;
    for (int64_t i = 0; i < n; ++i) sum += std::abs(double(pred[i]) - double(target[i]));
    return sum / double(n);
}

template <class T>
void l1LossBackward(T* dpred, const T* pred, const T* target, int64_t n, double scale) {
    const double g = scale / double(n);
    for (int64_t i = 0; i < n; ++i) {
        const double d = double(pred[i]) - double(target[i]);
        dpred[i] += T(d > 0 ? g : (d < 0 ? -g : 0.0));
    }
}

template <class T>
double mseLoss(const T* pred, const T* target, int64_t n) {
    double sum = 0.0;
    for (int64_t i = 0; i < n; ++i) {
        const double d = double(pred[i]) - double(target[i]);
        sum += d * d;
    }
    return sum / double(n);
}

template <class T>
void mseLossBackward(T* dpred, const T* pred, const T* target, int64_t n, double scale) {
    const double g = 2.0 * scale / double(n);
    for (int64_t i = 0; i < n; ++i) dpred[i] += T(g * (double(pred[i]) - double(target[i])));
}

template <class T>
double ssimLoss(const T* pred, const T* target, const SsimLossDesc& d) {
    d.validate();
    const int64_t planes = d.batch * d.channels, H = d.height, W = d.width;
    const double c1 = (kK1 * d.dataRange) * (kK1 * d.dataRange),
                 c2 = (kK2 * d.dataRange) * (kK2 * d.dataRange);
    std::vector<double> planeSums(planes, 0.0);
    parallelFor(0, planes, 1, [&](int64_t first, int64_t last) {
        PlaneMoments m;
        for (int64_t p = first; p < last; ++p) {
            // Shift both by the target's first sample.
            const double shift = double(target[p * H * W]);
            loadPlane(m.x, target + p * H * W, H * W, shift);
            loadPlane(m.y, pred + p * H * W, H * W, shift);
            m.compute(c1, c2, H, W, shift);
            double sum = 0.0;
            for (double v : m.ssim) sum += v;
            planeSums[p] = sum;
        }
    });
    double total = 0.0;
    for (double s : planeSums) total += s;
    return 1.0 - total / (double(planes) * double((H - 2 * kRadius) * (W - 2 * kRadius)));
}

template <class T>
void ssimLossBackward(T* dpred, const T* pred, const T* target, const SsimLossDesc& d, double scale) {
    d.validate();
    const int64_t planes = d.batch * d.channels, H = d.height, W = d.width;
    const int64_t valid = (H - 2 * kRadius) * (W - 2 * kRadius);
    const double c1 = (kK1 * d.dataRange) * (kK1 * d.dataRange),
                 c2 = (kK2 * d.dataRange) * (kK2 * d.dataRange);
    // Loss = 1 - mean S  =>  dLoss/dS_p = -1 / (planes * valid).
    const double dS = -scale / (double(planes) * double(valid));
    parallelFor(0, planes, 1, [&](int64_t first, int64_t last) {
        PlaneMoments m;
        std::vector<double> a(valid), b(valid), c(valid), ga(H * W), gb(H * W), gc(H * W),
            tmp(H * (W - 2 * kRadius));
        for (int64_t p = first; p < last; ++p) {
            const double shift = double(target[p * H * W]);
            loadPlane(m.x, target + p * H * W, H * W, shift);
            loadPlane(m.y, pred + p * H * W, H * W, shift);
            m.compute(c1, c2, H, W, shift);
            // S = A1 A2 / (B1 B2) in terms of the moments of the shifted samples (mean of y: my + shift).
            for (int64_t i = 0; i < valid; ++i) {
                const double mxs = m.mx[i], mys = m.my[i];
                const double ux = mxs + shift, uy = mys + shift;
                const double vx = m.exx[i] - mxs * mxs, vy = m.eyy[i] - mys * mys, cxy = m.exy[i] - mxs * mys;
                const double A1 = 2 * ux * uy + c1, A2 = 2 * cxy + c2;
                const double B1 = ux * ux + uy * uy + c1, B2 = vx + vy + c2;
                const double S = (A1 * A2) / (B1 * B2);
                const double dS_duy = 2 * ux * A2 / (B1 * B2) - S * 2 * uy / B1;  // luminance, direct
                const double dS_dvy = -S / B2;
                const double dS_dcxy = 2 * A1 / (B1 * B2);
                // Chain through vy = E[ys^2] - mys^2 and cxy = E[xs ys] - mxs mys (ys = y - shift).
                a[i] = dS * (dS_duy - 2 * mys * dS_dvy - mxs * dS_dcxy);
                b[i] = dS * dS_dvy;
                c[i] = dS * dS_dcxy;
            }
            std::fill(ga.begin(), ga.end(), 0.0);
            std::fill(gb.begin(), gb.end(), 0.0);
            std::fill(gc.begin(), gc.end(), 0.0);
            filterValidTransposed(a.data(), tmp.data(), ga.data(), H, W);
            filterValidTransposed(b.data(), tmp.data(), gb.data(), H, W);
            filterValidTransposed(c.data(), tmp.data(), gc.data(), H, W);
            T* g = dpred + p * H * W;
            for (int64_t q = 0; q < H * W; ++q) g[q] += T(ga[q] + 2 * m.y[q] * gb[q] + m.x[q] * gc[q]);
        }
    });
}

namespace {
// Sample n's mean squared errors of the prediction and of the input against the target.
template <class T>
std::pair<double, double> harmErrors(const T* pred, const T* input, const T* target, int64_t n,
                                     int64_t perSample) {
    const int64_t o = n * perSample;
    double predicted = 0.0, given = 0.0;
    for (int64_t i = 0; i < perSample; ++i) {
        const double dp = double(pred[o + i]) - double(target[o + i]);
        const double di = double(input[o + i]) - double(target[o + i]);
        predicted += dp * dp, given += di * di;
    }
    return {predicted / double(perSample), given / double(perSample)};
}
}  // namespace

template <class T>
double harmLoss(const T* pred, const T* input, const T* target, int64_t batch, int64_t perSample) {
    double total = 0.0;
    for (int64_t n = 0; n < batch; ++n) {
        const auto [predicted, given] = harmErrors(pred, input, target, n, perSample);
        if (predicted > given) total += (predicted - given) / (given + kHarmEpsilon);
    }
    return total / double(batch);
}

template <class T>
void harmLossBackward(T* dpred, const T* pred, const T* input, const T* target, int64_t batch,
                      int64_t perSample, double scale) {
    for (int64_t n = 0; n < batch; ++n) {
        const auto [predicted, given] = harmErrors(pred, input, target, n, perSample);
        if (!(predicted > given)) continue;  // the same comparison as the value
        const double k = scale * 2.0 / (double(batch) * double(perSample) * (given + kHarmEpsilon));
        const int64_t o = n * perSample;
        for (int64_t i = 0; i < perSample; ++i)
            dpred[o + i] += T(k * (double(pred[o + i]) - double(target[o + i])));
    }
}

namespace {
// Calls f(offset of the block's first element in sample n's plane c, block width, block height, n) for
// every block of every sample; the element (c, y, x) of the block is at offset + c * H * W + y * W + x.
template <class F>
void forEachHarmTile(const SsimLossDesc& d, int tile, F&& f) {
    for (int64_t n = 0; n < d.batch; ++n)
        for (int64_t y0 = 0; y0 < d.height; y0 += tile)
            for (int64_t x0 = 0; x0 < d.width; x0 += tile)
                f(n * d.channels * d.height * d.width + y0 * d.width + x0,
                  std::min<int64_t>(tile, d.width - x0), std::min<int64_t>(tile, d.height - y0));
}

int64_t harmTileCount(const SsimLossDesc& d, int tile) {
    return d.batch * ((d.height + tile - 1) / tile) * ((d.width + tile - 1) / tile);
}

// A block's mean squared errors of the prediction and of the input against the target.
template <class T>
std::pair<double, double> tileErrors(const T* pred, const T* input, const T* target, const SsimLossDesc& d,
                                     int64_t at, int64_t w, int64_t h) {
    double predicted = 0.0, given = 0.0;
    for (int64_t c = 0; c < d.channels; ++c)
        for (int64_t y = 0; y < h; ++y)
            for (int64_t x = 0; x < w; ++x) {
                const int64_t i = at + (c * d.height + y) * d.width + x;
                const double dp = double(pred[i]) - double(target[i]),
                             di = double(input[i]) - double(target[i]);
                predicted += dp * dp, given += di * di;
            }
    const double count = double(d.channels * w * h);
    return {predicted / count, given / count};
}
}  // namespace

template <class T>
double harmTilesLoss(const T* pred, const T* input, const T* target, const SsimLossDesc& d, int tile) {
    if (tile < 1) throw Error("harm: the block side must be at least 1");
    double total = 0.0;
    forEachHarmTile(d, tile, [&](int64_t at, int64_t w, int64_t h) {
        const auto [predicted, given] = tileErrors(pred, input, target, d, at, w, h);
        if (predicted > given) total += (predicted - given) / (given + kHarmEpsilon);
    });
    return total / double(harmTileCount(d, tile));
}

template <class T>
void harmTilesLossBackward(T* dpred, const T* pred, const T* input, const T* target, const SsimLossDesc& d,
                           int tile, double scale) {
    if (tile < 1) throw Error("harm: the block side must be at least 1");
    const double tiles = double(harmTileCount(d, tile));
    forEachHarmTile(d, tile, [&](int64_t at, int64_t w, int64_t h) {
        const auto [predicted, given] = tileErrors(pred, input, target, d, at, w, h);
        if (!(predicted > given)) return;  // the same comparison as the value
        const double k = scale * 2.0 / (tiles * double(d.channels * w * h) * (given + kHarmEpsilon));
        for (int64_t c = 0; c < d.channels; ++c)
            for (int64_t y = 0; y < h; ++y)
                for (int64_t x = 0; x < w; ++x) {
                    const int64_t i = at + (c * d.height + y) * d.width + x;
                    dpred[i] += T(k * (double(pred[i]) - double(target[i])));
                }
    });
}

namespace {
// Sample n's masked mean squared errors of the prediction and of the input, and the mask's sum.
template <class T>
std::array<double, 3> maskedErrors(const T* pred, const T* input, const T* target, const T* mask,
                                   const SsimLossDesc& d, int64_t n) {
    const int64_t plane = d.height * d.width;
    double predicted = 0.0, given = 0.0, weight = 0.0;
    const T* m = mask + n * plane;
    for (int64_t i = 0; i < plane; ++i) weight += double(m[i]);
    if (!(weight > 0)) return {0.0, 0.0, 0.0};
    for (int64_t c = 0; c < d.channels; ++c) {
        const int64_t o = (n * d.channels + c) * plane;
        for (int64_t i = 0; i < plane; ++i) {
            if (m[i] == T(0)) continue;
            const double dp = double(pred[o + i]) - double(target[o + i]),
                         di = double(input[o + i]) - double(target[o + i]);
            predicted += double(m[i]) * dp * dp, given += double(m[i]) * di * di;
        }
    }
    const double count = double(d.channels) * weight;
    return {predicted / count, given / count, weight};
}
}  // namespace

template <class T>
double maskedHarmLoss(const T* pred, const T* input, const T* target, const T* mask, const SsimLossDesc& d) {
    double total = 0.0;
    for (int64_t n = 0; n < d.batch; ++n) {
        const auto [predicted, given, weight] = maskedErrors(pred, input, target, mask, d, n);
        if (weight > 0 && predicted > given) total += (predicted - given) / (given + kHarmEpsilon);
    }
    return total / double(d.batch);
}

template <class T>
void maskedHarmLossBackward(T* dpred, const T* pred, const T* input, const T* target, const T* mask,
                            const SsimLossDesc& d, double scale) {
    const int64_t plane = d.height * d.width;
    for (int64_t n = 0; n < d.batch; ++n) {
        const auto [predicted, given, weight] = maskedErrors(pred, input, target, mask, d, n);
        if (!(weight > 0 && predicted > given)) continue;  // the same comparison as the value
        const double k =
            scale * 2.0 / (double(d.batch) * double(d.channels) * weight * (given + kHarmEpsilon));
        const T* m = mask + n * plane;
        for (int64_t c = 0; c < d.channels; ++c) {
            const int64_t o = (n * d.channels + c) * plane;
            for (int64_t i = 0; i < plane; ++i)
                if (m[i] != T(0))
                    dpred[o + i] += T(k * double(m[i]) * (double(pred[o + i]) - double(target[o + i])));
        }
    }
}

CompositeLoss CompositeLoss::parse(const std::string& text) {
    CompositeLoss loss;
    size_t start = 0;
    while (start <= text.size()) {
        const size_t plus = std::min(text.find('+', start), text.size());
        const std::string term = text.substr(start, plus - start);
        start = plus + 1;
        if (term.empty()) throw Error("loss '" + text + "' has an empty term");
        LossTerm t;
        std::string name = term;
        const size_t star = term.find('*');
        if (star != std::string::npos) {
            char* end = nullptr;
            t.weight = std::strtod(term.c_str(), &end);
            if (end != term.c_str() + star || !(t.weight > 0) || !std::isfinite(t.weight))
                throw Error("loss '" + text + "': '" + term.substr(0, star) + "' is not a positive weight");
            name = term.substr(star + 1);
        }
        if (name == "ssim")
            t.kind = LossKind::Ssim;
        else if (name == "l1")
            t.kind = LossKind::L1;
        else if (name == "mse")
            t.kind = LossKind::Mse;
        else if (name == "harm")
            t.kind = LossKind::Harm;
        else if (name == "texharm")
            t.kind = LossKind::MaskedHarm;
        else if (name.rfind("harm", 0) == 0 && name.size() > 4 && name.size() <= 8 &&
                 std::all_of(name.begin() + 4, name.end(), [](char ch) { return ch >= '0' && ch <= '9'; }) &&
                 std::stoi(name.substr(4)) >= 1)
            t.kind = LossKind::Harm, t.tile = std::stoi(name.substr(4));
        else
            throw Error("loss '" + text + "': unknown term '" + name +
                        "' (ssim, l1, mse, harm, harmN, texharm)");
        loss.terms.push_back(t);
    }
    return loss;
}

std::string CompositeLoss::describe() const {
    std::string text;
    for (const LossTerm& t : terms) {
        if (!text.empty()) text += " + ";
        std::ostringstream weight;
        weight << t.weight;
        text += weight.str() + " * " +
                (t.kind == LossKind::Ssim ? "(1 - SSIM)"
                 : t.kind == LossKind::L1 ? "L1"
                 : t.kind == LossKind::Harm
                     ? (t.tile > 0 ? "harm per " + std::to_string(t.tile) + " px block" : std::string("harm"))
                 : t.kind == LossKind::MaskedHarm ? "harm on texture pixels"
                                                  : "MSE");
    }
    return text;
}

bool CompositeLoss::needsInput() const {
    for (const LossTerm& t : terms)
        if (t.kind == LossKind::Harm || t.kind == LossKind::MaskedHarm) return true;
    return false;
}

bool CompositeLoss::needsMask() const {
    for (const LossTerm& t : terms)
        if (t.kind == LossKind::MaskedHarm) return true;
    return false;
}

template <class T>
double CompositeLoss::evaluate(T* dpred, const T* pred, const T* target, const SsimLossDesc& shape,
                               double scale, const T* input, const T* mask) const {
    const int64_t n = shape.batch * shape.channels * shape.height * shape.width;
    double value = 0.0;
    for (const LossTerm& t : terms) {
        switch (t.kind) {
            case LossKind::Ssim:
                value += t.weight * ssimLoss(pred, target, shape);
                if (dpred) ssimLossBackward(dpred, pred, target, shape, scale * t.weight);
                break;
            case LossKind::L1:
                value += t.weight * l1Loss(pred, target, n);
                if (dpred) l1LossBackward(dpred, pred, target, n, scale * t.weight);
                break;
            case LossKind::Mse:
                value += t.weight * mseLoss(pred, target, n);
                if (dpred) mseLossBackward(dpred, pred, target, n, scale * t.weight);
                break;
            case LossKind::Harm: {
                if (!input) throw Error("the loss's harm term needs the network's input");
                if (t.tile > 0) {
                    value += t.weight * harmTilesLoss(pred, input, target, shape, t.tile);
                    if (dpred)
                        harmTilesLossBackward(dpred, pred, input, target, shape, t.tile, scale * t.weight);
                    break;
                }
                const int64_t perSample = n / shape.batch;
                value += t.weight * harmLoss(pred, input, target, shape.batch, perSample);
                if (dpred)
                    harmLossBackward(dpred, pred, input, target, shape.batch, perSample, scale * t.weight);
                break;
            }
            case LossKind::MaskedHarm:
                if (!input || !mask)
                    throw Error("the loss's texharm term needs the network's input and a mask");
                value += t.weight * maskedHarmLoss(pred, input, target, mask, shape);
                if (dpred) maskedHarmLossBackward(dpred, pred, input, target, mask, shape, scale * t.weight);
                break;
        }
    }
    return value;
}

#define DEJAG_INSTANTIATE(T)                                                                                 \
    template double l1Loss<T>(const T*, const T*, int64_t);                                                  \
    template void l1LossBackward<T>(T*, const T*, const T*, int64_t, double);                                \
    template double mseLoss<T>(const T*, const T*, int64_t);                                                 \
    template void mseLossBackward<T>(T*, const T*, const T*, int64_t, double);                               \
    template double ssimLoss<T>(const T*, const T*, const SsimLossDesc&);                                    \
    template void ssimLossBackward<T>(T*, const T*, const T*, const SsimLossDesc&, double);                  \
    template double harmLoss<T>(const T*, const T*, const T*, int64_t, int64_t);                             \
    template void harmLossBackward<T>(T*, const T*, const T*, const T*, int64_t, int64_t, double);           \
    template double harmTilesLoss<T>(const T*, const T*, const T*, const SsimLossDesc&, int);                \
    template void harmTilesLossBackward<T>(T*, const T*, const T*, const T*, const SsimLossDesc&, int,       \
                                           double);                                                          \
    template double maskedHarmLoss<T>(const T*, const T*, const T*, const T*, const SsimLossDesc&);          \
    template void maskedHarmLossBackward<T>(T*, const T*, const T*, const T*, const T*, const SsimLossDesc&, \
                                            double);                                                         \
    template double CompositeLoss::evaluate<T>(T*, const T*, const T*, const SsimLossDesc&, double,          \
                                               const T*, const T*) const;
DEJAG_INSTANTIATE(float)
DEJAG_INSTANTIATE(double)
#undef DEJAG_INSTANTIATE

}  // namespace dejag::nn

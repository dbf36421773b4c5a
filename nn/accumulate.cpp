// The accumulate blend, forward and backward (see nn/layers.h).
#include <algorithm>
#include <cmath>
#include <string>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/layers.h"

namespace dejag::nn {
namespace {

constexpr int kMaxKernel = 7, kMaxTaps = kMaxKernel * kMaxKernel, kMaxChannels = 64;

// Calls body(n, y, x, at, w, offset) for every pixel (at = y W + x), rows split across the thread
// pool, with the softmax weights of its k^2 spatial logits and its taps' offsets in the plane.
template <class T, class F>
void forEachPixel(const AccumulateDesc& d, const T* logits, const F& body) {
    const int r = d.kernel / 2, taps = int(d.taps());
    const int64_t plane = d.height * d.width, count = taps + 1;
    parallelFor(0, d.batch * d.height, 1, [&](int64_t first, int64_t last) {
        T w[kMaxTaps];
        int64_t offset[kMaxTaps];
        for (int64_t row = first; row < last; ++row) {
            const int64_t n = row / d.height, y = row % d.height;
            for (int64_t x = 0; x < d.width; ++x) {
                const int64_t at = y * d.width + x;
                const T* l = logits + n * count * plane + at;
                T largest = -INFINITY, sum = 0;
                for (int j = 0; j < taps; ++j) largest = std::max(largest, w[j] = l[j * plane]);
                for (int j = 0; j < taps; ++j) sum += (w[j] = std::exp(w[j] - largest));
                for (int j = 0; j < taps; ++j) w[j] /= sum;
                for (int dy = -r, j = 0; dy <= r; ++dy)
                    for (int dx = -r; dx <= r; ++dx, ++j)
                        offset[j] = std::clamp<int64_t>(y + dy, 0, d.height - 1) * d.width +
                                    std::clamp<int64_t>(x + dx, 0, d.width - 1);
                body(n, at, w, offset);
            }
        }
    });
}

// The history's colour h clamped to [D(min), D(max)] of the taps' samples; bound: the tap whose sample
// bounds it (the first in tap order), -1 inside the range.
template <class T>
T clipToTaps(T h, const T* source, const int64_t* offset, int64_t taps, int& bound) {
    int low = 0, high = 0;
    for (int j = 1; j < taps; ++j) {
        if (source[offset[j]] < source[offset[low]]) low = j;
        if (source[offset[j]] > source[offset[high]]) high = j;
    }
    const T lo = srgbDecode(source[offset[low]]), hi = srgbDecode(source[offset[high]]);
    bound = h < lo ? low : h > hi ? high : -1;
    return h < lo ? lo : h > hi ? hi : h;
}

}  // namespace

void AccumulateDesc::validate() const {
    if (batch < 1 || channels < 1 || channels > kMaxChannels || height < 1 || width < 1)
        throw Error("Accumulate: sizes must be >= 1 (and at most " + std::to_string(kMaxChannels) +
                    " channels)");
    if (kernel < 1 || kernel > kMaxKernel || kernel % 2 == 0)
        throw Error("Accumulate: kernel must be odd and 1.." + std::to_string(kMaxKernel));
    if (!(maxCount >= 1.0f) || !std::isfinite(maxCount)) throw Error("Accumulate: max_count must be >= 1");
}

template <class T>
void accumulateForward(T* out, const T* image, const T* logits, const T* history, const AccumulateDesc& d) {
    d.validate();
    const int64_t C = d.channels, plane = d.height * d.width, taps = d.taps();
    forEachPixel(d, logits, [&](int64_t n, int64_t at, const T* w, const int64_t* offset) {
        T spatial[kMaxChannels], sample[kMaxChannels], hist[kMaxChannels], shown[kMaxChannels],
            kept[kMaxChannels];
        for (int64_t c = 0; c < C; ++c) {
            const T* source = image + (n * C + c) * plane;
            T sum = 0;
            for (int64_t j = 0; j < taps; ++j) sum += w[j] * source[offset[j]];
            spatial[c] = sum;
            sample[c] = source[at];
            hist[c] = history[(n * (C + 1) + c) * plane + at];
            int bound;
            if (d.clip) hist[c] = clipToTaps(hist[c], source, offset, taps, bound);
        }
        const T trust = logits[(n * (taps + 1) + taps) * plane + at];
        const T s = accumulatePixel(shown, kept, spatial, sample, hist, C, trust,
                                    history[(n * (C + 1) + C) * plane + at], T(d.maxCount));
        T* o = out + n * (2 * C + 1) * plane + at;
        for (int64_t c = 0; c < C; ++c) o[c * plane] = shown[c], o[(C + c) * plane] = kept[c];
        o[2 * C * plane] = s;
    });
}

template <class T>
void accumulateBackward(T* dimage, T* dlogits, T* dhistory, const T* dout, const T* image, const T* logits,
                        const T* history, const AccumulateDesc& d) {
    d.validate();
    const int64_t C = d.channels, plane = d.height * d.width, taps = d.taps(), count = taps + 1;
    const T N = T(d.maxCount), maxConfidence = N / (N + T(1));
    // Per pixel: the blend's parts, as the forward computes them.
    struct Parts {
        T a, m, n, rho, drho, s;
        bool inside, uncapped;
    };
    auto parts = [&](int64_t n, int64_t at) {
        Parts p;
        const T raw = history[(n * (C + 1) + C) * plane + at];
        p.s = std::clamp(raw, T(0), maxConfidence);
        p.inside = raw > T(0) && raw < maxConfidence;
        p.n = p.s / (T(1) - p.s);
        const T sigmoid = T(1) / (T(1) + std::exp(-logits[(n * count + taps) * plane + at]));
        p.rho = std::min(T(1), T(2) * sigmoid);
        p.drho = T(2) * sigmoid < T(1) ? T(2) * sigmoid * (T(1) - sigmoid) : T(0);
        p.m = p.rho * p.n;
        p.a = p.m / (T(1) + p.m);
        p.uncapped = T(1) + p.m < N;
        return p;
    };
    if (dlogits || dhistory)
        forEachPixel(d, logits, [&](int64_t n, int64_t at, const T* w, const int64_t* offset) {
            const Parts p = parts(n, at);
            // With u_c = D(spatial_c) + a (h_c - D(spatial_c)) (shown = E(u)) and g, k the gradients of shown
            // and kept: d/da = sum_c g_c E'(u_c) (h_c - D(spatial_c)) + k_c (h_c - D(image_c)); the spatial
            // logits see g_c E'(u_c) (1 - a) D'(spatial_c) per colour.
            T da = 0, g[kMaxTaps] = {}, mean = 0;
            const T* go = dout + n * (2 * C + 1) * plane + at;
            for (int64_t c = 0; c < C; ++c) {
                const T* source = image + (n * C + c) * plane;
                const T gc = go[c * plane], kc = go[(C + c) * plane];
                int bound = -1;
                T h = history[(n * (C + 1) + c) * plane + at];
                if (d.clip) h = clipToTaps(h, source, offset, taps, bound);
                T spatial = 0;
                for (int64_t j = 0; j < taps; ++j) spatial += w[j] * source[offset[j]];
                const T filtered = srgbDecode(spatial), own = srgbDecode(source[at]);
                const T gu = gc * srgbEncodeSlope(filtered + p.a * (h - filtered));
                const T dspatial = gu * (T(1) - p.a) * srgbDecodeSlope(spatial);
                for (int64_t j = 0; j < taps; ++j) g[j] += dspatial * source[offset[j]];
                da += gu * (h - filtered) + kc * (h - own);
                if (dhistory && bound < 0) dhistory[(n * (C + 1) + c) * plane + at] += p.a * (gu + kc);
            }
            const T gs = go[2 * C * plane];
            const T dm =
                da / ((T(1) + p.m) * (T(1) + p.m)) + (p.uncapped ? gs / ((T(2) + p.m) * (T(2) + p.m)) : T(0));
            if (dlogits) {
                for (int64_t j = 0; j < taps; ++j) mean += w[j] * g[j];
                for (int64_t j = 0; j < taps; ++j)
                    dlogits[(n * count + j) * plane + at] += w[j] * (g[j] - mean);
                dlogits[(n * count + taps) * plane + at] += dm * p.n * p.drho;
            }
            if (dhistory && p.inside) {
                const T oneMinus = T(1) - p.s;
                dhistory[(n * (C + 1) + C) * plane + at] += dm * p.rho / (oneMinus * oneMinus);
            }
        });
    if (dimage) {
        // Each tap sends w_j times the spatial colour's gradient back to the pixel it read, and the kept
        // colour (1 - a) D'(image) k to the pixel's own; one thread per batch item, in a fixed order.
        parallelFor(0, d.batch, 1, [&](int64_t first, int64_t last) {
            for (int64_t n = first; n < last; ++n) {
                const T* l = logits + n * count * plane;
                const T* im = image + n * C * plane;
                T* di = dimage + n * C * plane;
                const T* go = dout + n * (2 * C + 1) * plane;
                const int r = d.kernel / 2;
                for (int64_t y = 0; y < d.height; ++y)
                    for (int64_t x = 0; x < d.width; ++x) {
                        const int64_t at = y * d.width + x;
                        T w[kMaxTaps], largest = -INFINITY, sum = 0;
                        int64_t offset[kMaxTaps];
                        for (int j = 0; j < taps; ++j) largest = std::max(largest, w[j] = l[j * plane + at]);
                        for (int j = 0; j < taps; ++j) sum += (w[j] = std::exp(w[j] - largest));
                        for (int dy = -r, j = 0; dy <= r; ++dy)
                            for (int dx = -r; dx <= r; ++dx, ++j)
                                offset[j] = std::clamp<int64_t>(y + dy, 0, d.height - 1) * d.width +
                                            std::clamp<int64_t>(x + dx, 0, d.width - 1);
                        const Parts p = parts(n, at);
                        for (int64_t c = 0; c < C; ++c) {
                            const T* source = im + c * plane;
                            int bound = -1;
                            T h = history[(n * (C + 1) + c) * plane + at];
                            if (d.clip) h = clipToTaps(h, source, offset, taps, bound);
                            T spatial = 0;
                            for (int j = 0; j < taps; ++j) spatial += w[j] / sum * source[offset[j]];
                            const T filtered = srgbDecode(spatial);
                            const T gu =
                                go[c * plane + at] * srgbEncodeSlope(filtered + p.a * (h - filtered));
                            const T dspatial = gu * (T(1) - p.a) * srgbDecodeSlope(spatial);
                            for (int j = 0; j < taps; ++j) di[c * plane + offset[j]] += w[j] / sum * dspatial;
                            di[c * plane + at] +=
                                (T(1) - p.a) * srgbDecodeSlope(source[at]) * go[(C + c) * plane + at];
                            if (bound >= 0)  // the clipped history is the bounding tap's decoded sample
                                di[c * plane + offset[bound]] += p.a * (gu + go[(C + c) * plane + at]) *
                                                                 srgbDecodeSlope(source[offset[bound]]);
                        }
                    }
            }
        });
    }
}

#define DEJAG_INSTANTIATE(T)                                                                     \
    template void accumulateForward<T>(T*, const T*, const T*, const T*, const AccumulateDesc&); \
    template void accumulateBackward<T>(T*, T*, T*, const T*, const T*, const T*, const T*,      \
                                        const AccumulateDesc&);
DEJAG_INSTANTIATE(float)
DEJAG_INSTANTIATE(double)
#undef DEJAG_INSTANTIATE

}  // namespace dejag::nn

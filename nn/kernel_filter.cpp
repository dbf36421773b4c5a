// The kernel filter, forward and backward (see nn/layers.h).
#include <algorithm>
#include <cmath>
#include <string>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/layers.h"

namespace dejag::nn {
namespace {

constexpr int kMaxKernel = 7, kMaxWeights = kMaxKernel * kMaxKernel + 1;

// The softmax weights of pixel (y, x) of batch item n: w[j], j over the k^2 taps.
template <class T>
void tapWeights(T* w, const T* logits, int64_t n, int64_t y, int64_t x, const KernelFilterDesc& d) {
    const int64_t weights = d.weights(), plane = d.height * d.width;
    const T* l = logits + n * weights * plane + y * d.width + x;
    for (int64_t j = 0; j < weights; ++j) w[j] = l[j * plane];
    kernelFilterWeights(w, w, d);
}

// Offsets of the k^2 taps of pixel (y, x) in its plane, clamped to the image.
void tapOffsets(int64_t* offset, int64_t y, int64_t x, const KernelFilterDesc& d) {
    const int r = d.kernel / 2;
    for (int dy = -r, j = 0; dy <= r; ++dy)
        for (int dx = -r; dx <= r; ++dx, ++j)
            offset[j] = std::clamp<int64_t>(y + dy, 0, d.height - 1) * d.width +
                        std::clamp<int64_t>(x + dx, 0, d.width - 1);
}

// Calls body(n, y, x, w, offset) for every pixel, rows split across the thread pool, with the pixel's
// tap weights and tap offsets.
template <class T, class F>
void forEachPixel(const KernelFilterDesc& d, const T* logits, const F& body) {
    parallelFor(0, d.batch * d.height, 1, [&](int64_t first, int64_t last) {
        T w[kMaxWeights];
        int64_t offset[kMaxKernel * kMaxKernel];
        for (int64_t row = first; row < last; ++row) {
            const int64_t n = row / d.height, y = row % d.height;
            for (int64_t x = 0; x < d.width; ++x) {
                tapWeights(w, logits, n, y, x, d);
                tapOffsets(offset, y, x, d);
                body(n, y, x, w, offset);
            }
        }
    });
}

}  // namespace

template <class T>
void kernelFilterWeights(T* weights, const T* logits, const KernelFilterDesc& d) {
    const int64_t count = d.weights(), centre = d.taps() / 2;
    T largest = -INFINITY;
    for (int64_t j = 0; j < count; ++j) {
        weights[j] = logits[j] + (j == centre ? T(d.centreBias) : T(0));
        largest = std::max(largest, weights[j]);
    }
    T sum = 0;
    for (int64_t j = 0; j < count; ++j) sum += (weights[j] = std::exp(weights[j] - largest));
    for (int64_t j = 0; j < count; ++j) weights[j] /= sum;
}

void KernelFilterDesc::validate() const {
    if (batch < 1 || channels < 1 || height < 1 || width < 1) throw Error("KernelFilter: sizes must be >= 1");
    if (kernel < 1 || kernel > kMaxKernel || kernel % 2 == 0)
        throw Error("KernelFilter: kernel must be odd and 1.." + std::to_string(kMaxKernel) + ", not " +
                    std::to_string(kernel));
    if (!std::isfinite(centreBias)) throw Error("KernelFilter: centre_bias must be finite");
}

template <class T>
void kernelFilterForward(T* out, const T* in, const T* logits, const KernelFilterDesc& d, const T* history) {
    d.validate();
    if (d.history != (history != nullptr))
        throw Error("KernelFilter: the history is given iff the desc has one");
    const int64_t H = d.height, W = d.width, C = d.channels, plane = H * W, taps = d.taps();
    forEachPixel(d, logits, [&](int64_t n, int64_t y, int64_t x, const T* w, const int64_t* offset) {
        for (int64_t c = 0; c < C; ++c) {
            const T* source = in + (n * C + c) * plane;
            T sum = 0;
            for (int64_t j = 0; j < taps; ++j) sum += w[j] * source[offset[j]];
            if (history) sum += w[taps] * history[(n * C + c) * plane + y * W + x];
            out[(n * C + c) * plane + y * W + x] = sum;
        }
    });
}

template <class T>
void kernelFilterBackward(T* dinput, T* dlogits, const T* dout, const T* in, const T* logits,
                          const KernelFilterDesc& d, T* dhistory, const T* history) {
    d.validate();
    if (d.history != (history != nullptr))
        throw Error("KernelFilter: the history is given iff the desc has one");
    const int64_t H = d.height, W = d.width, C = d.channels, plane = H * W, taps = d.taps(),
                  count = d.weights();
    if (dlogits) {
        // dL/dlogit_j = w_j (g_j - sum_k w_k g_k), g_j = sum_c dout_c in_c(tap j) (the history's own pixel
        // for the history's weight).
        forEachPixel(d, logits, [&](int64_t n, int64_t y, int64_t x, const T* w, const int64_t* offset) {
            T g[kMaxWeights], mean = 0;
            for (int64_t j = 0; j < count; ++j) {
                g[j] = 0;
                for (int64_t c = 0; c < C; ++c) {
                    const int64_t at = (n * C + c) * plane;
                    g[j] += dout[at + y * W + x] * (j < taps ? in[at + offset[j]] : history[at + y * W + x]);
                }
                mean += w[j] * g[j];
            }
            for (int64_t j = 0; j < count; ++j)
                dlogits[(n * count + j) * plane + y * W + x] += w[j] * (g[j] - mean);
        });
    }
    if (dhistory)
        forEachPixel(d, logits, [&](int64_t n, int64_t y, int64_t x, const T* w, const int64_t*) {
            for (int64_t c = 0; c < C; ++c) {
                const int64_t at = (n * C + c) * plane + y * W + x;
                dhistory[at] += w[taps] * dout[at];
            }
        });
    if (dinput) {
        // Each tap sends w_j dout back to the pixel it read; one thread per batch item, in a fixed order.
        parallelFor(0, d.batch, 1, [&](int64_t first, int64_t last) {
            T w[kMaxWeights];
            int64_t offset[kMaxKernel * kMaxKernel];
            for (int64_t n = first; n < last; ++n)
                for (int64_t y = 0; y < H; ++y)
                    for (int64_t x = 0; x < W; ++x) {
                        tapWeights(w, logits, n, y, x, d);
                        tapOffsets(offset, y, x, d);
                        for (int64_t c = 0; c < C; ++c) {
                            T* di = dinput + (n * C + c) * plane;
                            const T g = dout[(n * C + c) * plane + y * W + x];
                            for (int64_t j = 0; j < taps; ++j) di[offset[j]] += w[j] * g;
                        }
                    }
        });
    }
}

#define DEJAG_INSTANTIATE(T)                                                                                 \
    template void kernelFilterWeights<T>(T*, const T*, const KernelFilterDesc&);                             \
    template void kernelFilterForward<T>(T*, const T*, const T*, const KernelFilterDesc&, const T*);         \
    template void kernelFilterBackward<T>(T*, T*, const T*, const T*, const T*, const KernelFilterDesc&, T*, \
                                          const T*);
DEJAG_INSTANTIATE(float)
DEJAG_INSTANTIATE(double)
#undef DEJAG_INSTANTIATE

}  // namespace dejag::nn

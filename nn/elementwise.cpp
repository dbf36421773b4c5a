// Activations, Add and Concat, forward and backward: the reference kernels (see nn/layers.h).
#include <algorithm>
#include <cmath>
#include <cstring>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/layers.h"

namespace dejag::nn {

const char* activationName(Activation activation) {
    switch (activation) {
        case Activation::None:
            return "none";
        case Activation::ReLU:
            return "relu";
        case Activation::LeakyReLU:
            return "leaky_relu";
        case Activation::Sigmoid:
            return "sigmoid";
        case Activation::Clamp:
            return "clamp";
    }
    return "unknown";
}

Activation parseActivation(const std::string& name) {
    for (Activation a :
         {Activation::None, Activation::ReLU, Activation::LeakyReLU, Activation::Sigmoid, Activation::Clamp})
        if (name == activationName(a)) return a;
    throw Error("unknown activation '" + name + "' (none, relu, leaky_relu, sigmoid, clamp)");
}

namespace {
constexpr int64_t kElementGrain = 1 << 15;
}

template <class T>
void activationForward(T* out, const T* in, int64_t n, const ActivationDesc& d) {
    const T slope = T(d.slope), low = T(d.low), high = T(d.high);
    parallelFor(0, n, kElementGrain, [&](int64_t first, int64_t last) {
        switch (d.kind) {
            case Activation::None:
                if (out != in) std::memmove(out + first, in + first, size_t(last - first) * sizeof(T));
                break;
            case Activation::ReLU:
                for (int64_t i = first; i < last; ++i)
                    out[i] = in[i] > T(0) ? in[i] : (std::isnan(in[i]) ? in[i] : T(0));
                break;
            case Activation::LeakyReLU:
                for (int64_t i = first; i < last; ++i) out[i] = in[i] > T(0) ? in[i] : slope * in[i];
                break;
            case Activation::Sigmoid:
                // Stable on both tails: never exp() of a large positive number.
                for (int64_t i = first; i < last; ++i) {
                    const T x = in[i];
                    if (x >= T(0)) {
                        out[i] = T(1) / (T(1) + std::exp(-x));
                    } else {
                        const T e = std::exp(x);
                        out[i] = e / (T(1) + e);
                    }
                }
                break;
            case Activation::Clamp:
                for (int64_t i = first; i < last; ++i)
                    out[i] = std::isnan(in[i]) ? in[i] : std::clamp(in[i], low, high);
                break;
        }
    });
}

template <class T>
void activationBackward(T* dinput, const T* dout, const T* in, const T* out, int64_t n,
                        const ActivationDesc& d) {
    const T slope = T(d.slope), low = T(d.low), high = T(d.high);
    parallelFor(0, n, kElementGrain, [&](int64_t first, int64_t last) {
        switch (d.kind) {
            case Activation::None:
                for (int64_t i = first; i < last; ++i) dinput[i] += dout[i];
                break;
            case Activation::ReLU:
                for (int64_t i = first; i < last; ++i) dinput[i] += in[i] > T(0) ? dout[i] : T(0);
                break;
            case Activation::LeakyReLU:
                for (int64_t i = first; i < last; ++i) dinput[i] += in[i] > T(0) ? dout[i] : slope * dout[i];
                break;
            case Activation::Sigmoid:
                for (int64_t i = first; i < last; ++i) dinput[i] += dout[i] * out[i] * (T(1) - out[i]);
                break;
            case Activation::Clamp:
                // PyTorch: the gradient passes where low <= x <= high.
                for (int64_t i = first; i < last; ++i)
                    dinput[i] += (in[i] >= low && in[i] <= high) ? dout[i] : T(0);
                break;
        }
    });
}

template <class T>
void addForward(T* out, const T* a, const T* b, int64_t n) {
    parallelFor(0, n, kElementGrain, [&](int64_t first, int64_t last) {
        for (int64_t i = first; i < last; ++i) out[i] = a[i] + b[i];
    });
}

template <class T>
void addBackward(T* da, T* db, const T* dout, int64_t n) {
    parallelFor(0, n, kElementGrain, [&](int64_t first, int64_t last) {
        if (da)
            for (int64_t i = first; i < last; ++i) da[i] += dout[i];
        if (db)
            for (int64_t i = first; i < last; ++i) db[i] += dout[i];
    });
}

template <class T>
void concatForward(T* out, const std::vector<const T*>& inputs, const std::vector<int64_t>& channels,
                   int64_t batch, int64_t planeSize) {
    if (inputs.size() != channels.size()) throw Error("Concat: one channel count per input is needed");
    int64_t total = 0;
    for (int64_t c : channels) total += c;
    parallelFor(0, batch, 1, [&](int64_t first, int64_t last) {
        for (int64_t n = first; n < last; ++n) {
            T* o = out + n * total * planeSize;
            for (size_t i = 0; i < inputs.size(); ++i) {
                const int64_t count = channels[i] * planeSize;
                std::memcpy(o, inputs[i] + n * count, size_t(count) * sizeof(T));
                o += count;
            }
        }
    });
}

template <class T>
void concatBackward(const std::vector<T*>& dinputs, const T* dout, const std::vector<int64_t>& channels,
                    int64_t batch, int64_t planeSize) {
    if (dinputs.size() != channels.size()) throw Error("Concat: one channel count per input is needed");
    int64_t total = 0;
    for (int64_t c : channels) total += c;
    parallelFor(0, batch, 1, [&](int64_t first, int64_t last) {
        for (int64_t n = first; n < last; ++n) {
            const T* g = dout + n * total * planeSize;
            for (size_t i = 0; i < dinputs.size(); ++i) {
                const int64_t count = channels[i] * planeSize;
                if (dinputs[i]) {
                    T* di = dinputs[i] + n * count;
                    for (int64_t k = 0; k < count; ++k) di[k] += g[k];
                }
                g += count;
            }
        }
    });
}

#define DEJAG_INSTANTIATE(T)                                                                                \
    template void activationForward<T>(T*, const T*, int64_t, const ActivationDesc&);                       \
    template void activationBackward<T>(T*, const T*, const T*, const T*, int64_t, const ActivationDesc&);  \
    template void addForward<T>(T*, const T*, const T*, int64_t);                                           \
    template void addBackward<T>(T*, T*, const T*, int64_t);                                                \
    template void concatForward<T>(T*, const std::vector<const T*>&, const std::vector<int64_t>&, int64_t,  \
                                   int64_t);                                                                \
    template void concatBackward<T>(const std::vector<T*>&, const T*, const std::vector<int64_t>&, int64_t, \
                                    int64_t);
DEJAG_INSTANTIATE(float)
DEJAG_INSTANTIATE(double)
#undef DEJAG_INSTANTIATE

}  // namespace dejag::nn

// MaxPool2D forward and backward: the reference kernels (see nn/layers.h).
#include <algorithm>
#include <cmath>
#include <limits>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/layers.h"

namespace dejag::nn {

int64_t MaxPool2dDesc::outHeight() const {
    return (inHeight + 2 * int64_t(padding) - kernel) / stride + 1;
}
int64_t MaxPool2dDesc::outWidth() const {
    return (inWidth + 2 * int64_t(padding) - kernel) / stride + 1;
}

void MaxPool2dDesc::validate() const {
    auto require = [](bool ok, const std::string& what) {
        if (!ok) throw Error("MaxPool2D: " + what);
    };
    require(batch >= 1 && channels >= 1 && inHeight >= 1 && inWidth >= 1, "sizes must be >= 1");
    require(kernel >= 1 && stride >= 1, "kernel and stride must be >= 1");
    require(padding >= 0 && 2 * padding <= kernel, "padding must be between 0 and half the kernel");
    require(inHeight + 2 * padding >= kernel && inWidth + 2 * padding >= kernel,
            "the window does not fit the input");
    require(inHeight * inWidth <= std::numeric_limits<int32_t>::max(), "the input plane is too large");
}

template <class T>
void maxPool2dForward(T* out, int32_t* argmax, const T* in, const MaxPool2dDesc& d) {
    d.validate();
    const int64_t OH = d.outHeight(), OW = d.outWidth(), H = d.inHeight, W = d.inWidth;
    parallelFor(0, d.batch * d.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const T* input = in + plane * H * W;
            T* o = out + plane * OH * OW;
            int32_t* a = argmax + plane * OH * OW;
            for (int64_t oy = 0; oy < OH; ++oy)
                for (int64_t ox = 0; ox < OW; ++ox) {
                    // PyTorch's rule: start at -inf with the window's first cell, take strictly larger
                    // values and any NaN.
                    const int64_t y0 = std::max<int64_t>(0, oy * d.stride - d.padding);
                    const int64_t x0 = std::max<int64_t>(0, ox * d.stride - d.padding);
                    T best = -std::numeric_limits<T>::infinity();
                    int64_t bestIndex = y0 * W + x0;
                    for (int ky = 0; ky < d.kernel; ++ky) {
                        const int64_t iy = oy * d.stride - d.padding + ky;
                        if (iy < 0 || iy >= H) continue;
                        for (int kx = 0; kx < d.kernel; ++kx) {
                            const int64_t ix = ox * d.stride - d.padding + kx;
                            if (ix < 0 || ix >= W) continue;
                            const T value = input[iy * W + ix];
                            if (value > best || std::isnan(value)) {
                                best = value;
                                bestIndex = iy * W + ix;
                            }
                        }
                    }
                    o[oy * OW + ox] = best;
                    a[oy * OW + ox] = int32_t(bestIndex);
                }
        }
    });
}

template <class T>
void maxPool2dBackward(T* dinput, const T* dout, const int32_t* argmax, const MaxPool2dDesc& d) {
    d.validate();
    const int64_t outPlane = d.outHeight() * d.outWidth(), inPlane = d.inHeight * d.inWidth;
    parallelFor(0, d.batch * d.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            T* di = dinput + plane * inPlane;
            const T* g = dout + plane * outPlane;
            const int32_t* a = argmax + plane * outPlane;
            for (int64_t i = 0; i < outPlane; ++i) di[a[i]] += g[i];
        }
    });
}

template void maxPool2dForward<float>(float*, int32_t*, const float*, const MaxPool2dDesc&);
template void maxPool2dForward<double>(double*, int32_t*, const double*, const MaxPool2dDesc&);
template void maxPool2dBackward<float>(float*, const float*, const int32_t*, const MaxPool2dDesc&);
template void maxPool2dBackward<double>(double*, const double*, const int32_t*, const MaxPool2dDesc&);

}  // namespace dejag::nn

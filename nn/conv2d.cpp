// Conv2D forward and backward: the reference kernels (see nn/layers.h for the conventions).
#include <algorithm>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/layers.h"

namespace dejag::nn {

int64_t Conv2dDesc::outHeight() const {
    return (inHeight + padTop + padBottom - int64_t(dilationH) * (kernelHeight - 1) - 1) / strideH + 1;
}

int64_t Conv2dDesc::outWidth() const {
    return (inWidth + padLeft + padRight - int64_t(dilationW) * (kernelWidth - 1) - 1) / strideW + 1;
}

void Conv2dDesc::validate() const {
    auto require = [](bool ok, const std::string& what) {
        if (!ok) throw Error("Conv2D: " + what);
    };
    require(batch >= 1 && inChannels >= 1 && outChannels >= 1, "batch and channel counts must be >= 1");
    require(inHeight >= 1 && inWidth >= 1, "input size must be >= 1");
    require(kernelHeight >= 1 && kernelWidth >= 1, "kernel size must be >= 1");
    require(strideH >= 1 && strideW >= 1 && dilationH >= 1 && dilationW >= 1,
            "stride and dilation must be >= 1");
    require(padTop >= 0 && padBottom >= 0 && padLeft >= 0 && padRight >= 0, "padding must be >= 0");
    require(inHeight + padTop + padBottom >= int64_t(dilationH) * (kernelHeight - 1) + 1 &&
                inWidth + padLeft + padRight >= int64_t(dilationW) * (kernelWidth - 1) + 1,
            "the kernel (" + std::to_string(kernelHeight) + "x" + std::to_string(kernelWidth) +
                ") does not fit the padded input (" + std::to_string(inHeight) + "x" +
                std::to_string(inWidth) + ")");
}

void Conv2dDesc::setSamePadding() {
    auto same = [](int64_t in, int64_t k, int stride, int dilation, int& before, int& after) {
        const int64_t out = (in + stride - 1) / stride;
        const int64_t total = std::max<int64_t>(0, (out - 1) * stride + int64_t(dilation) * (k - 1) + 1 - in);
        before = int(total / 2);
        after = int(total - total / 2);
    };
    same(inHeight, kernelHeight, strideH, dilationH, padTop, padBottom);
    same(inWidth, kernelWidth, strideW, dilationW, padLeft, padRight);
}

namespace {

// Output columns ox whose input column ox * stride - pad + offset lies in [0, width): [first, last).
inline void validRange(int64_t outSize, int64_t inSize, int stride, int64_t shift, int64_t& first,
                       int64_t& last) {
    // ix = ox * stride + shift must satisfy 0 <= ix < inSize.
    first = shift >= 0 ? 0 : (-shift + stride - 1) / stride;
    last = inSize - shift <= 0 ? 0 : std::min(outSize, (inSize - shift - 1) / stride + 1);
    if (last < first) last = first;
}

}  // namespace

template <class T>
void conv2dForward(T* out, const T* in, const T* weight, const T* bias, const Conv2dDesc& d) {
    d.validate();
    const int64_t OH = d.outHeight(), OW = d.outWidth(), H = d.inHeight, W = d.inWidth;
    const int64_t KH = d.kernelHeight, KW = d.kernelWidth, Cin = d.inChannels, Cout = d.outChannels;
    parallelFor(0, d.batch * Cout, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const int64_t n = plane / Cout, co = plane % Cout;
            T* o = out + plane * OH * OW;
            const T initial = bias ? bias[co] : T(0);
            std::fill(o, o + OH * OW, initial);
            for (int64_t ci = 0; ci < Cin; ++ci) {
                const T* input = in + (n * Cin + ci) * H * W;
                const T* w = weight + (co * Cin + ci) * KH * KW;
                for (int64_t ky = 0; ky < KH; ++ky) {
                    int64_t oyFirst, oyLast;
                    validRange(OH, H, d.strideH, ky * d.dilationH - d.padTop, oyFirst, oyLast);
                    for (int64_t kx = 0; kx < KW; ++kx) {
                        const T wk = w[ky * KW + kx];
                        const int64_t shiftX = kx * d.dilationW - d.padLeft;
                        int64_t oxFirst, oxLast;
                        validRange(OW, W, d.strideW, shiftX, oxFirst, oxLast);
                        for (int64_t oy = oyFirst; oy < oyLast; ++oy) {
                            const T* row =
                                input + (oy * d.strideH + ky * d.dilationH - d.padTop) * W + shiftX;
                            T* orow = o + oy * OW;
                            for (int64_t ox = oxFirst; ox < oxLast; ++ox)
                                orow[ox] += wk * row[ox * d.strideW];
                        }
                    }
                }
            }
        }
    });
}

template <class T>
void conv2dBackward(T* dinput, T* dweight, T* dbias, const T* dout, const T* in, const T* weight,
                    const Conv2dDesc& d) {
    d.validate();
    const int64_t OH = d.outHeight(), OW = d.outWidth(), H = d.inHeight, W = d.inWidth;
    const int64_t KH = d.kernelHeight, KW = d.kernelWidth, Cin = d.inChannels, Cout = d.outChannels;
    // dweight and dbias: one output channel per work item.
    if (dweight || dbias) {
        parallelFor(0, Cout, 1, [&](int64_t first, int64_t last) {
            for (int64_t co = first; co < last; ++co) {
                for (int64_t n = 0; n < d.batch; ++n) {
                    const T* g = dout + (n * Cout + co) * OH * OW;
                    if (dbias) {
                        T sum = 0;
                        for (int64_t i = 0; i < OH * OW; ++i) sum += g[i];
                        dbias[co] += sum;
                    }
                    if (!dweight) continue;
                    for (int64_t ci = 0; ci < Cin; ++ci) {
                        const T* input = in + (n * Cin + ci) * H * W;
                        T* dw = dweight + (co * Cin + ci) * KH * KW;
                        for (int64_t ky = 0; ky < KH; ++ky) {
                            int64_t oyFirst, oyLast;
                            validRange(OH, H, d.strideH, ky * d.dilationH - d.padTop, oyFirst, oyLast);
                            for (int64_t kx = 0; kx < KW; ++kx) {
                                const int64_t shiftX = kx * d.dilationW - d.padLeft;
                                int64_t oxFirst, oxLast;
                                validRange(OW, W, d.strideW, shiftX, oxFirst, oxLast);
                                T sum = 0;
                                for (int64_t oy = oyFirst; oy < oyLast; ++oy) {
                                    const T* row =
                                        input + (oy * d.strideH + ky * d.dilationH - d.padTop) * W + shiftX;
                                    const T* grow = g + oy * OW;
                                    for (int64_t ox = oxFirst; ox < oxLast; ++ox)
                                        sum += grow[ox] * row[ox * d.strideW];
                                }
                                dw[ky * KW + kx] += sum;
                            }
                        }
                    }
                }
            }
        });
    }
    // dinput: one input plane per work item, scattering the forward's gathers.
    if (dinput) {
        parallelFor(0, d.batch * Cin, 1, [&](int64_t first, int64_t last) {
            for (int64_t plane = first; plane < last; ++plane) {
                const int64_t n = plane / Cin, ci = plane % Cin;
                T* di = dinput + plane * H * W;
                for (int64_t co = 0; co < Cout; ++co) {
                    const T* g = dout + (n * Cout + co) * OH * OW;
                    const T* w = weight + (co * Cin + ci) * KH * KW;
                    for (int64_t ky = 0; ky < KH; ++ky) {
                        int64_t oyFirst, oyLast;
                        validRange(OH, H, d.strideH, ky * d.dilationH - d.padTop, oyFirst, oyLast);
                        for (int64_t kx = 0; kx < KW; ++kx) {
                            const T wk = w[ky * KW + kx];
                            const int64_t shiftX = kx * d.dilationW - d.padLeft;
                            int64_t oxFirst, oxLast;
                            validRange(OW, W, d.strideW, shiftX, oxFirst, oxLast);
                            for (int64_t oy = oyFirst; oy < oyLast; ++oy) {
                                T* row = di + (oy * d.strideH + ky * d.dilationH - d.padTop) * W + shiftX;
                                const T* grow = g + oy * OW;
                                for (int64_t ox = oxFirst; ox < oxLast; ++ox)
                                    row[ox * d.strideW] += wk * grow[ox];
                            }
                        }
                    }
                }
            }
        });
    }
}

template void conv2dForward<float>(float*, const float*, const float*, const float*, const Conv2dDesc&);
template void conv2dForward<double>(double*, const double*, const double*, const double*, const Conv2dDesc&);
template void conv2dBackward<float>(float*, float*, float*, const float*, const float*, const float*,
                                    const Conv2dDesc&);
template void conv2dBackward<double>(double*, double*, double*, const double*, const double*, const double*,
                                     const Conv2dDesc&);

}  // namespace dejag::nn

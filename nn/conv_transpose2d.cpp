// ConvTranspose2D forward and backward (PyTorch semantics): the reference kernels. The forward is the
// conv2d input-gradient: every input pixel scatters its kernel-weighted value into the output.
#include <algorithm>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/layers.h"

namespace dejag::nn {

int64_t ConvTranspose2dDesc::outHeight() const {
    return (inHeight - 1) * strideH - 2 * int64_t(padH) + int64_t(dilationH) * (kernelHeight - 1) +
           outputPaddingH + 1;
}

int64_t ConvTranspose2dDesc::outWidth() const {
    return (inWidth - 1) * strideW - 2 * int64_t(padW) + int64_t(dilationW) * (kernelWidth - 1) +
           outputPaddingW + 1;
}

void ConvTranspose2dDesc::validate() const {
    auto require = [](bool ok, const std::string& what) {
        if (!ok) throw Error("ConvTranspose2D: " + what);
    };
    require(batch >= 1 && inChannels >= 1 && outChannels >= 1, "batch and channel counts must be >= 1");
    require(inHeight >= 1 && inWidth >= 1, "input size must be >= 1");
    require(kernelHeight >= 1 && kernelWidth >= 1, "kernel size must be >= 1");
    require(strideH >= 1 && strideW >= 1 && dilationH >= 1 && dilationW >= 1,
            "stride and dilation must be >= 1");
    require(padH >= 0 && padW >= 0, "padding must be >= 0");
    require(outputPaddingH >= 0 && outputPaddingW >= 0 &&
                (outputPaddingH < strideH || outputPaddingH < dilationH) &&
                (outputPaddingW < strideW || outputPaddingW < dilationW),
            "output padding must be smaller than the stride or the dilation");
    require(outHeight() >= 1 && outWidth() >= 1, "the output would be empty");
}

namespace {

// Input indices i whose output index i * stride + shift lies in [0, outSize): [first, last).
inline void scatterRange(int64_t inSize, int64_t outSize, int stride, int64_t shift, int64_t& first,
                         int64_t& last) {
    first = shift >= 0 ? 0 : (-shift + stride - 1) / stride;
    last = outSize - shift <= 0 ? 0 : std::min(inSize, (outSize - shift - 1) / stride + 1);
    if (last < first) last = first;
}

}  // namespace

template <class T>
void convTranspose2dForward(T* out, const T* in, const T* weight, const T* bias,
                            const ConvTranspose2dDesc& d) {
    d.validate();
    const int64_t OH = d.outHeight(), OW = d.outWidth(), H = d.inHeight, W = d.inWidth;
    const int64_t KH = d.kernelHeight, KW = d.kernelWidth, Cin = d.inChannels, Cout = d.outChannels;
    parallelFor(0, d.batch * Cout, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const int64_t n = plane / Cout, co = plane % Cout;
            T* o = out + plane * OH * OW;
            std::fill(o, o + OH * OW, bias ? bias[co] : T(0));
            for (int64_t ci = 0; ci < Cin; ++ci) {
                const T* input = in + (n * Cin + ci) * H * W;
                const T* w = weight + (ci * Cout + co) * KH * KW;
                for (int64_t ky = 0; ky < KH; ++ky) {
                    const int64_t shiftY = ky * d.dilationH - d.padH;
                    int64_t iyFirst, iyLast;
                    scatterRange(H, OH, d.strideH, shiftY, iyFirst, iyLast);
                    for (int64_t kx = 0; kx < KW; ++kx) {
                        const T wk = w[ky * KW + kx];
                        const int64_t shiftX = kx * d.dilationW - d.padW;
                        int64_t ixFirst, ixLast;
                        scatterRange(W, OW, d.strideW, shiftX, ixFirst, ixLast);
                        for (int64_t iy = iyFirst; iy < iyLast; ++iy) {
                            const T* row = input + iy * W;
                            T* orow = o + (iy * d.strideH + shiftY) * OW + shiftX;
                            for (int64_t ix = ixFirst; ix < ixLast; ++ix)
                                orow[ix * d.strideW] += wk * row[ix];
                        }
                    }
                }
            }
        }
    });
}

template <class T>
void convTranspose2dBackward(T* dinput, T* dweight, T* dbias, const T* dout, const T* in, const T* weight,
                             const ConvTranspose2dDesc& d) {
    d.validate();
    const int64_t OH = d.outHeight(), OW = d.outWidth(), H = d.inHeight, W = d.inWidth;
    const int64_t KH = d.kernelHeight, KW = d.kernelWidth, Cin = d.inChannels, Cout = d.outChannels;
    if (dbias) {
        parallelFor(0, Cout, 1, [&](int64_t first, int64_t last) {
            for (int64_t co = first; co < last; ++co) {
                T sum = 0;
                for (int64_t n = 0; n < d.batch; ++n) {
                    const T* g = dout + (n * Cout + co) * OH * OW;
                    for (int64_t i = 0; i < OH * OW; ++i) sum += g[i];
                }
                dbias[co] += sum;
            }
        });
    }
    // dweight[ci, co] and dinput[n, ci]: one input channel per work item (both gather from dout).
    if (dweight || dinput) {
        parallelFor(0, Cin, 1, [&](int64_t first, int64_t last) {
            for (int64_t ci = first; ci < last; ++ci) {
                for (int64_t n = 0; n < d.batch; ++n) {
                    const T* input = in + (n * Cin + ci) * H * W;
                    T* di = dinput ? dinput + (n * Cin + ci) * H * W : nullptr;
                    for (int64_t co = 0; co < Cout; ++co) {
                        const T* g = dout + (n * Cout + co) * OH * OW;
                        const T* w = weight + (ci * Cout + co) * KH * KW;
                        T* dw = dweight ? dweight + (ci * Cout + co) * KH * KW : nullptr;
                        for (int64_t ky = 0; ky < KH; ++ky) {
                            const int64_t shiftY = ky * d.dilationH - d.padH;
                            int64_t iyFirst, iyLast;
                            scatterRange(H, OH, d.strideH, shiftY, iyFirst, iyLast);
                            for (int64_t kx = 0; kx < KW; ++kx) {
                                const int64_t shiftX = kx * d.dilationW - d.padW;
                                int64_t ixFirst, ixLast;
                                scatterRange(W, OW, d.strideW, shiftX, ixFirst, ixLast);
                                const T wk = w[ky * KW + kx];
                                T sum = 0;
                                for (int64_t iy = iyFirst; iy < iyLast; ++iy) {
                                    const T* grow = g + (iy * d.strideH + shiftY) * OW + shiftX;
                                    const T* row = input + iy * W;
                                    if (di) {
                                        T* drow = di + iy * W;
                                        for (int64_t ix = ixFirst; ix < ixLast; ++ix)
                                            drow[ix] += wk * grow[ix * d.strideW];
                                    }
                                    if (dw)
                                        for (int64_t ix = ixFirst; ix < ixLast; ++ix)
                                            sum += row[ix] * grow[ix * d.strideW];
                                }
                                if (dw) dw[ky * KW + kx] += sum;
                            }
                        }
                    }
                }
            }
        });
    }
}

template void convTranspose2dForward<float>(float*, const float*, const float*, const float*,
                                            const ConvTranspose2dDesc&);
template void convTranspose2dForward<double>(double*, const double*, const double*, const double*,
                                             const ConvTranspose2dDesc&);
template void convTranspose2dBackward<float>(float*, float*, float*, const float*, const float*, const float*,
                                             const ConvTranspose2dDesc&);
template void convTranspose2dBackward<double>(double*, double*, double*, const double*, const double*,
                                              const double*, const ConvTranspose2dDesc&);

}  // namespace dejag::nn

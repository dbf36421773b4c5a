// Upsampling (nearest, bilinear) and pixel shuffle, forward and backward (see nn/layers.h).
#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/thread_pool.h"
#include "nn/layers.h"

namespace dejag::nn {
namespace {

void validate(const ResampleDesc& d, const char* what) {
    if (d.batch < 1 || d.channels < 1 || d.inHeight < 1 || d.inWidth < 1 || d.factor < 1)
        throw Error(std::string(what) + ": sizes and factor must be >= 1");
}

// PyTorch's bilinear source coordinate (align_corners=False) along one axis.
struct Tap {
    int64_t i0, i1;
    double lambda;  // weight of i1
};

Tap bilinearTap(int64_t dst, int64_t inSize, int factor) {
    double src = (double(dst) + 0.5) / factor - 0.5;
    if (src < 0) src = 0;
    const int64_t i0 = std::min<int64_t>(int64_t(src), inSize - 1);
    const int64_t i1 = std::min<int64_t>(i0 + 1, inSize - 1);
    return {i0, i1, src - double(i0)};
}

}  // namespace

template <class T>
void upsampleNearestForward(T* out, const T* in, const ResampleDesc& d) {
    validate(d, "UpsampleNearest");
    const int64_t H = d.inHeight, W = d.inWidth, f = d.factor, OW = W * f;
    parallelFor(0, d.batch * d.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const T* input = in + plane * H * W;
            T* o = out + plane * H * W * f * f;
            for (int64_t oy = 0; oy < H * f; ++oy)
                for (int64_t ox = 0; ox < OW; ++ox) o[oy * OW + ox] = input[(oy / f) * W + ox / f];
        }
    });
}

template <class T>
void upsampleNearestBackward(T* dinput, const T* dout, const ResampleDesc& d) {
    validate(d, "UpsampleNearest");
    const int64_t H = d.inHeight, W = d.inWidth, f = d.factor, OW = W * f;
    parallelFor(0, d.batch * d.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            T* di = dinput + plane * H * W;
            const T* g = dout + plane * H * W * f * f;
            for (int64_t oy = 0; oy < H * f; ++oy)
                for (int64_t ox = 0; ox < OW; ++ox) di[(oy / f) * W + ox / f] += g[oy * OW + ox];
        }
    });
}

template <class T>
void upsampleBilinearForward(T* out, const T* in, const ResampleDesc& d) {
    validate(d, "UpsampleBilinear");
    const int64_t H = d.inHeight, W = d.inWidth, OH = H * d.factor, OW = W * d.factor;
    parallelFor(0, d.batch * d.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const T* input = in + plane * H * W;
            T* o = out + plane * OH * OW;
            for (int64_t oy = 0; oy < OH; ++oy) {
                const Tap ty = bilinearTap(oy, H, d.factor);
                for (int64_t ox = 0; ox < OW; ++ox) {
                    const Tap tx = bilinearTap(ox, W, d.factor);
                    const T ly = T(ty.lambda), lx = T(tx.lambda);
                    o[oy * OW + ox] =
                        (T(1) - ly) *
                            ((T(1) - lx) * input[ty.i0 * W + tx.i0] + lx * input[ty.i0 * W + tx.i1]) +
                        ly * ((T(1) - lx) * input[ty.i1 * W + tx.i0] + lx * input[ty.i1 * W + tx.i1]);
                }
            }
        }
    });
}

template <class T>
void upsampleBilinearBackward(T* dinput, const T* dout, const ResampleDesc& d) {
    validate(d, "UpsampleBilinear");
    const int64_t H = d.inHeight, W = d.inWidth, OH = H * d.factor, OW = W * d.factor;
    parallelFor(0, d.batch * d.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            T* di = dinput + plane * H * W;
            const T* g = dout + plane * OH * OW;
            for (int64_t oy = 0; oy < OH; ++oy) {
                const Tap ty = bilinearTap(oy, H, d.factor);
                for (int64_t ox = 0; ox < OW; ++ox) {
                    const Tap tx = bilinearTap(ox, W, d.factor);
                    const T ly = T(ty.lambda), lx = T(tx.lambda), v = g[oy * OW + ox];
                    di[ty.i0 * W + tx.i0] += (T(1) - ly) * (T(1) - lx) * v;
                    di[ty.i0 * W + tx.i1] += (T(1) - ly) * lx * v;
                    di[ty.i1 * W + tx.i0] += ly * (T(1) - lx) * v;
                    di[ty.i1 * W + tx.i1] += ly * lx * v;
                }
            }
        }
    });
}

template <class T>
void pixelShuffleForward(T* out, const T* in, const ResampleDesc& d) {
    validate(d, "PixelShuffle");
    const int64_t f = d.factor, C = d.channels / (f * f), H = d.inHeight, W = d.inWidth;
    if (C * f * f != d.channels) throw Error("PixelShuffle: channels must be a multiple of factor^2");
    parallelFor(0, d.batch * C, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const int64_t n = plane / C, c = plane % C;
            T* o = out + plane * H * W * f * f;
            for (int64_t i = 0; i < f; ++i)
                for (int64_t j = 0; j < f; ++j) {
                    const T* input = in + ((n * C + c) * f * f + i * f + j) * H * W;
                    for (int64_t y = 0; y < H; ++y)
                        for (int64_t x = 0; x < W; ++x) o[(y * f + i) * W * f + x * f + j] = input[y * W + x];
                }
        }
    });
}

template <class T>
void pixelShuffleBackward(T* dinput, const T* dout, const ResampleDesc& d) {
    validate(d, "PixelShuffle");
    const int64_t f = d.factor, C = d.channels / (f * f), H = d.inHeight, W = d.inWidth;
    if (C * f * f != d.channels) throw Error("PixelShuffle: channels must be a multiple of factor^2");
    parallelFor(0, d.batch * C, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const int64_t n = plane / C, c = plane % C;
            const T* g = dout + plane * H * W * f * f;
            for (int64_t i = 0; i < f; ++i)
                for (int64_t j = 0; j < f; ++j) {
                    T* di = dinput + ((n * C + c) * f * f + i * f + j) * H * W;
                    for (int64_t y = 0; y < H; ++y)
                        for (int64_t x = 0; x < W; ++x) di[y * W + x] += g[(y * f + i) * W * f + x * f + j];
                }
        }
    });
}

#define DEJAG_INSTANTIATE(T)                                                      \
    template void upsampleNearestForward<T>(T*, const T*, const ResampleDesc&);   \
    template void upsampleNearestBackward<T>(T*, const T*, const ResampleDesc&);  \
    template void upsampleBilinearForward<T>(T*, const T*, const ResampleDesc&);  \
    template void upsampleBilinearBackward<T>(T*, const T*, const ResampleDesc&); \
    template void pixelShuffleForward<T>(T*, const T*, const ResampleDesc&);      \
    template void pixelShuffleBackward<T>(T*, const T*, const ResampleDesc&);
DEJAG_INSTANTIATE(float)
DEJAG_INSTANTIATE(double)
#undef DEJAG_INSTANTIATE

}  // namespace dejag::nn

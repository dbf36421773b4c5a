// The motion warp, forward and backward (see nn/layers.h).
#include <algorithm>
#include <cmath>
#include <cstring>
#include <string>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/blocked.h"
#include "nn/layers.h"
#include "nn/warp_kernels.h"

namespace dejag::nn {
namespace {

// The cubic convolution kernel of parameter a at distance t >= 0, and its derivative in t.
template <class T>
T cubicNear(T t, T a) {  // |t| <= 1
    return ((a + 2) * t - (a + 3)) * t * t + 1;
}
template <class T>
T cubicFar(T t, T a) {  // 1 < |t| < 2
    return ((a * t - 5 * a) * t + 8 * a) * t - 4 * a;
}
template <class T>
T cubicNearSlope(T t, T a) {
    return (3 * (a + 2) * t - 2 * (a + 3)) * t;
}
template <class T>
T cubicFarSlope(T t, T a) {
    return (3 * a * t - 10 * a) * t + 8 * a;
}

// The taps of a read at index coordinate s along one axis: the first tap's index, each tap's weight and
// the weight's derivative in s.
template <class T>
struct Taps {
    int64_t first = 0;
    T w[4] = {}, dw[4] = {};
};
template <class T>
Taps<T> taps(T s, WarpFilter filter) {
    Taps<T> t;
    const T base = std::floor(s), f = s - base;
    if (filter == WarpFilter::Bilinear) {
        t.first = int64_t(base);
        t.w[0] = 1 - f, t.w[1] = f;
        t.dw[0] = -1, t.dw[1] = 1;
        return t;
    }
    const T a = filter == WarpFilter::CatmullRom ? T(-0.5) : T(-0.75);
    t.first = int64_t(base) - 1;
    // Distances 1 + f, f, 1 - f, 2 - f from the taps first .. first + 3.
    t.w[0] = cubicFar(1 + f, a), t.dw[0] = cubicFarSlope(1 + f, a);
    t.w[1] = cubicNear(f, a), t.dw[1] = cubicNearSlope(f, a);
    t.w[2] = cubicNear(1 - f, a), t.dw[2] = -cubicNearSlope(1 - f, a);
    t.w[3] = cubicFar(2 - f, a), t.dw[3] = -cubicFarSlope(2 - f, a);
    return t;
}

// Where pixel (y, x) of item n reads, in index coordinates; a non-finite or huge motion reads the border
// (the clamp keeps the tap indices in range; its gradient there is 0).
template <class T>
void clampPlace(T& sx, T& sy, int64_t width, int64_t height) {
    const T limitX = T(width + 2), limitY = T(height + 2);
    sx = std::isnan(sx) ? T(0) : std::clamp(sx, -limitX, 2 * limitX);
    sy = std::isnan(sy) ? T(0) : std::clamp(sy, -limitY, 2 * limitY);
}
template <class T>
void readPlace(const T* motion, const WarpDesc& d, int64_t n, int64_t y, int64_t x, T& sx, T& sy) {
    const int64_t plane = d.height * d.width, at = y * d.width + x;
    sx = T(x) - motion[(n * 2) * plane + at];
    sy = T(y) - motion[(n * 2 + 1) * plane + at];
    clampPlace(sx, sy, d.width, d.height);
}

void check(const WarpDesc& d) {
    if (d.batch < 1 || d.channels < 1 || d.height < 1 || d.width < 1) throw Error("warp: empty shape");
}

}  // namespace

WarpFilter parseWarpFilter(const std::string& name) {
    if (name == "bilinear") return WarpFilter::Bilinear;
    if (name == "catmull-rom") return WarpFilter::CatmullRom;
    if (name == "bicubic") return WarpFilter::Bicubic;
    throw Error("unknown warp filter '" + name + "' (bilinear, catmull-rom, bicubic)");
}

const char* warpFilterName(WarpFilter filter) {
    switch (filter) {
        case WarpFilter::Bilinear:
            return "bilinear";
        case WarpFilter::CatmullRom:
            return "catmull-rom";
        case WarpFilter::Bicubic:
            return "bicubic";
    }
    return "?";
}

template <class T>
void warpForward(T* out, const T* image, const T* motion, const WarpDesc& d) {
    check(d);
    const int64_t plane = d.height * d.width;
    const int k = d.taps();
    parallelFor(0, d.batch * d.height, 1, [&](int64_t first, int64_t last) {
        for (int64_t row = first; row < last; ++row) {
            const int64_t n = row / d.height, y = row % d.height;
            for (int64_t x = 0; x < d.width; ++x) {
                T sx, sy;
                readPlace(motion, d, n, y, x, sx, sy);
                const Taps<T> tx = taps(sx, d.filter), ty = taps(sy, d.filter);
                int64_t offset[4][4];
                for (int j = 0; j < k; ++j)
                    for (int i = 0; i < k; ++i)
                        offset[j][i] = std::clamp<int64_t>(ty.first + j, 0, d.height - 1) * d.width +
                                       std::clamp<int64_t>(tx.first + i, 0, d.width - 1);
                for (int64_t c = 0; c < d.channels; ++c) {
                    const T* src = image + (n * d.channels + c) * plane;
                    T sum = 0;
                    for (int j = 0; j < k; ++j) {
                        T rowSum = 0;
                        for (int i = 0; i < k; ++i) rowSum += tx.w[i] * src[offset[j][i]];
                        sum += ty.w[j] * rowSum;
                    }
                    out[(n * d.channels + c) * plane + y * d.width + x] = sum;
                }
            }
        }
    });
}

template <class T>
void warpBackward(T* dimage, T* dmotion, const T* dout, const T* image, const T* motion, const WarpDesc& d) {
    check(d);
    const int64_t plane = d.height * d.width;
    const int k = d.taps();
    // The image's gradient: a scatter, so each thread owns whole planes (no two write one value, and the
    // sums come in one order whatever the thread count).
    if (dimage)
        parallelFor(0, d.batch * d.channels, 1, [&](int64_t first, int64_t last) {
            for (int64_t nc = first; nc < last; ++nc) {
                const int64_t n = nc / d.channels;
                T* grad = dimage + nc * plane;
                const T* g = dout + nc * plane;
                for (int64_t y = 0; y < d.height; ++y)
                    for (int64_t x = 0; x < d.width; ++x) {
                        T sx, sy;
                        readPlace(motion, d, n, y, x, sx, sy);
                        const Taps<T> tx = taps(sx, d.filter), ty = taps(sy, d.filter);
                        const T go = g[y * d.width + x];
                        for (int j = 0; j < k; ++j) {
                            const int64_t r = std::clamp<int64_t>(ty.first + j, 0, d.height - 1) * d.width;
                            for (int i = 0; i < k; ++i)
                                grad[r + std::clamp<int64_t>(tx.first + i, 0, d.width - 1)] +=
                                    ty.w[j] * tx.w[i] * go;
                        }
                    }
            }
        });
    // The motion's: the read place moves against the motion (s = x - motion).
    if (dmotion)
        parallelFor(0, d.batch * d.height, 1, [&](int64_t first, int64_t last) {
            for (int64_t row = first; row < last; ++row) {
                const int64_t n = row / d.height, y = row % d.height;
                for (int64_t x = 0; x < d.width; ++x) {
                    T sx, sy;
                    readPlace(motion, d, n, y, x, sx, sy);
                    const int64_t at = y * d.width + x;
                    const T rawX = T(x) - motion[(n * 2) * plane + at],
                            rawY = T(y) - motion[(n * 2 + 1) * plane + at];
                    const Taps<T> tx = taps(sx, d.filter), ty = taps(sy, d.filter);
                    T gx = 0, gy = 0;
                    for (int64_t c = 0; c < d.channels; ++c) {
                        const T* src = image + (n * d.channels + c) * plane;
                        const T go = dout[(n * d.channels + c) * plane + at];
                        for (int j = 0; j < k; ++j) {
                            const int64_t r = std::clamp<int64_t>(ty.first + j, 0, d.height - 1) * d.width;
                            for (int i = 0; i < k; ++i) {
                                const T v = src[r + std::clamp<int64_t>(tx.first + i, 0, d.width - 1)] * go;
                                gx += ty.w[j] * tx.dw[i] * v, gy += ty.dw[j] * tx.w[i] * v;
                            }
                        }
                    }
                    // (Where the place was clamped, it does not move with the motion.)
                    dmotion[(n * 2) * plane + at] += rawX == sx ? -gx : T(0);
                    dmotion[(n * 2 + 1) * plane + at] += rawY == sy ? -gy : T(0);
                }
            }
        });
}

void blockedSlice(float* out, const BlockedShape& os, const float* in, const BlockedShape& is, int from) {
    parallelFor(0, os.batch * os.height, 8, [&](int64_t first, int64_t last) {
        for (int64_t row = first; row < last; ++row) {
            const int64_t n = row / os.height, y = row % os.height;
            for (int64_t c = 0; c < os.channels; ++c) {
                const int64_t source = c + from;
                float* o = out + os.offset(n, c / os.block, y, 0) + c % os.block;
                const float* i = in + is.offset(n, source / is.block, y, 0) + source % is.block;
                for (int64_t x = 0; x < os.width; ++x) o[x * os.block] = i[x * is.block];
            }
            // The lanes past the channel count are zero in every blocked activation (the arena is reused).
            for (int64_t c = os.channels; c < os.channelBlocks() * os.block; ++c) {
                float* o = out + os.offset(n, c / os.block, y, 0) + c % os.block;
                for (int64_t x = 0; x < os.width; ++x) o[x * os.block] = 0.0f;
            }
        }
    });
}

void blockedWarp(float* out, const BlockedShape& os, const float* image, const BlockedShape& is,
                 const float* motion, const BlockedShape& ms, WarpFilter filter) {
    WarpDesc d;
    d.batch = os.batch, d.channels = os.channels, d.height = os.height, d.width = os.width, d.filter = filter;
    const int k = d.taps();
    const int64_t blocks = os.channelBlocks();
    const bool sameBlock = os.block == is.block;
    parallelFor(0, d.batch * d.height, 4, [&](int64_t first, int64_t last) {
        for (int64_t row = first; row < last; ++row) {
            const int64_t n = row / d.height, y = row % d.height;
            const float* mxRow = motion + ms.offset(n, 0, y, 0);
            const float* myRow = motion + ms.offset(n, 1 / ms.block, y, 0) + 1 % ms.block;
            for (int64_t x = 0; x < d.width; ++x) {
                float sx = float(x) - mxRow[x * ms.block], sy = float(y) - myRow[x * ms.block];
                clampPlace(sx, sy, d.width, d.height);
                const Taps<float> tx = taps(sx, filter), ty = taps(sy, filter);
                int64_t column[4], line[4];
                for (int i = 0; i < k; ++i) column[i] = std::clamp<int64_t>(tx.first + i, 0, d.width - 1);
                for (int j = 0; j < k; ++j) line[j] = std::clamp<int64_t>(ty.first + j, 0, d.height - 1);
                if (sameBlock) {
                    // One channel block at a time: each tap is one vector of the block's channels.
                    constexpr int kMaxBlock = 64;
                    const int B = os.block;
                    for (int64_t cb = 0; cb < blocks; ++cb) {
                        float sum[kMaxBlock] = {};
                        for (int j = 0; j < k; ++j) {
                            float rowSum[kMaxBlock] = {};
                            for (int i = 0; i < k; ++i) {
                                const float* p = image + is.offset(n, cb, line[j], column[i]);
                                const float w = tx.w[i];
                                for (int l = 0; l < B; ++l) rowSum[l] += w * p[l];
                            }
                            for (int l = 0; l < B; ++l) sum[l] += ty.w[j] * rowSum[l];
                        }
                        float* o = out + os.offset(n, cb, y, x);
                        for (int l = 0; l < B; ++l) o[l] = sum[l];
                    }
                } else {
                    for (int64_t c = 0; c < d.channels; ++c) {
                        float sum = 0;
                        for (int j = 0; j < k; ++j) {
                            float rowSum = 0;
                            for (int i = 0; i < k; ++i)
                                rowSum +=
                                    tx.w[i] *
                                    image[is.offset(n, c / is.block, line[j], column[i]) + c % is.block];
                            sum += ty.w[j] * rowSum;
                        }
                        out[os.offset(n, c / os.block, y, x) + c % os.block] = sum;
                    }
                    for (int64_t c = d.channels; c < blocks * os.block; ++c)
                        out[os.offset(n, c / os.block, y, x) + c % os.block] = 0.0f;
                }
            }
        }
    });
}

void warpInterleaved(float* const* out, const float* image, const float* motion, int64_t width,
                     int64_t height, int channels, WarpFilter filter) {
    if (channels < 1 || channels > 4 || width < 1 || height < 1)
        throw Error("warp: 1..4 interleaved channels");
    WarpRowsArgs args;
    args.out = out, args.image = image, args.motion = motion, args.width = width, args.height = height;
    args.channels = channels, args.taps = filter == WarpFilter::Bilinear ? 2 : 4;
    args.a = filter == WarpFilter::CatmullRom ? -0.5f : -0.75f;
    parallelFor(0, height, 4, [&](int64_t first, int64_t last) {
        WarpRowsArgs band = args;
        band.firstRow = first, band.lastRow = last;
        DEJAG_SIMD_CALL(warpInterleavedRows, band);
    });
}

void warpPlane(float* out, const float* image, const float* motion, int64_t width, int64_t height,
               WarpFilter filter) {
    if (width < 1 || height < 1) throw Error("warp: an empty plane");
    float* planes[1] = {out};
    WarpRowsArgs args;
    args.out = planes, args.image = image, args.motion = motion, args.width = width, args.height = height;
    args.channels = 1, args.planar = true, args.taps = filter == WarpFilter::Bilinear ? 2 : 4;
    args.a = filter == WarpFilter::CatmullRom ? -0.5f : -0.75f;
    parallelFor(0, height, 4, [&](int64_t first, int64_t last) {
        WarpRowsArgs band = args;
        band.firstRow = first, band.lastRow = last;
        DEJAG_SIMD_CALL(warpInterleavedRows, band);
    });
}

#define DEJAG_WARP(T)                                                      \
    template void warpForward<T>(T*, const T*, const T*, const WarpDesc&); \
    template void warpBackward<T>(T*, T*, const T*, const T*, const T*, const WarpDesc&);
DEJAG_WARP(float)
DEJAG_WARP(double)
#undef DEJAG_WARP

}  // namespace dejag::nn

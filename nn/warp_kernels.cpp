#include "nn/warp_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>

#if defined(DEJAG_SIMD_LEVEL_avx512) || defined(DEJAG_SIMD_LEVEL_avx2)
#include <immintrin.h>
#endif

namespace dejag::nn::DEJAG_SIMD_NAMESPACE {
namespace {

typedef float V4 __attribute__((vector_size(16)));
typedef float V8 __attribute__((vector_size(32)));
typedef float V16 __attribute__((vector_size(64)));

typedef int32_t I16 __attribute__((vector_size(64)));
constexpr int kChunk = 16;  // pixels whose places and weights are computed together

// The places and weights of kChunk pixels along one axis from their index coordinates s: the first tap's
// index and K weights (nn/warp.cpp's cubic convolution kernel of parameter a, or the linear one). A
// non-finite or huge s reads the border, as nn/warp.cpp's clampPlace.
template <int K>
[[gnu::always_inline]] inline void axis(const V16& place, float limit, float a, I16& first, V16 w[4]) {
    V16 s = place == place ? place : V16{};  // NaN: 0
    s = s < -limit ? -limit : s;
    s = s > 2 * limit ? 2 * limit : s;
    I16 base = __builtin_convertvector(s, I16);
    base -= (__builtin_convertvector(base, V16) > s) ? 1 : 0;  // floor
    const V16 f = s - __builtin_convertvector(base, V16);
    if constexpr (K == 2) {
        first = base, w[0] = 1 - f, w[1] = f;
    } else {
        const V16 t0 = 1 + f, t1 = f, t2 = 1 - f, t3 = 2 - f;  // the taps' distances
        first = base - 1;
        w[0] = ((a * t0 - 5 * a) * t0 + 8 * a) * t0 - 4 * a;
        w[1] = ((a + 2) * t1 - (a + 3)) * t1 * t1 + 1;
        w[2] = ((a + 2) * t2 - (a + 3)) * t2 * t2 + 1;
        w[3] = ((a * t3 - 5 * a) * t3 + 8 * a) * t3 - 4 * a;
    }
}

#if defined(DEJAG_SIMD_LEVEL_avx512) || defined(DEJAG_SIMD_LEVEL_avx2)
// image[index[l]] for the 16 lanes: one gather (AVX-512) or two (AVX2).
// (Results through a reference: a 64-byte vector returned by value changes the ABI below AVX-512.)
[[gnu::always_inline]] inline void gather16(const float* image, const I16& index, V16& out) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    out = V16(_mm512_mask_i32gather_ps(_mm512_setzero_ps(), 0xffff, __m512i(index), image, 4));
#else
    typedef int32_t I8 __attribute__((vector_size(32)));
    const I8 low = __builtin_shufflevector(index, index, 0, 1, 2, 3, 4, 5, 6, 7),
             high = __builtin_shufflevector(index, index, 8, 9, 10, 11, 12, 13, 14, 15);
    const V8 a = V8(_mm256_i32gather_ps(image, __m256i(low), 4)),
             b = V8(_mm256_i32gather_ps(image, __m256i(high), 4));
    out = __builtin_shufflevector(a, b, 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15);
#endif
}

// A plane's kChunk pixels whose first taps are (firstX, firstY): every tap's place clamped to the image
// (edges repeated, as the per-pixel path) and gathered, the same sums in the same order.
template <int K>
[[gnu::always_inline]] inline void planarChunk(const WarpRowsArgs& args, const I16& firstX, const I16& firstY,
                                               const V16 (&wxs)[4], const V16 (&wys)[4], V16& sum) {
    const int32_t lastX = int32_t(args.width - 1), lastY = int32_t(args.height - 1);
    I16 column[K];
    for (int i = 0; i < K; ++i) {
        I16 c = firstX + i;
        c = c < 0 ? 0 : c;
        column[i] = c > lastX ? lastX : c;
    }
    sum = V16{};
    for (int j = 0; j < K; ++j) {
        I16 row = firstY + j;
        row = row < 0 ? 0 : row;
        row = (row > lastY ? lastY : row) * int32_t(args.width);
        V16 rowSum = {};
        for (int i = 0; i < K; ++i) {
            V16 tap;
            gather16(args.image, row + column[i], tap);
            rowSum += wxs[i] * tap;
        }
        sum += wys[j] * rowSum;
    }
}
#endif

template <int K, bool Planar>
void rows(const WarpRowsArgs& args) {
    const int64_t W = args.width, H = args.height;
    const float limitX = float(W + 2), limitY = float(H + 2);
    const V16 lane = {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15};
    for (int64_t y = args.firstRow; y < args.lastRow; ++y) {
        const float* motion = args.motion + y * W * 2;
        for (int64_t x0 = 0; x0 < W; x0 += kChunk) {
            const int n = int(std::min<int64_t>(kChunk, W - x0));
            float pairs[2 * kChunk] = {};
            std::memcpy(pairs, motion + 2 * x0, sizeof(float) * 2 * size_t(n));
            V16 even, odd;
            std::memcpy(&even, pairs, sizeof(even)), std::memcpy(&odd, pairs + kChunk, sizeof(odd));
            const I16 evens = {0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30};
            const V16 mx = __builtin_shuffle(even, odd, evens), my = __builtin_shuffle(even, odd, evens + 1);
            I16 firstX, firstY;
            V16 wxs[4], wys[4];
            const V16 sx = float(x0) + lane - mx, sy = float(y) - my;
            axis<K>(sx, limitX, args.a, firstX, wxs);
            axis<K>(sy, limitY, args.a, firstY, wys);
#if defined(DEJAG_SIMD_LEVEL_avx512) || defined(DEJAG_SIMD_LEVEL_avx2)
            // (32-bit indices: planes of fewer than 2^31 pixels.)
            if (Planar && n == kChunk && W * H < (int64_t(1) << 31)) {
                V16 sum;
                planarChunk<K>(args, firstX, firstY, wxs, wys, sum);
                std::memcpy(args.out[0] + y * W + x0, &sum, sizeof(sum));
                continue;
            }
#endif
            for (int l = 0; l < n; ++l) {
                const int64_t tx = firstX[l], ty = firstY[l];
                if constexpr (Planar) {  // one plane: K x K scalar taps
                    const bool inside = tx >= 0 && tx + K <= W && ty >= 0 && ty + K <= H;
                    float sum = 0;
                    for (int j = 0; j < K; ++j) {
                        const float* row =
                            args.image + (inside ? ty + j : std::clamp<int64_t>(ty + j, 0, H - 1)) * W;
                        float rowSum = 0;
                        for (int i = 0; i < K; ++i)
                            rowSum +=
                                wxs[i][l] * row[inside ? tx + i : std::clamp<int64_t>(tx + i, 0, W - 1)];
                        sum += wys[j][l] * rowSum;
                    }
                    args.out[0][y * W + x0 + l] = sum;
                    continue;
                }
                V4 sum;
                if (tx >= 0 && tx + K <= W && ty >= 0 && ty + K <= H) {
                    // A tap row is K pixels of 4 floats in a row: one vector; the rows weighted, then the
                    // columns, then the K pixels' 4-float lanes summed.
                    const float* at = args.image + (ty * W + tx) * 4;
                    if constexpr (K == 4) {
                        V16 acc, row;
                        std::memcpy(&acc, at, sizeof(acc));
                        acc *= wys[0][l];
                        for (int j = 1; j < 4; ++j) {
                            std::memcpy(&row, at + j * W * 4, sizeof(row));
                            acc += wys[j][l] * row;
                        }
                        V4 part[4];
                        std::memcpy(part, &acc, sizeof(acc));
                        sum = wxs[0][l] * part[0] + wxs[1][l] * part[1] +
                              (wxs[2][l] * part[2] + wxs[3][l] * part[3]);
                    } else {
                        V8 acc, row;
                        std::memcpy(&acc, at, sizeof(acc));
                        acc *= wys[0][l];
                        std::memcpy(&row, at + W * 4, sizeof(row));
                        acc += wys[1][l] * row;
                        V4 part[2];
                        std::memcpy(part, &acc, sizeof(acc));
                        sum = wxs[0][l] * part[0] + wxs[1][l] * part[1];
                    }
                } else {
                    int64_t column[K];
                    for (int i = 0; i < K; ++i) column[i] = std::clamp<int64_t>(tx + i, 0, W - 1) * 4;
                    sum = V4{0, 0, 0, 0};
                    for (int j = 0; j < K; ++j) {
                        const float* row = args.image + std::clamp<int64_t>(ty + j, 0, H - 1) * W * 4;
                        V4 rowSum = {0, 0, 0, 0};
                        for (int i = 0; i < K; ++i) {
                            V4 tap;
                            std::memcpy(&tap, row + column[i], sizeof(tap));
                            rowSum += wxs[i][l] * tap;
                        }
                        sum += wys[j][l] * rowSum;
                    }
                }
                const int64_t p = y * W + x0 + l;
                for (int c = 0; c < args.channels; ++c) args.out[c][p] = sum[c];
            }
        }
    }
}

}  // namespace

void warpInterleavedRows(const WarpRowsArgs& args) {
    if (args.planar)
        args.taps == 2 ? rows<2, true>(args) : rows<4, true>(args);
    else
        args.taps == 2 ? rows<2, false>(args) : rows<4, false>(args);
}

}  // namespace dejag::nn::DEJAG_SIMD_NAMESPACE

// The kernel filter over one row (see nn/kernel_filter_kernels.h), compiled once per SIMD level: the
// pixels whose whole neighbourhood lies inside the row are done kFloatLanes at a time, the few at each
// end (edges repeated) one at a time with the same arithmetic.
#include "nn/kernel_filter_kernels.h"

#include <algorithm>
#include <cstring>
#include <type_traits>

#include "base/pixel_simd.h"
#include "base/srgb_simd.h"

namespace dejag::nn::DEJAG_SIMD_NAMESPACE {
using namespace ::dejag::DEJAG_SIMD_NAMESPACE;  // VFloat, kFloatLanes, loadu, storeu, splat
namespace {

#if defined(DEJAG_SIMD_LEVEL_scalar)
using VInt = int32_t;
#else
typedef int32_t VInt __attribute__((vector_size(kFloatLanes * sizeof(int32_t))));
#endif

template <class To, class From>
inline To bitCast(From v) {
    static_assert(sizeof(To) == sizeof(From));
    To to;
    std::memcpy(&to, &v, sizeof(To));
    return to;
}

// e^x for x <= 0 (the softmax's logits minus their maximum), relative error about 2e-7: x = n ln 2 + r
// with |r| <= ln 2 / 2, e^r by its degree-6 Taylor polynomial, 2^n put in the exponent bits. Below -87
// the result is e^-87 (1.6e-38) instead of a denormal or zero: a weight that small is zero to the sum.
template <class V, class I>
inline V expNonPositive(V x) {
    const V magic = splat<V>(12582912.0f);  // 1.5 * 2^23: adding it rounds to an integer
    x = x < -87.0f ? splat<V>(-87.0f) : x;
    const V shifted = x * 1.44269504f + magic;
    const V n = shifted - magic;
    const V r = x - n * 0.693145752f - n * 1.42860677e-6f;  // ln 2 in two parts
    V p = splat<V>(1.0f / 720.0f);
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    const I exponent = (bitCast<I>(shifted) - bitCast<I>(magic) + 127) << 23;
    return p * bitCast<V>(exponent);
}

// The sRGB curves on [0, 1] (clamped), as srgbDecode and srgbEncode of nn/layers.h, by exponent and
// mantissa (base/srgb_simd.h) at degree 7: within 2e-7 of the reference (rounding included).
const PowerCurve& decodeCurve() {
    return srgbDecodeCurve7();
}
const PowerCurve& encodeCurve() {
    return srgbEncodeCurve7();
}
template <class V, class I>
inline V decodeSrgb(V v) {
    return decodeSrgbBy<7>(decodeCurve(), v);
}
template <class V, class I>
inline V encodeSrgb(V x) {
    return encodeSrgbBy<7>(encodeCurve(), x);
}

// Interleaved stores of a pixel (V = float) or of a vector of pixels (base/pixel_simd.h).
inline void storeRgbOf(float* p, const float* v) {
    p[0] = v[0], p[1] = v[1], p[2] = v[2];
}
inline void storeQuadsOf(float* p, const float* v) {
    p[0] = v[0], p[1] = v[1], p[2] = v[2], p[3] = v[3];
}
#if !defined(DEJAG_SIMD_LEVEL_scalar)
inline void storeRgbOf(float* p, const VFloat* v) {
    storeRgb(p, v[0], v[1], v[2]);
}
inline void storeQuadsOf(float* p, const VFloat* v) {
    storeQuads(p, v);
}
#endif

// The pixels from x (as many as V has lanes), all of whose taps x + dx lie in [0, width) unless `clampX`;
// with `History`, one more weight on the history's pixel; with `Accumulate` (and History), accumulate's
// blend of the filtered pixels with the history's kept mean.
// kChannels: the channel count when known at compile time (0: a.channels), so that the per-channel
// vectors stay in registers.
template <class V, class I, int K, bool History = false, bool Accumulate = false, int kChannels = 0>
inline void filterPixels(const KernelFilterRowArgs& a, int64_t x, bool clampX) {
    const int channels = kChannels > 0 ? kChannels : a.channels;
    constexpr int kTaps = K * K, kRadius = K / 2, kCentre = kTaps / 2,
                  kWeights = kTaps + (History && !Accumulate ? 1 : 0);
    V weight[kWeights];
    V largest = splat<V>(-3.4e38f);
    for (int j = 0; j < kWeights; ++j) {
        weight[j] = loadu<V>(a.logits + j * a.width + x);
        if (j == kCentre) weight[j] = weight[j] + a.centreBias;
        largest = largest < weight[j] ? weight[j] : largest;
    }
    V sum = splat<V>(0.0f);
    for (int j = 0; j < kWeights; ++j) sum = sum + (weight[j] = expNonPositive<V, I>(weight[j] - largest));
    const V scale = 1.0f / sum;
    int64_t column[K];
    for (int dx = -kRadius; dx <= kRadius; ++dx)
        column[dx + kRadius] = clampX ? std::clamp<int64_t>(x + dx, 0, a.width - 1) : x + dx;
    if constexpr (Accumulate) {
        // a = m / (1 + m), m = rho n, n = s / (1 - s), rho = min(1, 2 sigmoid(trust)) = 1 from trust 0 up
        // and 2 e^t / (1 + e^t) below; s' = n' / (n' + 1), n' = min(1 + m, N).
        constexpr int kMaxChannels = 4;
        const float maxConfidence = a.maxCount / (a.maxCount + 1.0f);
        V s = loadu<V>(a.confidence + x);
        s = s < 0.0f ? splat<V>(0.0f) : s;
        s = s > maxConfidence ? splat<V>(maxConfidence) : s;
        V trust = loadu<V>(a.logits + kTaps * a.width + x);
        // Per colour: the filtered value, the taps' range decoded (for the clip and the gate) and the
        // history.
        V filtered[kMaxChannels], low[kMaxChannels], high[kMaxChannels], history[kMaxChannels];
        const bool ranges = a.clip || a.still;
        for (int c = 0; c < channels; ++c) {
            V value = splat<V>(0.0f), lo = splat<V>(3.4e38f), hi = splat<V>(-3.4e38f);
            for (int dy = 0; dy < K; ++dy) {
                const float* row = a.in[c * K + dy];
                for (int dx = 0; dx < K; ++dx) {
                    const V tap = loadu<V>(row + column[dx]);
                    value = value + weight[dy * K + dx] * tap;
                    if (ranges) lo = tap < lo ? tap : lo, hi = tap > hi ? tap : hi;
                }
            }
            filtered[c] = decodeSrgb<V, I>(value * scale), history[c] = loadu<V>(a.history[c] + x);
            if (ranges) low[c] = decodeSrgb<V, I>(lo), high[c] = decodeSrgb<V, I>(hi);
        }
        // The still gate: full trust and the history whole where nothing moves, the network trusts the
        // history enough and the history's colours lie within the taps' range (widened).
        V gated = splat<V>(0.0f);
        if (a.still) {
            V keep = loadu<V>(a.still + x) > 0.5f && trust >= a.stillLogit ? splat<V>(1.0f) : splat<V>(0.0f);
            for (int c = 0; c < channels; ++c)
                keep = history[c] >= low[c] - a.stillTolerance && history[c] <= high[c] + a.stillTolerance
                           ? keep
                           : splat<V>(0.0f);
            gated = keep;
            trust = gated > 0.5f ? splat<V>(0.0f) : trust;  // rho = 1 from 0 up
        }
        if (a.clip)
            for (int c = 0; c < channels; ++c) {
                V clipped = history[c] < low[c] ? low[c] : history[c];
                clipped = clipped > high[c] ? high[c] : clipped;
                history[c] = gated > 0.5f ? history[c] : clipped;
            }
        const V e = expNonPositive<V, I>(trust < 0.0f ? trust : splat<V>(0.0f));
        const V rho = trust < 0.0f ? 2.0f * e / (1.0f + e) : splat<V>(1.0f);
        const V m = rho * (s / (1.0f - s));
        const V historyWeight = m / (1.0f + m);
        V next = 1.0f + m;
        next = next < a.maxCount ? next : splat<V>(a.maxCount);
        V shown[kMaxChannels], keptValue[kMaxChannels];
        for (int c = 0; c < channels; ++c) {
            const V own = decodeSrgb<V, I>(loadu<V>(a.in[c * K + kRadius] + x));
            shown[c] = encodeSrgb<V, I>(filtered[c] + historyWeight * (history[c] - filtered[c]));
            keptValue[c] = own + historyWeight * (history[c] - own);
        }
        if (a.keptInterleaved) {  // (3 channels) the kept mean and the confidence, 4 floats a pixel
            keptValue[3] = next / (next + 1.0f);
            storeQuadsOf(a.keptInterleaved + 4 * x, keptValue);
        } else {
            storeu(a.nextConfidence + x, next / (next + 1.0f));
            for (int c = 0; c < channels; ++c) storeu(a.kept[c] + x, keptValue[c]);
        }
        if (!a.shownInterleaved) {
            for (int c = 0; c < channels; ++c) storeu(a.out[c] + x, shown[c]);
            return;
        }
        // The colour shown, clamped to [0, 1], into the frame's pixels of shownChannels floats (3 or 4:
        // the 4th passed through from shownPass) up to shownWidth.
        constexpr int kLanes = int(sizeof(V) / sizeof(float));
        for (int c = 0; c < 3; ++c) {
            shown[c] = shown[c] < 0.0f ? splat<V>(0.0f) : shown[c];
            shown[c] = shown[c] > 1.0f ? splat<V>(1.0f) : shown[c];
        }
        const int C = a.shownChannels;
        float* o = a.shownInterleaved + C * x;
        if (x + kLanes <= a.shownWidth) {
            if (C == 3) {
                storeRgbOf(o, shown);
            } else {
                shown[3] = splat<V>(0.0f);
                storeQuadsOf(o, shown);
                for (int l = 0; l < kLanes; ++l) o[4 * l + 3] = a.shownPass[4 * (x + l) + 3];
            }
            return;
        }
        for (int l = 0; l < kLanes && x + l < a.shownWidth; ++l) {
            for (int c = 0; c < 3; ++c) {
                if constexpr (kLanes == 1)
                    o[C * l + c] = shown[c];
                else
                    o[C * l + c] = shown[c][l];
            }
            if (C == 4) o[4 * l + 3] = a.shownPass[4 * (x + l) + 3];
        }
        return;
    }
    for (int c = 0; c < channels; ++c) {
        V value = splat<V>(0.0f);
        for (int dy = 0; dy < K; ++dy) {
            const float* row = a.in[c * K + dy];
            for (int dx = 0; dx < K; ++dx) value = value + weight[dy * K + dx] * loadu<V>(row + column[dx]);
        }
        if constexpr (History) value = value + weight[kTaps] * loadu<V>(a.history[c] + x);
        storeu(a.out[c] + x, value * scale);
    }
}

// The centre inputs of the pixels from x into the output (passed through).
template <class V, int K>
inline void passPixels(const KernelFilterRowArgs& a, int64_t x) {
    for (int c = 0; c < a.channels; ++c) storeu(a.out[c] + x, loadu<V>(a.in[c * K + K / 2] + x));
}

// History: with a history's (a guide's) weight after the taps (kernel_filter with a history).
template <int K, bool History = false>
void filterRow(const KernelFilterRowArgs& a) {
    constexpr int kRadius = K / 2;
    const int64_t W = a.width;
    const uint8_t* flat = a.flatGroups;
    auto onePixel = [&](int64_t x) {
        if (flat && flat[x / kPassGroup])
            passPixels<float, K>(a, x);
        else
            filterPixels<float, int32_t, K, History>(a, x, true);
    };
    int64_t x = 0;
    for (; x < std::min<int64_t>(kRadius, W); ++x) onePixel(x);
    for (; x + kFloatLanes + kRadius <= W; x += kFloatLanes) {
        if (!flat) {
            filterPixels<VFloat, VInt, K, History>(a, x, false);
            continue;
        }
        // The vector's lanes lie in one or two groups.
        const int64_t first = x / kPassGroup, last = (x + kFloatLanes - 1) / kPassGroup;
        if (flat[first] && flat[last]) {
            passPixels<VFloat, K>(a, x);
            continue;
        }
        filterPixels<VFloat, VInt, K, History>(a, x, false);
        if (flat[first] || flat[last]) {  // the passed lanes back to their inputs
            VInt lane;
#if defined(DEJAG_SIMD_LEVEL_scalar)
            lane = 0;
#else
            for (int l = 0; l < kFloatLanes; ++l) lane[l] = l;
#endif
            const VInt inFirst = lane < int32_t(last * kPassGroup - x);
            const VInt passed = flat[first] ? inFirst : ~inFirst;
            for (int c = 0; c < a.channels; ++c) {
                const VFloat centre = loadu<VFloat>(a.in[c * K + kRadius] + x);
                const VFloat filtered = loadu<VFloat>(a.out[c] + x);
                storeu(a.out[c] + x, passed ? centre : filtered);
            }
        }
    }
    for (; x < W; ++x) onePixel(x);
}

// One logit: bias + weights . the source pixel's features.
inline float logitAt(const KernelLogitsRowArgs& a, int64_t source, int tapPhase) {
    const float* w = a.weights + int64_t(tapPhase) * a.inChannels;
    float value = a.bias[tapPhase];
    for (int c = 0; c < a.inChannels; ++c)
        value += w[c] * a.features[(c / a.block) * a.blockStride + source * a.block + c % a.block];
    return value;
}

#if !defined(DEJAG_SIMD_LEVEL_scalar)
typedef float Float8 __attribute__((vector_size(8 * sizeof(float))));

// column[c] = element c of the 8 rows of 8 floats at p, p + rowStride, ... (an 8x8 transpose: unpacks
// within 128-bit halves, shuffles, then the halves exchanged), 24 shuffles instead of 8 gathers.
inline void transpose8x8(const float* p, int64_t rowStride, Float8 column[8]) {
    __m256 r[8], t[8], u[8];
    for (int i = 0; i < 8; ++i) r[i] = _mm256_loadu_ps(p + rowStride * i);
    for (int i = 0; i < 8; i += 2) {
        t[i] = _mm256_unpacklo_ps(r[i], r[i + 1]);      // r_i0 r_j0 r_i1 r_j1 | r_i4 r_j4 r_i5 r_j5
        t[i + 1] = _mm256_unpackhi_ps(r[i], r[i + 1]);  // r_i2 r_j2 r_i3 r_j3 | r_i6 r_j6 r_i7 r_j7
    }
    for (int i = 0; i < 8; i += 4)
        for (int k = 0; k < 2; ++k) {
            u[i + 2 * k] = _mm256_shuffle_ps(t[i + k], t[i + 2 + k], _MM_SHUFFLE(1, 0, 1, 0));
            u[i + 2 * k + 1] = _mm256_shuffle_ps(t[i + k], t[i + 2 + k], _MM_SHUFFLE(3, 2, 3, 2));
        }
    // u[k] (k < 4) holds columns k and k + 4 of rows 0-3, u[k + 4] the same of rows 4-7.
    for (int k = 0; k < 4; ++k) {
        column[k] = Float8(_mm256_permute2f128_ps(u[k], u[k + 4], 0x20));
        column[k + 4] = Float8(_mm256_permute2f128_ps(u[k], u[k + 4], 0x31));
    }
}
#endif

#if !defined(DEJAG_SIMD_LEVEL_scalar)
// The kTaps weighted sums of column phase `phase` for the vector of source pixels whose channel c is
// feature[c]: one dependency chain per sum, so they overlap.
template <int kTaps>
inline void phaseSums(const KernelLogitsRowArgs& a, const VFloat* feature, int phase, VFloat* sum) {
#pragma GCC unroll 16
    for (int j = 0; j < kTaps; ++j) sum[j] = splat<VFloat>(a.bias[2 * j + phase]);
    for (int c = 0; c < a.inChannels; ++c) {
        const float* w = a.weights + phase * a.inChannels + c;
#pragma GCC unroll 16
        for (int j = 0; j < kTaps; ++j) sum[j] = sum[j] + splat<VFloat>(w[2 * j * a.inChannels]) * feature[c];
    }
}

// kFloatLanes source pixels at a time for a factor of 2 and kTaps taps, from source pixel s: each channel's
// values gathered into a vector once, the kTaps sums of each column phase accumulated in a pass of their
// own (AVX2's 16 registers hold one phase's sums, not both: with both the compiler kept half of them on
// the stack, every multiply-add a load and a store), then each tap's two phases interleaved into
// 2 kFloatLanes columns.
template <int kTaps>
void logitsFactor2(const KernelLogitsRowArgs& a, int64_t& s) {
    const int64_t sources = a.width / 2;
    VInt stride;
    for (int l = 0; l < kFloatLanes; ++l) stride[l] = l * a.block;
    // Each channel's first source pixel (no division per vector).
    const float* channel[16];
    for (int c = 0; c < a.inChannels; ++c)
        channel[c] = a.features + (c / a.block) * a.blockStride + c % a.block;
    for (; s + kFloatLanes <= sources; s += kFloatLanes) {
        // 2 kFloatLanes output columns, inside one pass-through group: skipped when it is passed.
        if (a.flatGroups && a.flatGroups[2 * s / kPassGroup]) continue;
        // The gathers wait on memory unless the pixels two vectors ahead are on their way (the hardware
        // prefetcher does not follow gathers): a line per pixel for the first channel block.
        for (int l = 0; l < kFloatLanes; ++l)
            __builtin_prefetch(channel[0] + (s + 2 * kFloatLanes + l) * a.block);
        VFloat feature[16];
#if defined(DEJAG_SIMD_LEVEL_avx2)
        if (a.block == 8 && a.inChannels == 8) {  // kpn:8xD: the 8 pixels' channels are 64 floats in a row
            Float8 column[8];
            transpose8x8(a.features + s * 8, 8, column);
            for (int c = 0; c < 8; ++c) feature[c] = column[c];
        } else
#elif defined(DEJAG_SIMD_LEVEL_avx512)
        if (a.block == 16 && a.inChannels == 8) {  // kpn:8xD: the first 8 lanes of each pixel's vector
            // Two 8x8 transposes (pixels s..s+7 and s+8..s+15) joined: 16 loads and 56 shuffles
            // instead of 8 gathers of 16 floats.
            Float8 low[8], high[8];
            transpose8x8(a.features + s * 16, 16, low);
            transpose8x8(a.features + (s + 8) * 16, 16, high);
            for (int c = 0; c < 8; ++c)
                feature[c] = __builtin_shufflevector(low[c], high[c], 0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11,
                                                     12, 13, 14, 15);
        } else
#endif
        {
            for (int c = 0; c < a.inChannels; ++c) {
                const float* base = channel[c] + s * a.block;
#if defined(DEJAG_SIMD_LEVEL_avx512)
                feature[c] =
                    VFloat(_mm512_mask_i32gather_ps(_mm512_setzero_ps(), 0xffff, __m512i(stride), base, 4));
#else
                feature[c] = VFloat(_mm256_i32gather_ps(base, __m256i(stride), 4));
#endif
            }
        }
        VFloat even[kTaps], odd[kTaps];
        phaseSums<kTaps>(a, feature, 0, even);
        phaseSums<kTaps>(a, feature, 1, odd);
#pragma GCC unroll 16
        for (int j = 0; j < kTaps; ++j) {
            float* out = a.logits + j * a.width + 2 * s;
#if defined(DEJAG_SIMD_LEVEL_avx512)
            storeu(out, __builtin_shufflevector(even[j], odd[j], 0, 16, 1, 17, 2, 18, 3, 19, 4, 20, 5, 21, 6,
                                                22, 7, 23));
            storeu(out + 16, __builtin_shufflevector(even[j], odd[j], 8, 24, 9, 25, 10, 26, 11, 27, 12, 28,
                                                     13, 29, 14, 30, 15, 31));
#else
            storeu(out, __builtin_shufflevector(even[j], odd[j], 0, 8, 1, 9, 2, 10, 3, 11));
            storeu(out + 8, __builtin_shufflevector(even[j], odd[j], 4, 12, 5, 13, 6, 14, 7, 15));
#endif
        }
    }
}
#endif

}  // namespace

#if !defined(DEJAG_SIMD_LEVEL_scalar)
typedef float Float4 __attribute__((vector_size(4 * sizeof(float))));

// The largest lane of `high` minus the smallest of `low`, by halving (a tree, not a chain of
// kFloatLanes dependent steps).
inline float laneSpread(VFloat high, VFloat low) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    typedef float Half __attribute__((vector_size(8 * sizeof(float))));
    const Half hh = __builtin_shufflevector(high, high, 0, 1, 2, 3, 4, 5, 6, 7),
               hl = __builtin_shufflevector(high, high, 8, 9, 10, 11, 12, 13, 14, 15);
    const Half lh = __builtin_shufflevector(low, low, 0, 1, 2, 3, 4, 5, 6, 7),
               ll = __builtin_shufflevector(low, low, 8, 9, 10, 11, 12, 13, 14, 15);
    const Half h8 = hh < hl ? hl : hh, l8 = ll < lh ? ll : lh;
#else
    const VFloat h8 = high, l8 = low;
#endif
    const Float4 ha = __builtin_shufflevector(h8, h8, 0, 1, 2, 3),
                 hb = __builtin_shufflevector(h8, h8, 4, 5, 6, 7);
    const Float4 la = __builtin_shufflevector(l8, l8, 0, 1, 2, 3),
                 lb = __builtin_shufflevector(l8, l8, 4, 5, 6, 7);
    Float4 h = ha < hb ? hb : ha, l = lb < la ? lb : la;
    h = h < __builtin_shufflevector(h, h, 2, 3, 0, 1) ? __builtin_shufflevector(h, h, 2, 3, 0, 1) : h;
    l = __builtin_shufflevector(l, l, 2, 3, 0, 1) < l ? __builtin_shufflevector(l, l, 2, 3, 0, 1) : l;
    return std::max(h[0], h[1]) - std::min(l[0], l[1]);
}

// The greatest and the least of v's lanes, by halving.
template <bool kGreatest>
inline float laneExtreme(VFloat v) {
    auto pick = [](auto a, auto b) {
        if constexpr (kGreatest)
            return a < b ? b : a;
        else
            return b < a ? b : a;
    };
#if defined(DEJAG_SIMD_LEVEL_avx512)
    const auto e8 = pick(__builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7),
                         __builtin_shufflevector(v, v, 8, 9, 10, 11, 12, 13, 14, 15));
#else
    const VFloat e8 = v;
#endif
    Float4 e = pick(__builtin_shufflevector(e8, e8, 0, 1, 2, 3), __builtin_shufflevector(e8, e8, 4, 5, 6, 7));
    e = pick(e, __builtin_shufflevector(e, e, 2, 3, 0, 1));
    e = pick(e, __builtin_shufflevector(e, e, 1, 0, 3, 2));
    return e[0];
}
inline float laneMax(VFloat v) {
    return laneExtreme<true>(v);
}
inline float laneMin(VFloat v) {
    return laneExtreme<false>(v);
}

// The sum of v's lanes (NaN if any lane is), by halving.
inline float laneSum(VFloat v) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    typedef float Half __attribute__((vector_size(8 * sizeof(float))));
    const Half s8 = __builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7) +
                    __builtin_shufflevector(v, v, 8, 9, 10, 11, 12, 13, 14, 15);
#else
    const VFloat s8 = v;
#endif
    Float4 s4 = __builtin_shufflevector(s8, s8, 0, 1, 2, 3) + __builtin_shufflevector(s8, s8, 4, 5, 6, 7);
    s4 = s4 + __builtin_shufflevector(s4, s4, 2, 3, 0, 1);
    return s4[0] + s4[1];
}
#endif

#if !defined(DEJAG_SIMD_LEVEL_scalar)
// Columns [x0, x1] of a row (at least a vector of them) into lane-wise extremes and a sum that turns NaN
// at a NaN or an infinity: whole vectors, then the last columns by an overlapping load.
inline void takeWindow(const float* row, int64_t x0, int64_t x1, VFloat& low, VFloat& high, VFloat& bad) {
    auto take = [&](int64_t x) {
        const VFloat v = loadu<VFloat>(row + x);
        low = v < low ? v : low, high = high < v ? v : high, bad = bad + (v - v);
    };
    int64_t x = x0;
    for (; x + kFloatLanes <= x1 + 1; x += kFloatLanes) take(x);
    if (x <= x1) take(x1 + 1 - kFloatLanes);
}
#endif

int64_t kernelFlatGroups(const KernelFilterRowArgs& a, float span, uint8_t* flat) {
    const int K = a.kernel, r = K / 2;
    const int64_t W = a.width, groups = (W + kPassGroup - 1) / kPassGroup;
    int64_t count = 0;
    for (int64_t g = 0; g < groups; ++g) {
        // The group's neighbourhood: columns [x0, x1] of the kernel's rows (edges repeated, so clamping
        // the columns loses nothing). A NaN or an infinity anywhere there makes `bad` NaN: not flat.
        const int64_t x0 = std::max<int64_t>(0, g * kPassGroup - r),
                      x1 = std::min<int64_t>(W - 1, (g + 1) * kPassGroup - 1 + r);
        bool isFlat = true;
        for (int c = 0; c < a.channels && isFlat; ++c) {
#if !defined(DEJAG_SIMD_LEVEL_scalar)
            if (x1 - x0 + 1 >= kFloatLanes) {
                VFloat low = loadu<VFloat>(a.in[c * K] + x0), high = low, bad = low - low;
                for (int dy = 0; dy < K; ++dy) takeWindow(a.in[c * K + dy], x0, x1, low, high, bad);
                isFlat = laneSpread(high, low) <= span && laneSum(bad) == 0.0f;
                continue;
            }
#endif
            float low = a.in[c * K][x0], high = low, bad = 0.0f;
            for (int dy = 0; dy < K; ++dy)
                for (int64_t x = x0; x <= x1; ++x) {
                    const float v = a.in[c * K + dy][x];
                    low = std::min(low, v), high = std::max(high, v), bad += v - v;
                }
            isFlat = high - low <= span && bad == 0.0f;
        }
        flat[g] = isFlat;
        count += isFlat;
    }
    return count;
}

void kernelRowRanges(const float* const* rows, int channels, int64_t width, int radius, float* low,
                     float* high, uint8_t* bad) {
    const int64_t groups = (width + kPassGroup - 1) / kPassGroup;
    for (int64_t g = 0; g < groups; ++g) {
        const int64_t x0 = std::max<int64_t>(0, g * kPassGroup - radius),
                      x1 = std::min<int64_t>(width - 1, (g + 1) * kPassGroup - 1 + radius);
        float badSum = 0.0f;  // NaN when a value is a NaN or an infinity
        for (int c = 0; c < channels; ++c) {
            const float* row = rows[c];
#if !defined(DEJAG_SIMD_LEVEL_scalar)
            if (x1 - x0 + 1 >= kFloatLanes) {
                VFloat lo = loadu<VFloat>(row + x0), hi = lo, sum = lo - lo;
                takeWindow(row, x0, x1, lo, hi, sum);
                low[g * channels + c] = laneMin(lo), high[g * channels + c] = laneMax(hi);
                badSum += laneSum(sum);
                continue;
            }
#endif
            float l = row[x0], h = l;
            for (int64_t x = x0; x <= x1; ++x) {
                const float v = row[x];
                l = std::min(l, v), h = std::max(h, v), badSum += v - v;
            }
            low[g * channels + c] = l, high[g * channels + c] = h;
        }
        bad[g] = !(badSum == 0.0f);
    }
}

void kernelLogitsRow(const KernelLogitsRowArgs& a) {
    int64_t s = 0;
#if !defined(DEJAG_SIMD_LEVEL_scalar)
    if (a.factor == 2 && a.taps == 9 && a.inChannels <= 16) logitsFactor2<9>(a, s);  // the kpn family's
    // the temporal families' (9 taps and the history's weight or the trust)
    if (a.factor == 2 && a.taps == 10 && a.inChannels <= 16) logitsFactor2<10>(a, s);
#endif
    for (; s < a.width / a.factor; ++s)
        for (int j = 0; j < a.taps; ++j)
            for (int p = 0; p < a.factor; ++p)
                a.logits[j * a.width + s * a.factor + p] = logitAt(a, s, j * a.factor + p);
}

// A row with a history (or accumulate's): every pixel filtered (no pass-through).
template <int K, bool Accumulate, int kChannels = 0>
void filterRowWithHistory(const KernelFilterRowArgs& a) {
    if constexpr (kChannels == 0)
        if (a.channels == 3) return filterRowWithHistory<K, Accumulate, 3>(a);  // RGB: unrolled
    constexpr int kRadius = K / 2;
    const int64_t W = a.width;
    int64_t x = 0;
    for (; x < std::min<int64_t>(kRadius, W); ++x)
        filterPixels<float, int32_t, K, true, Accumulate, kChannels>(a, x, true);
    for (; x + kFloatLanes + kRadius <= W; x += kFloatLanes)
        filterPixels<VFloat, VInt, K, true, Accumulate, kChannels>(a, x, false);
    for (; x < W; ++x) filterPixels<float, int32_t, K, true, Accumulate, kChannels>(a, x, true);
}

void kernelFilterRow(const KernelFilterRowArgs& args) {
    if (args.history && (args.kept || args.keptInterleaved)) {  // accumulate
        if (args.kernel == 3) return filterRowWithHistory<3, true>(args);
        if (args.kernel == 1) return filterRowWithHistory<1, true>(args);
        return;
    }
    if (args.history && args.flatGroups) {  // a guided kpn's, gated: flat groups passed through
        if (args.kernel == 3) return filterRow<3, true>(args);
        if (args.kernel == 1) return filterRow<1, true>(args);
        return;
    }
    if (args.history) {
        if (args.kernel == 3) return filterRowWithHistory<3, false>(args);
        if (args.kernel == 1) return filterRowWithHistory<1, false>(args);
        return;
    }
    switch (args.kernel) {
        case 1:
            return filterRow<1>(args);
        case 3:
            return filterRow<3>(args);
        case 5:
            return filterRow<5>(args);
        case 7:
            return filterRow<7>(args);
        default:
            return;
    }
}

}  // namespace dejag::nn::DEJAG_SIMD_NAMESPACE

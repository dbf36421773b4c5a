// dejag/base: the sRGB curves on SIMD lanes by exponent and mantissa, for kernel sources built with
// dejag_add_simd_kernels() (taa-hq's band, the accumulate kernel). Both curves are powers past their knee:
// x^p with x = 2^e m, m in [1, 2), is 2^(e p) m^p. m^p is one polynomial in m - 1.5 (interpolating it at
// the Chebyshev nodes of [1, 2], fitted in double once), and 2^(e p) one of 16 factors read by the low 4
// bits of the float's biased exponent (decoding sees e in [-5, 0], encoding e in [-9, -1]: 16 apart at
// most). No gathers: the factor is one permute (AVX-512) or two and a blend (AVX2). The degree sets the
// accuracy: m^2.4 to 1.4e-6 relative at degree 5, 1.3e-7 at 6, 6e-9 at 7; m^(1/2.4) to 5e-7 at 6, 3.5e-8
// at 7 (scripts/srgb_polynomials.py measures them).
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <utility>

#include "base/pixel_simd.h"
#include "base/srgb.h"

namespace dejag::DEJAG_SIMD_NAMESPACE {

using dejag::kSrgbDecodeKnee;
using dejag::kSrgbEncodeKnee;

using dejag::fitPower;
using dejag::PowerCurve;
using dejag::srgbDecodeCurve7;
using dejag::srgbEncodeCurve7;

// The int lanes of V (float: one int32_t).
template <class V>
using IntLanes = std::conditional_t<sizeof(V) == sizeof(float), int32_t, VInt>;

template <class V>
inline IntLanes<V> asIntLanes(V v) {
    IntLanes<V> i;
    std::memcpy(&i, &v, sizeof(i));
    return i;
}
template <class V>
inline V asFloatLanes(IntLanes<V> i) {
    V v;
    std::memcpy(&v, &i, sizeof(v));
    return v;
}

// table[index & 15] for each lane (table 64-byte aligned).
template <class V>
inline V lookup16(const float* table, IntLanes<V> index) {
    if constexpr (sizeof(V) == sizeof(float)) {
        return table[index & 15];
#if defined(DEJAG_SIMD_LEVEL_avx512)
    } else {
        const __m512 t = _mm512_load_ps(table);  // (both sources: bit 4 of the index picks either)
        return V(_mm512_permutex2var_ps(t, __m512i(index), t));
#elif defined(DEJAG_SIMD_LEVEL_avx2)
    } else {
        const __m256 low = _mm256_permutevar8x32_ps(_mm256_load_ps(table), __m256i(index));
        const __m256 high = _mm256_permutevar8x32_ps(_mm256_load_ps(table + 8), __m256i(index));
        // (vpermps reads the low 3 bits; bit 3 picks the second half, moved to the sign bit)
        return V(_mm256_blendv_ps(low, high, _mm256_castsi256_ps(_mm256_slli_epi32(__m256i(index), 28))));
#endif
    }
}

// The curve at x > 0 (a normal float): factor(e) m^p. Degree: the curve's (a constant, so the polynomial
// is unrolled).
template <int Degree, class V>
inline V powerAt(const PowerCurve& curve, V x) {
    static_assert(Degree >= 1 && Degree <= 7);
    const IntLanes<V> bits = asIntLanes(x);
    const V s = asFloatLanes<V>((bits & 0x7fffff) | 0x3f800000) - 1.5f;  // m - 1.5
    V poly = splat<V>(curve.c[Degree]);
#pragma GCC unroll 8
    for (int j = Degree - 1; j >= 0; --j) poly = poly * s + curve.c[j];
    return lookup16<V>(curve.factor, bits >> 23) * poly;
}

// sRGB-encoded [0, 1] (clamped; NaN reads 0) to linear light, by `curve` = fitPower(2.4, Degree, 1).
template <int Degree, class V>
inline V decodeSrgbBy(const PowerCurve& curve, V v) {
    v = v > 0.0f ? v : splat<V>(0.0f);  // (a NaN becomes 0)
    v = v < 1.0f ? v : splat<V>(1.0f);
    const V power = powerAt<Degree>(curve, v * (1.0f / 1.055f) + (0.055f / 1.055f));
    return v <= kSrgbDecodeKnee ? v * (1.0f / 12.92f) : power;
}

// Linear light [0, 1] (clamped; NaN reads 0) to sRGB-encoded, by `curve` = fitPower(1 / 2.4, Degree,
// 1.055).
template <int Degree, class V>
inline V encodeSrgbBy(const PowerCurve& curve, V x) {
    x = x > 0.0f ? x : splat<V>(0.0f);
    x = x < 0.99999994f ? x : splat<V>(0.99999994f);  // (below 1: e at most -1)
    // (the linear part's lanes, 0 and subnormals too, read some factor of the table and are replaced)
    const V power = powerAt<Degree>(curve, x) - 0.055f;
    return x <= kSrgbEncodeKnee ? x * 12.92f : power;
}

}  // namespace dejag::DEJAG_SIMD_NAMESPACE

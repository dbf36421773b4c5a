// dejag/base: per-pixel SIMD helpers for the pixel kernels (FXAA, TAA, the network's frame rows). Include
// only from kernel sources built with dejag_add_simd_kernels(): one body, written with VFloat/VInt and the
// helpers below, runs kFloatLanes pixels at a time on every level (one pixel on the scalar path).
//
// Masks are what a comparison returns: a vector of 0 / -1 ints, or a bool on the scalar path; select(),
// any() and all() take either.
#pragma once

#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>

#include "base/simd_vector.h"

namespace dejag::DEJAG_SIMD_NAMESPACE {

#if defined(DEJAG_SIMD_LEVEL_scalar)
using VInt = int32_t;
using VMask = bool;
#else
typedef int32_t VInt __attribute__((vector_size(kFloatLanes * sizeof(int32_t))));
using VMask = VInt;
#endif

template <class V>
inline V select(VMask m, V a, V b) {
    return m ? a : b;
}
inline VFloat vmin(VFloat a, VFloat b) {
    return b < a ? b : a;  // std::min's order
}
inline VFloat vmax(VFloat a, VFloat b) {
    return a < b ? b : a;  // std::max's order
}
inline VInt vmin(VInt a, VInt b) {
    return b < a ? b : a;
}
inline VInt vmax(VInt a, VInt b) {
    return a < b ? b : a;
}
inline VFloat clamp01(VFloat v) {
    return vmin(vmax(v, splat<VFloat>(0.0f)), splat<VFloat>(1.0f));
}
inline VFloat vclamp(VFloat v, VFloat lo, VFloat hi) {
    return vmin(vmax(v, lo), hi);
}
inline VInt vclamp(VInt v, VInt lo, VInt hi) {
    return vmin(vmax(v, lo), hi);
}
inline VFloat mix(VFloat a, VFloat b, VFloat t) {
    return a + (b - a) * t;
}

#if defined(DEJAG_SIMD_LEVEL_scalar)
inline VInt splatInt(int32_t v) {
    return v;
}
inline VFloat vabs(VFloat v) {
    return std::fabs(v);
}
inline VFloat vsqrt(VFloat v) {
    return std::sqrt(v);
}
inline VFloat toFloat(VInt v) {
    return float(v);
}
inline VInt truncateToInt(VFloat v) {
    return int32_t(v);
}
inline bool any(VMask m) {
    return m;
}
inline bool all(VMask m) {
    return m;
}
inline uint32_t maskBits(VMask m) {
    return m ? 1u : 0u;
}
inline VMask maskNot(VMask m) {
    return !m;
}
inline VInt laneIndex() {
    return 0;
}
inline int32_t laneMin(VInt m) {
    return m;
}
inline int32_t laneMax(VInt m) {
    return m;
}
inline VFloat gather(const float* base, VInt index) {
    return base[index];
}
inline void gatherPairs(const float* base, VInt index, VFloat& first, VFloat& second) {
    first = base[index], second = base[index + 1];
}
#else
inline VInt splatInt(int32_t v) {
    return VInt{} + v;  // a broadcast (a lane-by-lane loop here cost T-TAA 7 % of its time)
}
inline VFloat vabs(VFloat v) {
    return VFloat(VInt(v) & splatInt(0x7fffffff));
}
inline VFloat toFloat(VInt v) {
    return __builtin_convertvector(v, VFloat);
}
inline VInt truncateToInt(VFloat v) {
    return __builtin_convertvector(v, VInt);
}
inline VMask maskNot(VMask m) {
    return ~m;
}
inline VInt laneIndex() {
    VInt r;
    for (int i = 0; i < kFloatLanes; ++i) r[i] = i;
    return r;
}
#if defined(DEJAG_SIMD_LEVEL_avx512)
inline VFloat vsqrt(VFloat v) {
    return VFloat(_mm512_maskz_sqrt_ps(0xffff, __m512(v)));  // (GCC 12 warns on the unmasked form)
}
inline bool any(VMask m) {
    return _mm512_movepi32_mask(__m512i(m)) != 0;
}
inline bool all(VMask m) {
    return _mm512_movepi32_mask(__m512i(m)) == 0xffff;
}
inline uint32_t maskBits(VMask m) {  // bit i: lane i
    return _mm512_movepi32_mask(__m512i(m));
}
// The smallest and largest lane, by halving (generic shuffles: GCC 12 warns on the intrinsics').
inline int32_t laneMin(VInt m) {
    m = vmin(m, __builtin_shufflevector(m, m, 8, 9, 10, 11, 12, 13, 14, 15, 0, 1, 2, 3, 4, 5, 6, 7));
    m = vmin(m, __builtin_shufflevector(m, m, 4, 5, 6, 7, 0, 1, 2, 3, 12, 13, 14, 15, 8, 9, 10, 11));
    m = vmin(m, __builtin_shufflevector(m, m, 2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13));
    m = vmin(m, __builtin_shufflevector(m, m, 1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14));
    return m[0];
}
inline int32_t laneMax(VInt m) {
    m = vmax(m, __builtin_shufflevector(m, m, 8, 9, 10, 11, 12, 13, 14, 15, 0, 1, 2, 3, 4, 5, 6, 7));
    m = vmax(m, __builtin_shufflevector(m, m, 4, 5, 6, 7, 0, 1, 2, 3, 12, 13, 14, 15, 8, 9, 10, 11));
    m = vmax(m, __builtin_shufflevector(m, m, 2, 3, 0, 1, 6, 7, 4, 5, 10, 11, 8, 9, 14, 15, 12, 13));
    m = vmax(m, __builtin_shufflevector(m, m, 1, 0, 3, 2, 5, 4, 7, 6, 9, 8, 11, 10, 13, 12, 15, 14));
    return m[0];
}
// base[index] and base[index + 1] per lane: 64-bit gathers, half as many elements as two 32-bit ones.
inline void gatherPairs(const float* base, VInt index, VFloat& first, VFloat& second) {
    typedef int32_t VInt8 __attribute__((vector_size(32)));
    const VInt8 low = __builtin_shufflevector(index, index, 0, 1, 2, 3, 4, 5, 6, 7);
    const VInt8 high = __builtin_shufflevector(index, index, 8, 9, 10, 11, 12, 13, 14, 15);
    const __m512 a =
        _mm512_castsi512_ps(_mm512_mask_i32gather_epi64(_mm512_setzero_si512(), 0xff, __m256i(low), base, 4));
    const __m512 b = _mm512_castsi512_ps(
        _mm512_mask_i32gather_epi64(_mm512_setzero_si512(), 0xff, __m256i(high), base, 4));
    first = VFloat(_mm512_permutex2var_ps(
        a, _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30), b));
    second = VFloat(_mm512_permutex2var_ps(
        a, _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31), b));
}
inline VFloat gather(const float* base, VInt index) {
    return VFloat(_mm512_mask_i32gather_ps(_mm512_setzero_ps(), 0xffff, __m512i(index), base, 4));
}
#else
inline VFloat vsqrt(VFloat v) {
    return VFloat(_mm256_sqrt_ps(__m256(v)));
}
inline bool any(VMask m) {
    return _mm256_movemask_ps(__m256(m)) != 0;
}
inline bool all(VMask m) {
    return _mm256_movemask_ps(__m256(m)) == 0xff;
}
inline uint32_t maskBits(VMask m) {  // bit i: lane i
    return uint32_t(_mm256_movemask_ps(__m256(m)));
}
inline VFloat gather(const float* base, VInt index) {
    return VFloat(_mm256_i32gather_ps(base, __m256i(index), 4));
}
// The smallest and largest lane, by halving.
inline int32_t laneMin(VInt m) {
    m = vmin(m, __builtin_shufflevector(m, m, 4, 5, 6, 7, 0, 1, 2, 3));
    m = vmin(m, __builtin_shufflevector(m, m, 2, 3, 0, 1, 6, 7, 4, 5));
    m = vmin(m, __builtin_shufflevector(m, m, 1, 0, 3, 2, 5, 4, 7, 6));
    return m[0];
}
inline int32_t laneMax(VInt m) {
    m = vmax(m, __builtin_shufflevector(m, m, 4, 5, 6, 7, 0, 1, 2, 3));
    m = vmax(m, __builtin_shufflevector(m, m, 2, 3, 0, 1, 6, 7, 4, 5));
    m = vmax(m, __builtin_shufflevector(m, m, 1, 0, 3, 2, 5, 4, 7, 6));
    return m[0];
}
inline void gatherPairs(const float* base, VInt index, VFloat& first, VFloat& second) {
    first = gather(base, index), second = gather(base + 1, index);
}
#endif

// A window of kWindowFloats consecutive floats read with two loads, from which a permute gives each lane
// the float its index names: where the lanes read nearby pixels of one row (a still or smoothly moving
// camera), this replaces a gather (AVX-512: one 32-entry permute; AVX2: two 8-entry permutes and a blend).
inline constexpr int kWindowFloats = 2 * kFloatLanes;
struct Window {
    VFloat low, high;
};
inline Window loadWindow(const float* p) {
    return {loadu<VFloat>(p), loadu<VFloat>(p + kFloatLanes)};
}
// Lane i: window[index[i]], index in [0, kWindowFloats).
inline VFloat fromWindow(const Window& w, VInt index) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    return VFloat(_mm512_permutex2var_ps(__m512(w.low), __m512i(index), __m512(w.high)));
#else
    const __m256 low = _mm256_permutevar8x32_ps(__m256(w.low), __m256i(index));
    const __m256 high = _mm256_permutevar8x32_ps(__m256(w.high), __m256i(index));
    // (vpermps reads the low 3 bits of each index; bit 3 picks the second vector, moved to the sign bit)
    return VFloat(_mm256_blendv_ps(low, high, _mm256_castsi256_ps(_mm256_slli_epi32(__m256i(index), 28))));
#endif
}
// Whether every lane of lo and hi lies in [first, first + kWindowFloats) (no lane reductions: one
// subtraction each, an or and a test).
inline bool withinWindow(VInt lo, VInt hi, int32_t first) {
    const VInt offsets = (lo - first) | (hi - first);  // a lane below first is negative: high bits set
#if defined(DEJAG_SIMD_LEVEL_avx512)
    return _mm512_test_epi32_mask(__m512i(offsets), _mm512_set1_epi32(~(kWindowFloats - 1))) == 0;
#else
    return _mm256_testz_si256(__m256i(offsets), _mm256_set1_epi32(~(kWindowFloats - 1))) != 0;
#endif
}
#endif

// The 4 consecutive floats at base + index of each lane, as 4 vectors: quad[i] lane l = base[index[l] + i].
// One 128-bit load a lane and a 4x4 transpose instead of 4 gathers (about 3x cheaper a float on Zen 4,
// where a gather costs about 1.9 cycles an element).
inline void loadQuads(const float* base, VInt index, VFloat quad[4]) {
#if defined(DEJAG_SIMD_LEVEL_scalar)
    for (int i = 0; i < 4; ++i) quad[i] = base[index + i];
#else
    alignas(64) int32_t at[kFloatLanes];
    std::memcpy(at, &index, sizeof(at));
    auto q = [&](int lane) { return _mm_loadu_ps(base + at[lane]); };
    // Vector b holds lanes b, 4 + b, ... in its 128-bit blocks, so the transpose inside the blocks leaves
    // lane 4p + b of each result in block p, element b: lane order.
#if defined(DEJAG_SIMD_LEVEL_avx512)
    __m512 z[4];
    for (int b = 0; b < 4; ++b)
        z[b] = _mm512_insertf32x4(
            _mm512_insertf32x4(_mm512_insertf32x4(_mm512_castps128_ps512(q(b)), q(4 + b), 1), q(8 + b), 2),
            q(12 + b), 3);
    // (shuffles written as such: GCC 12 warns on the unpack intrinsics' undefined operand)
    const VFloat z0 = VFloat(z[0]), z1 = VFloat(z[1]), z2 = VFloat(z[2]), z3 = VFloat(z[3]);
    const VFloat lo01 =
        __builtin_shufflevector(z0, z1, 0, 16, 1, 17, 4, 20, 5, 21, 8, 24, 9, 25, 12, 28, 13, 29);
    const VFloat hi01 =
        __builtin_shufflevector(z0, z1, 2, 18, 3, 19, 6, 22, 7, 23, 10, 26, 11, 27, 14, 30, 15, 31);
    const VFloat lo23 =
        __builtin_shufflevector(z2, z3, 0, 16, 1, 17, 4, 20, 5, 21, 8, 24, 9, 25, 12, 28, 13, 29);
    const VFloat hi23 =
        __builtin_shufflevector(z2, z3, 2, 18, 3, 19, 6, 22, 7, 23, 10, 26, 11, 27, 14, 30, 15, 31);
    quad[0] = __builtin_shufflevector(lo01, lo23, 0, 1, 16, 17, 4, 5, 20, 21, 8, 9, 24, 25, 12, 13, 28, 29);
    quad[1] = __builtin_shufflevector(lo01, lo23, 2, 3, 18, 19, 6, 7, 22, 23, 10, 11, 26, 27, 14, 15, 30, 31);
    quad[2] = __builtin_shufflevector(hi01, hi23, 0, 1, 16, 17, 4, 5, 20, 21, 8, 9, 24, 25, 12, 13, 28, 29);
    quad[3] = __builtin_shufflevector(hi01, hi23, 2, 3, 18, 19, 6, 7, 22, 23, 10, 11, 26, 27, 14, 15, 30, 31);
#else
    __m256 z[4];
    for (int b = 0; b < 4; ++b) z[b] = _mm256_insertf128_ps(_mm256_castps128_ps256(q(b)), q(4 + b), 1);
    const __m256 lo01 = _mm256_unpacklo_ps(z[0], z[1]), hi01 = _mm256_unpackhi_ps(z[0], z[1]);
    const __m256 lo23 = _mm256_unpacklo_ps(z[2], z[3]), hi23 = _mm256_unpackhi_ps(z[2], z[3]);
    quad[0] = VFloat(_mm256_shuffle_ps(lo01, lo23, _MM_SHUFFLE(1, 0, 1, 0)));
    quad[1] = VFloat(_mm256_shuffle_ps(lo01, lo23, _MM_SHUFFLE(3, 2, 3, 2)));
    quad[2] = VFloat(_mm256_shuffle_ps(hi01, hi23, _MM_SHUFFLE(1, 0, 1, 0)));
    quad[3] = VFloat(_mm256_shuffle_ps(hi01, hi23, _MM_SHUFFLE(3, 2, 3, 2)));
#endif
#endif
}

// floor(v) as an int (v within the int range).
inline VInt floorToInt(VFloat v) {
    const VInt t = truncateToInt(v);
#if defined(DEJAG_SIMD_LEVEL_scalar)
    return float(t) > v ? t - 1 : t;
#else
    return t + (toFloat(t) > v);  // true is -1
#endif
}

// Pixels x .. x + kFloatLanes - 1 of an interleaved RGB row, split into planes (and back).
inline void loadRgb(const float* p, VFloat& r, VFloat& g, VFloat& b) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    const __m512 a0 = _mm512_loadu_ps(p), a1 = _mm512_loadu_ps(p + 16), a2 = _mm512_loadu_ps(p + 32);
    // Step 1 takes the lanes whose stream position 3j + c lies in a0:a1, step 2 the rest from a2.
    const __m512i first[3] = {_mm512_setr_epi32(0, 3, 6, 9, 12, 15, 18, 21, 24, 27, 30, 0, 0, 0, 0, 0),
                              _mm512_setr_epi32(1, 4, 7, 10, 13, 16, 19, 22, 25, 28, 31, 0, 0, 0, 0, 0),
                              _mm512_setr_epi32(2, 5, 8, 11, 14, 17, 20, 23, 26, 29, 0, 0, 0, 0, 0, 0)};
    const __m512i second[3] = {_mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 17, 20, 23, 26, 29),
                               _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 18, 21, 24, 27, 30),
                               _mm512_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 16, 19, 22, 25, 28, 31)};
    r = VFloat(_mm512_permutex2var_ps(_mm512_permutex2var_ps(a0, first[0], a1), second[0], a2));
    g = VFloat(_mm512_permutex2var_ps(_mm512_permutex2var_ps(a0, first[1], a1), second[1], a2));
    b = VFloat(_mm512_permutex2var_ps(_mm512_permutex2var_ps(a0, first[2], a1), second[2], a2));
#elif defined(DEJAG_SIMD_LEVEL_scalar)
    r = p[0], g = p[1], b = p[2];
#else
    // Each 128-bit half deinterleaves 4 pixels: pixels 0-3 from the first 12 floats, 4-7 from the next.
    // Per half: q0 = r0 g0 b0 r1, q1 = g1 b1 r2 g2, q2 = b2 r3 g3 b3.
    const __m256 q0 = _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p)), _mm_loadu_ps(p + 12), 1);
    const __m256 q1 =
        _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 4)), _mm_loadu_ps(p + 16), 1);
    const __m256 q2 =
        _mm256_insertf128_ps(_mm256_castps128_ps256(_mm_loadu_ps(p + 8)), _mm_loadu_ps(p + 20), 1);
    const __m256 rg = _mm256_shuffle_ps(q1, q2, _MM_SHUFFLE(2, 1, 3, 2));  // r2 g2 r3 g3
    const __m256 gb = _mm256_shuffle_ps(q0, q1, _MM_SHUFFLE(1, 0, 2, 1));  // g0 b0 g1 b1
    r = VFloat(_mm256_shuffle_ps(q0, rg, _MM_SHUFFLE(2, 0, 3, 0)));
    g = VFloat(_mm256_shuffle_ps(gb, rg, _MM_SHUFFLE(3, 1, 2, 0)));
    b = VFloat(_mm256_shuffle_ps(gb, q2, _MM_SHUFFLE(3, 0, 3, 1)));
#endif
}

inline void storeRgb(float* p, VFloat r, VFloat g, VFloat b) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    // Output vector k holds stream positions 16k .. 16k + 15: pixel s / 3, channel s % 3.
    const __m512i rg[3] = {_mm512_setr_epi32(0, 16, 0, 1, 17, 0, 2, 18, 0, 3, 19, 0, 4, 20, 0, 5),
                           _mm512_setr_epi32(21, 0, 6, 22, 0, 7, 23, 0, 8, 24, 0, 9, 25, 0, 10, 26),
                           _mm512_setr_epi32(0, 11, 27, 0, 12, 28, 0, 13, 29, 0, 14, 30, 0, 15, 31, 0)};
    const __m512i withB[3] = {_mm512_setr_epi32(0, 1, 16, 3, 4, 17, 6, 7, 18, 9, 10, 19, 12, 13, 20, 15),
                              _mm512_setr_epi32(0, 21, 2, 3, 22, 5, 6, 23, 8, 9, 24, 11, 12, 25, 14, 15),
                              _mm512_setr_epi32(26, 1, 2, 27, 4, 5, 28, 7, 8, 29, 10, 11, 30, 13, 14, 31)};
    for (int k = 0; k < 3; ++k)
        _mm512_storeu_ps(
            p + 16 * k,
            _mm512_permutex2var_ps(_mm512_permutex2var_ps(__m512(r), rg[k], __m512(g)), withB[k], __m512(b)));
#elif defined(DEJAG_SIMD_LEVEL_scalar)
    p[0] = r, p[1] = g, p[2] = b;
#else
    // loadRgb backwards: per 128-bit half, pixels 0-3 (or 4-7) interleaved into q0 q1 q2.
    const __m256 vr = __m256(r), vg = __m256(g), vb = __m256(b);
    const __m256 rg = _mm256_shuffle_ps(vr, vg, _MM_SHUFFLE(2, 0, 2, 0));  // r0 r2 g0 g2
    const __m256 gb = _mm256_shuffle_ps(vg, vb, _MM_SHUFFLE(3, 1, 3, 1));  // g1 g3 b1 b3
    const __m256 br = _mm256_shuffle_ps(vb, vr, _MM_SHUFFLE(3, 1, 2, 0));  // b0 b2 r1 r3
    const __m256 q0 = _mm256_shuffle_ps(rg, br, _MM_SHUFFLE(2, 0, 2, 0));  // r0 g0 b0 r1
    const __m256 q1 = _mm256_shuffle_ps(gb, rg, _MM_SHUFFLE(3, 1, 2, 0));  // g1 b1 r2 g2
    const __m256 q2 = _mm256_shuffle_ps(br, gb, _MM_SHUFFLE(3, 1, 3, 1));  // b2 r3 g3 b3
    _mm256_storeu_ps(p, _mm256_permute2f128_ps(q0, q1, 0x20));
    _mm256_storeu_ps(p + 8, _mm256_permute2f128_ps(q2, q0, 0x30));
    _mm256_storeu_ps(p + 16, _mm256_permute2f128_ps(q1, q2, 0x31));
#endif
}

// The first `count` pixels of storeRgb (all of them when count >= kFloatLanes): a row's last, partial
// vector.
inline void storeRgbFirst(float* p, VFloat r, VFloat g, VFloat b, int count) {
    if (count >= kFloatLanes) return storeRgb(p, r, g, b);
    float tail[3 * kFloatLanes];
    storeRgb(tail, r, g, b);
    std::memcpy(p, tail, sizeof(float) * 3 * size_t(count));
}

// Four planes' lanes stored as kFloatLanes pixels of 4 floats (p[4 l + c] = v[c] lane l): the two
// channel pairs alternated, then the pairs alternated; two shuffles a vector stored.
#if !defined(DEJAG_SIMD_LEVEL_scalar)
namespace quads_detail {
using Lanes = std::array<int32_t, kFloatLanes>;
constexpr int N = kFloatLanes;
// a0 b0 a1 b1 ... from lane `from` of each.
constexpr Lanes pairs(int from) {
    Lanes index{};
    for (int i = 0; i < N; ++i) index[size_t(i)] = (i % 2 ? N : 0) + from + i / 2;
    return index;
}
// Two pair vectors' pairs alternated from pair `from` of each: a0 b0 c0 d0 a1 b1 c1 d1 ...
constexpr Lanes quads(int from) {
    Lanes index{};
    for (int i = 0; i < N; ++i) index[size_t(i)] = (i / 2 % 2 ? N : 0) + 2 * (from + i / 4) + i % 2;
    return index;
}
inline constexpr Lanes kPairsLow = pairs(0), kPairsHigh = pairs(N / 2);
inline constexpr Lanes kQuadsLow = quads(0), kQuadsHigh = quads(N / 4);
}  // namespace quads_detail
#endif
inline void storeQuads(float* p, const VFloat v[4]) {
#if defined(DEJAG_SIMD_LEVEL_scalar)
    for (int c = 0; c < 4; ++c) p[c] = v[c];
#else
    using namespace quads_detail;
    const VFloat ab[2] = {shuffleTwo<kPairsLow>(v[0], v[1]), shuffleTwo<kPairsHigh>(v[0], v[1])};
    const VFloat cd[2] = {shuffleTwo<kPairsLow>(v[2], v[3]), shuffleTwo<kPairsHigh>(v[2], v[3])};
    for (int h = 0; h < 2; ++h) {
        storeu(p + (2 * h) * N, shuffleTwo<kQuadsLow>(ab[h], cd[h]));
        storeu(p + (2 * h + 1) * N, shuffleTwo<kQuadsHigh>(ab[h], cd[h]));
    }
#endif
}

// Pixels x .. x + kFloatLanes - 1 of an interleaved 2-channel row (motion vectors), split into planes.
inline void loadPairs(const float* p, VFloat& a, VFloat& b) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    const __m512 a0 = _mm512_loadu_ps(p), a1 = _mm512_loadu_ps(p + 16);
    a = VFloat(_mm512_permutex2var_ps(
        a0, _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30), a1));
    b = VFloat(_mm512_permutex2var_ps(
        a0, _mm512_setr_epi32(1, 3, 5, 7, 9, 11, 13, 15, 17, 19, 21, 23, 25, 27, 29, 31), a1));
#elif defined(DEJAG_SIMD_LEVEL_scalar)
    a = p[0], b = p[1];
#else
    // Per 128-bit half the even and odd floats of both loads (a0 a1 a4 a5 | a2 a3 a6 a7), then the
    // 64-bit quarters in order.
    const __m256 p0 = _mm256_loadu_ps(p), p1 = _mm256_loadu_ps(p + 8);
    a = VFloat(_mm256_castpd_ps(_mm256_permute4x64_pd(
        _mm256_castps_pd(_mm256_shuffle_ps(p0, p1, _MM_SHUFFLE(2, 0, 2, 0))), _MM_SHUFFLE(3, 1, 2, 0))));
    b = VFloat(_mm256_castpd_ps(_mm256_permute4x64_pd(
        _mm256_castps_pd(_mm256_shuffle_ps(p0, p1, _MM_SHUFFLE(3, 1, 3, 1))), _MM_SHUFFLE(3, 1, 2, 0))));
#endif
}

// `count` pixels of an interleaved 2-channel row (motion vectors) split into two planes.
inline void splitPairs(const float* p, float* a, float* b, int count) {
    int x = 0;
    for (; x + kFloatLanes <= count; x += kFloatLanes) {
        VFloat va, vb;
        loadPairs(p + 2 * x, va, vb);
        storeu(a + x, va), storeu(b + x, vb);
    }
    for (; x < count; ++x) a[x] = p[2 * x], b[x] = p[2 * x + 1];
}

// R, G, B of an interleaved frame (`channels` floats per pixel, rows `width` pixels) read bilinearly at
// pixel coordinates (x, y) of the lanes (pixel (i, j)'s centre at (i + 0.5, j + 0.5)), clamp to edge as a
// texture unit does; x and y must be within the int range.
inline void bilinearRgb(const float* frame, int width, int height, int channels, VFloat x, VFloat y,
                        VFloat rgb[3]) {
    const VFloat fx = x - 0.5f, fy = y - 0.5f;
    const VInt x0 = floorToInt(fx), y0 = floorToInt(fy);
    const VFloat tx = fx - toFloat(x0), ty = fy - toFloat(y0);
    const VInt zero = splatInt(0), lastX = splatInt(width - 1), lastY = splatInt(height - 1);
    const VInt xa = vclamp(x0, zero, lastX), xb = vclamp(x0 + 1, zero, lastX);
    const VInt ra = vclamp(y0, zero, lastY) * splatInt(width),
               rb = vclamp(y0 + 1, zero, lastY) * splatInt(width);
    const VInt stride = splatInt(channels);
    const VInt ia = (ra + xa) * stride, ib = (ra + xb) * stride;
    const VInt ic = (rb + xa) * stride, id = (rb + xb) * stride;
    for (int k = 0; k < 3; ++k) {
        const float* base = frame + k;
        const VFloat pa = gather(base, ia), pb = gather(base, ib);
        const VFloat pc = gather(base, ic), pd = gather(base, id);
        const VFloat top = pa + tx * (pb - pa), bottom = pc + tx * (pd - pc);
        rgb[k] = top + ty * (bottom - top);
    }
}

}  // namespace dejag::DEJAG_SIMD_NAMESPACE

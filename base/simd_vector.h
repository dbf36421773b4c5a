// dejag/base: the vector type of the SIMD level being compiled. Include only from kernel sources built
// with dejag_add_simd_kernels(); each copy of such a source sees its own width.
//
// VFloat is a GCC vector of kFloatLanes floats (plain float on the scalar path), so one kernel body
// written with +, -, *, / and the helpers below serves every level; FMA contraction comes from the
// per-level flags (-ffp-contract=fast).
#pragma once

#include <array>
#include <cstdint>
#include <cstring>
#include <utility>

#if !defined(DEJAG_SIMD_LEVEL_scalar)
#include <immintrin.h>
#endif

#if !defined(DEJAG_SIMD_NAMESPACE)
#error "simd_vector.h is for kernel sources compiled by dejag_add_simd_kernels()"
#endif

namespace dejag::DEJAG_SIMD_NAMESPACE {

#if defined(DEJAG_SIMD_LEVEL_avx512)
inline constexpr int kFloatLanes = 16;
#elif defined(DEJAG_SIMD_LEVEL_avx2)
inline constexpr int kFloatLanes = 8;
#else
inline constexpr int kFloatLanes = 1;
#endif

#if defined(DEJAG_SIMD_LEVEL_scalar)
using VFloat = float;
#else
typedef float VFloat __attribute__((vector_size(kFloatLanes * sizeof(float))));
#endif

template <class V>
inline V loadu(const float* p) {
    V v;
    std::memcpy(&v, p, sizeof(V));
    return v;
}

template <class V>
inline void storeu(float* p, V v) {
    std::memcpy(p, &v, sizeof(V));
}

// Broadcast, through the set1 intrinsic so a value loaded from memory becomes one vbroadcastss from
// that address. (Not V{} + s: adding +0.0 is not an identity for -0.0, so the compiler keeps the add.)
template <class V>
inline V splat(float s) {
    if constexpr (sizeof(V) == sizeof(float)) {
        return s;
#if defined(DEJAG_SIMD_LEVEL_avx512)
    } else if constexpr (sizeof(V) == 64) {
        return V(_mm512_set1_ps(s));
#endif
#if defined(DEJAG_SIMD_LEVEL_avx2) || defined(DEJAG_SIMD_LEVEL_avx512)
    } else if constexpr (sizeof(V) == 32) {
        return V(_mm256_set1_ps(s));
#endif
    } else {
        V v;
        for (int i = 0; i < int(sizeof(V) / sizeof(float)); ++i) v[i] = s;
        return v;
    }
}

// Sum of the lanes, in a fixed order (deterministic).
inline float horizontalSum(float v) {
    return v;
}
#if !defined(DEJAG_SIMD_LEVEL_scalar)
inline float horizontalSum(VFloat v) {
    float lanes[kFloatLanes];
    std::memcpy(lanes, &v, sizeof(v));
    float sum = 0.0f;
    for (int i = 0; i < kFloatLanes; ++i) sum += lanes[i];
    return sum;
}
#endif

#if !defined(DEJAG_SIMD_LEVEL_scalar)
// Lanes Index[0..kFloatLanes) of the concatenation a ++ b (a shuffle with constant indices, GCC and Clang
// alike).
template <const auto& Index, size_t... I>
inline VFloat shuffleTwo(VFloat a, VFloat b, std::index_sequence<I...>) {
    return __builtin_shufflevector(a, b, Index[I]...);
}
template <const auto& Index>
inline VFloat shuffleTwo(VFloat a, VFloat b) {
    return shuffleTwo<Index>(a, b, std::make_index_sequence<kFloatLanes>());
}

namespace interleave_detail {
constexpr int N = kFloatLanes;
using Lanes = std::array<int32_t, kFloatLanes>;
// Two channels' lanes alternated, from lane `from` of each: a0 b0 a1 b1 ...
constexpr Lanes pairs(int from) {
    Lanes index{};
    for (int i = 0; i < N; ++i) index[size_t(i)] = (i % 2 ? N : 0) + from + i / 2;
    return index;
}
// Two such pair vectors' pairs alternated, from pair `from` of each: a0 b0 c0 d0 a1 b1 c1 d1 ...
constexpr Lanes quads(int from) {
    Lanes index{};
    for (int i = 0; i < N; ++i) {
        const int pair = i / 2;
        index[size_t(i)] = (pair % 2 ? N : 0) + 2 * (from + pair / 2) + i % 2;
    }
    return index;
}
// Three channels: output vector k's lanes of channels 0 and 1 (first shuffle), then channel 2's.
constexpr Lanes triplesFirst(int k) {
    Lanes index{};
    for (int i = 0; i < N; ++i) {
        const int g = k * N + i, pixel = g / 3, channel = g % 3;
        index[size_t(i)] = channel == 0 ? pixel : channel == 1 ? N + pixel : 0;
    }
    return index;
}
constexpr Lanes triplesSecond(int k) {
    Lanes index{};
    for (int i = 0; i < N; ++i) {
        const int g = k * N + i, pixel = g / 3, channel = g % 3;
        index[size_t(i)] = channel == 2 ? N + pixel : i;
    }
    return index;
}
inline constexpr Lanes kPairsLow = pairs(0), kPairsHigh = pairs(N / 2);
inline constexpr Lanes kQuads[2] = {quads(0), quads(N / 4)};
inline constexpr Lanes kTriplesFirst[3] = {triplesFirst(0), triplesFirst(1), triplesFirst(2)};
inline constexpr Lanes kTriplesSecond[3] = {triplesSecond(0), triplesSecond(1), triplesSecond(2)};
}  // namespace interleave_detail

// The lanes of C = 3 or 4 channel vectors stored as kFloatLanes pixels of C floats each (p[C l + c] =
// v[c][l]): two shuffles per vector stored.
template <int C>
inline void storeInterleaved(float* p, const VFloat* v) {
    using namespace interleave_detail;
    static_assert(C == 3 || C == 4, "3 or 4 channels");
    if constexpr (C == 4) {
        const VFloat ab[2] = {shuffleTwo<kPairsLow>(v[0], v[1]), shuffleTwo<kPairsHigh>(v[0], v[1])};
        const VFloat cd[2] = {shuffleTwo<kPairsLow>(v[2], v[3]), shuffleTwo<kPairsHigh>(v[2], v[3])};
        for (int h = 0; h < 2; ++h) {
            storeu(p + (2 * h) * N, shuffleTwo<kQuads[0]>(ab[h], cd[h]));
            storeu(p + (2 * h + 1) * N, shuffleTwo<kQuads[1]>(ab[h], cd[h]));
        }
    } else {
        storeu(p, shuffleTwo<kTriplesSecond[0]>(shuffleTwo<kTriplesFirst[0]>(v[0], v[1]), v[2]));
        storeu(p + N, shuffleTwo<kTriplesSecond[1]>(shuffleTwo<kTriplesFirst[1]>(v[0], v[1]), v[2]));
        storeu(p + 2 * N, shuffleTwo<kTriplesSecond[2]>(shuffleTwo<kTriplesFirst[2]>(v[0], v[1]), v[2]));
    }
}
#endif
template <int C>
inline void storeInterleaved(float* p, const float* v) {
    for (int c = 0; c < C; ++c) p[c] = v[c];
}

}  // namespace dejag::DEJAG_SIMD_NAMESPACE

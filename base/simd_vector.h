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
#endif

}  // namespace dejag::DEJAG_SIMD_NAMESPACE

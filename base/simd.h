// dejag/base: which SIMD instruction set the hot kernels run with.
//
// Kernels are compiled once per level (cmake/DejagSimd.cmake) into dejag::simd_scalar, simd_avx2 and
// simd_avx512. The active level is the best the CPU and OS support, lowered by the environment variable
// DEJAG_SIMD=scalar|avx2|avx512 or by setSimdLevel() (tests force each path this way). Asking for a
// level the CPU lacks is an error, never a silent fallback.
#pragma once

#include <optional>
#include <string_view>

namespace dejag {

enum class SimdLevel { Scalar = 0, Avx2 = 1, Avx512 = 2 };

SimdLevel cpuSimdLevel();            // best level this CPU and OS can run
SimdLevel activeSimdLevel();         // level the kernels use now
void setSimdLevel(SimdLevel level);  // throws dejag::Error if the CPU lacks it
const char* simdLevelName(SimdLevel level);
std::optional<SimdLevel> parseSimdLevel(std::string_view name);
int simdFloatLanes(SimdLevel level);  // 1, 8 or 16
// AVX-512 BF16 (vdpbf16ps: two bf16 products per float lane): the CPU has it and the active level is
// avx512. Inference may then run its convolutions on bf16 activations (nn/inference.h).
bool bf16Available();

}  // namespace dejag

// Calls the kernel `fn` of the active SIMD level: DEJAG_SIMD_CALL(ssimBand, args).
#define DEJAG_SIMD_CALL(fn, ...)                     \
    ([&]() {                                         \
        switch (::dejag::activeSimdLevel()) {        \
            case ::dejag::SimdLevel::Avx512:         \
                return simd_avx512::fn(__VA_ARGS__); \
            case ::dejag::SimdLevel::Avx2:           \
                return simd_avx2::fn(__VA_ARGS__);   \
            default:                                 \
                return simd_scalar::fn(__VA_ARGS__); \
        }                                            \
    }())

// Declares the same kernel signatures in the three per-level namespaces.
#define DEJAG_SIMD_DECLARE(declarations) \
    namespace simd_scalar {              \
    declarations                         \
    }                                    \
    namespace simd_avx2 {                \
    declarations                         \
    }                                    \
    namespace simd_avx512 {              \
    declarations                         \
    }

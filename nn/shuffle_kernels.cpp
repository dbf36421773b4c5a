#include "nn/shuffle_kernels.h"

#include "base/simd_vector.h"

namespace dejag::nn::DEJAG_SIMD_NAMESPACE {
using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

bool shuffleRow(const ShuffleRowArgs& a) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    constexpr int L = 16;
    const __mmask16 zeroMask = __mmask16(((1u << a.valid) - 1) & ~((1u << a.from) - 1));  // the shuffle's
    const __mmask16 storeMask = __mmask16(0xFFFFu & ~((1u << a.from) - 1));               // from .. 15
    __m512i index[16];
    for (int j = 0; j < a.factor; ++j) index[j] = _mm512_loadu_si512(a.lane[j]);
    if (a.bf16) {
        // Both source blocks in one vector of 32 bf16 lanes (the second block by a masked load into the
        // upper half), one vpermw, a masked store of the lower 16.
        const auto* source = static_cast<const uint16_t*>(a.source);
        auto* out = static_cast<uint16_t*>(a.out);
        __m512i wordIndex[16];
        for (int j = 0; j < a.factor; ++j) {
            int16_t words[32] = {};
            for (int l = 0; l < L; ++l) words[l] = int16_t(a.lane[j][l]);
            wordIndex[j] = _mm512_loadu_si512(words);
        }
        const uint16_t* pixel = source;  // source pixel x / factor, column phase j = x % factor
        for (int64_t x = 0, j = 0; x < a.width; ++x) {
            __m512i both = _mm512_maskz_loadu_epi16(0x0000FFFFu, pixel + a.firstBlock[j] * a.blockStride);
            both = _mm512_mask_loadu_epi16(both, 0xFFFF0000u, pixel + a.secondBlock[j] * a.blockStride - L);
            const __m512i permuted = _mm512_maskz_permutexvar_epi16(__mmask32(zeroMask), wordIndex[j], both);
            _mm512_mask_storeu_epi16(out + x * L, __mmask32(storeMask), permuted);
            if (++j == a.factor) j = 0, pixel += L;
        }
        return true;
    }
    const auto* source = static_cast<const float*>(a.source);
    auto* out = static_cast<float*>(a.out);
    const float* pixel = source;  // source pixel x / factor, column phase j = x % factor
    for (int64_t x = 0, j = 0; x < a.width; ++x) {
        const __m512 permuted =
            _mm512_maskz_permutex2var_ps(zeroMask, _mm512_loadu_ps(pixel + a.firstBlock[j] * a.blockStride),
                                         index[j], _mm512_loadu_ps(pixel + a.secondBlock[j] * a.blockStride));
        _mm512_mask_storeu_ps(out + x * L, storeMask, permuted);
        if (++j == a.factor) j = 0, pixel += L;
    }
    return true;
#elif defined(DEJAG_SIMD_LEVEL_avx2)
    constexpr int L = 8;
    if (a.bf16) return false;
    __m256i index[16], fromSecond[16];
    int32_t keep[L], store[L];
    for (int l = 0; l < L; ++l)
        keep[l] = l >= a.from && l < a.valid ? -1 : 0, store[l] = l >= a.from ? -1 : 0;
    const __m256i keepMask = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(keep));
    const __m256i storeMask = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(store));
    for (int j = 0; j < a.factor; ++j) {
        index[j] = _mm256_loadu_si256(reinterpret_cast<const __m256i*>(a.lane[j]));
        fromSecond[j] = _mm256_cmpgt_epi32(index[j], _mm256_set1_epi32(L - 1));
    }
    const auto* source = static_cast<const float*>(a.source);
    auto* out = static_cast<float*>(a.out);
    const float* pixel = source;  // source pixel x / factor, column phase j = x % factor
    for (int64_t x = 0, j = 0; x < a.width; ++x) {
        const __m256 first =
            _mm256_permutevar8x32_ps(_mm256_loadu_ps(pixel + a.firstBlock[j] * a.blockStride), index[j]);
        const __m256 second =
            _mm256_permutevar8x32_ps(_mm256_loadu_ps(pixel + a.secondBlock[j] * a.blockStride), index[j]);
        const __m256 value =
            _mm256_and_ps(_mm256_blendv_ps(first, second, _mm256_castsi256_ps(fromSecond[j])),
                          _mm256_castsi256_ps(keepMask));
        _mm256_maskstore_ps(out + x * L, storeMask, value);
        if (++j == a.factor) j = 0, pixel += L;
    }
    return true;
#else
    (void)a;
    return false;
#endif
}

}  // namespace dejag::nn::DEJAG_SIMD_NAMESPACE

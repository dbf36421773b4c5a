// Register-blocked direct convolution micro-kernels (see nn/fast_conv.h), compiled once per SIMD level.
#include "nn/fast_conv_kernels.h"

#include <algorithm>
#include <array>
#include <cstdint>
#include <utility>

#include "base/error.h"
#include "base/simd_vector.h"

namespace dejag::nn::DEJAG_SIMD_NAMESPACE {
using namespace ::dejag::DEJAG_SIMD_NAMESPACE;  // VFloat, kFloatLanes, loadu, storeu, splat
namespace {

constexpr int B = kFloatLanes;  // channels per block = floats per vector
// Tile: TW output pixels x CB output channel blocks, TW * CB accumulators in registers.
#if defined(DEJAG_SIMD_LEVEL_avx512)
constexpr int kTileWidth = 12, kTileBlocks = 2;  // 24 zmm accumulators + 2 weights of 32 registers
#elif defined(DEJAG_SIMD_LEVEL_avx2)
constexpr int kTileWidth = 6, kTileBlocks = 2;  // 12 ymm accumulators + 2 weights + 1 broadcast of 16
#else
constexpr int kTileWidth = 4, kTileBlocks = 1;
#endif
constexpr int kNarrowMaxChannels = 4;  // the narrow kernel's output channels (see below)

template <Activation Kind>
inline VFloat activate(VFloat v, const ActivationDesc& a) {
    if constexpr (Kind == Activation::ReLU) {
        return v > 0.0f ? v : splat<VFloat>(0.0f);
    } else if constexpr (Kind == Activation::LeakyReLU) {
        return v > 0.0f ? v : v * a.slope;
    } else if constexpr (Kind == Activation::Clamp) {
        v = v < a.low ? splat<VFloat>(a.low) : v;
        return v > a.high ? splat<VFloat>(a.high) : v;
    } else {
        return v;
    }
}

// The activation chosen at run time; a predictable branch per vector (a lambda or template per kind
// would let the accumulators' address escape, and GCC would then keep them in memory).
[[gnu::always_inline]] inline VFloat applyActivation(VFloat v, const ActivationDesc& a) {
    switch (a.kind) {
        case Activation::ReLU:
            return activate<Activation::ReLU>(v, a);
        case Activation::LeakyReLU:
            return activate<Activation::LeakyReLU>(v, a);
        case Activation::Clamp:
            return activate<Activation::Clamp>(v, a);
        default:
            return v;
    }
}

inline VFloat maximum(VFloat a, VFloat b) {
    return a > b ? a : b;
}

// What every tile of one lattice row shares, computed once per row.
struct RowContext {
    const float* in = nullptr;         // input pixel of lattice column 0, channel block 0
    const uint16_t* inBf16 = nullptr;  // the same, for a bf16 input
    int64_t inRowStep = 0;             // floats from one lattice row's input pixel to the next (pooling)
    int64_t inBlockStride = 0;         // floats per input channel block
    int64_t inPixelStep = 0;           // floats between the input pixels of neighbouring lattice columns
    int64_t cinBlocks = 0;
    int lastBlockChannels = 0;  // channels in the last input block
    int taps = 0;
    const int64_t* tapOffsets = nullptr;
    const float* weights = nullptr;
    const float* narrowWeights = nullptr;
    const uint16_t* pairWeights = nullptr;
    int64_t weightBlockStride = 0;  // floats of packed weights per output channel block
    const float* bias = nullptr;
    ActivationDesc activation;
    float* out = nullptr;         // output pixel of lattice column 0 (pooled column 0 when pooling), block 0
    uint16_t* outBf16 = nullptr;  // the same, for a bf16 output
    int64_t outBlockStride = 0;
    int64_t outPixelStep = 0;
    VFloat narrowBias{};
    bool streamWide = false;  // the wide kernel streams its stores (a large output)
};

RowContext rowContext(const ConvRowsArgs& a, int64_t r) {
    const BlockedShape& is = a.inShape;
    const BlockedShape& os = a.outShape;
    const ConvPass& p = a.pass;
    RowContext c;
    const int64_t convRow = a.pool2x2 ? 2 * r : r;
    const int64_t inOffset = is.offset(a.image, 0, p.inY0 + convRow * p.inStepY, p.inX0);
    if (a.inBf16)
        c.inBf16 = reinterpret_cast<const uint16_t*>(a.in) + inOffset;
    else
        c.in = a.in + inOffset;
    c.inRowStep = p.inStepY * is.rowStride();
    c.inBlockStride = is.planeStride();
    c.inPixelStep = p.inStepX * is.block;
    c.cinBlocks = is.channelBlocks();
    c.lastBlockChannels = int(is.channels - (c.cinBlocks - 1) * is.block);
    c.taps = p.taps;
    c.tapOffsets = p.tapOffsets;
    c.weights = p.weights;
    c.narrowWeights = p.narrowWeights;
    c.pairWeights = p.pairWeights;
    c.weightBlockStride = c.cinBlocks * p.taps * is.block * B;
    c.bias = a.bias;
    c.activation = a.activation;
    const int64_t outOffset =
        a.pool2x2 ? os.offset(a.image, 0, r, 0) : os.offset(a.image, 0, p.outY0 + r * p.outStepY, p.outX0);
    if (a.outBf16)
        c.outBf16 = reinterpret_cast<uint16_t*>(a.out) + outOffset;
    else
        c.out = a.out + outOffset;
    c.outPixelStep = a.pool2x2 ? B : p.outStepX * B;
    c.outBlockStride = os.planeStride();
    if (os.block < B) c.outPixelStep = os.block;  // compact narrow output (unit output step only)
    // The narrow kernel's bias, laid out like its reduced sums: lane k holds output channel k % Cout.
    if (p.narrowWeights) {
        float lanes[B] = {};
        for (int64_t k = 0; k < B / os.channels * os.channels; ++k) lanes[k] = a.bias[k % os.channels];
        c.narrowBias = loadu<VFloat>(lanes);
    }
    return c;
}

// A store that bypasses the caches (p aligned to the vector). Over a large frame an output's lines are
// not read again before they leave the cache, and reading them first (write-allocate) would add half
// again to a layer's memory traffic (a 1080p activation of 16 channels: 133 MB).
inline void streamStore(float* p, VFloat v) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    _mm512_stream_ps(p, __m512(v));
#elif defined(DEJAG_SIMD_LEVEL_avx2)
    _mm256_stream_ps(p, __m256(v));
#else
    *p = v;
#endif
}

inline void storeFence() {
#if !defined(DEJAG_SIMD_LEVEL_scalar)
    _mm_sfence();  // streamed stores are visible before the work item ends
#endif
}

// Outputs larger than a.streamBytes as stored (bf16 or float) are streamed past the caches.
inline bool largeOutput(const ConvRowsArgs& a) {
    const int64_t bytes = a.outBf16 ? int64_t(sizeof(uint16_t)) : int64_t(sizeof(float));
    return a.outShape.batch * a.outShape.imageStride() * bytes > a.streamBytes;
}

// ---- The wide kernel: lanes = output channels ------------------------------------------------------

// Accumulates TW lattice columns from column j (input row `in`) for CB output blocks from cob.
// BI: channels per input block (B, or 1 for a planar input); UNIT: the lattice's input step is 1 pixel,
// so every pixel offset is a compile-time constant.
template <int TW, int CB, int BI, bool UNIT>
[[gnu::always_inline]] inline void accumulateWide(const RowContext& c, const float* in, int64_t cob,
                                                  int64_t j, VFloat (&acc)[CB][TW]) {
    const int64_t step = UNIT ? BI : c.inPixelStep;
    for (int b = 0; b < CB; ++b) {
        const VFloat bias = loadu<VFloat>(c.bias + (cob + b) * B);
        for (int i = 0; i < TW; ++i) acc[b][i] = bias;
    }
    const float* weights = c.weights + cob * c.weightBlockStride;
    for (int64_t cib = 0; cib < c.cinBlocks; ++cib) {
        const int channels = cib + 1 < c.cinBlocks ? BI : c.lastBlockChannels;
        const float* base = in + cib * c.inBlockStride + j * step;
        const float* w = weights + cib * c.taps * BI * B;
        for (int t = 0; t < c.taps; ++t, w += BI * B) {
            const float* pixels = base + c.tapOffsets[t];
            auto accumulateChannel = [&](int ci) {
                VFloat weight[CB];
                for (int b = 0; b < CB; ++b) weight[b] = loadu<VFloat>(w + b * c.weightBlockStride + ci * B);
#pragma GCC unroll 16
                for (int i = 0; i < TW; ++i) {
                    const VFloat value = splat<VFloat>(pixels[i * step + ci]);
                    for (int b = 0; b < CB; ++b) acc[b][i] += value * weight[b];
                }
            };
            if constexpr (BI == 1) {
                accumulateChannel(0);
            } else if (channels == BI) {
#pragma GCC unroll 4
                for (int ci = 0; ci < BI; ++ci) accumulateChannel(ci);
            } else {
                // A partial last block (e.g. 3 RGB channels): skip the zero channels.
                for (int ci = 0; ci < channels; ++ci) accumulateChannel(ci);
            }
        }
    }
}

// bf16 activations: AVX-512 BF16's vdpbf16ps multiplies a pair of bf16 values in each 32-bit lane and
// adds both products to a float lane, so one instruction does two input channels' multiply-adds for 16
// output channels (twice a float FMA's work at the same throughput on Zen 4 and Zen 5).
#if defined(DEJAG_SIMD_LEVEL_avx512)
inline constexpr bool kBf16Kernels = true;
#else
inline constexpr bool kBf16Kernels = false;
#endif

// The bf16 variant of accumulateWide: TW lattice columns of a bf16 input in blocks of B channels,
// input channels taken in pairs (the weights are ConvPass::pairWeights).
template <int TW, int CB, bool UNIT>
[[gnu::always_inline]] inline void accumulateWidePairs(const RowContext& c, const uint16_t* in, int64_t cob,
                                                       int64_t j, VFloat (&acc)[CB][TW]) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    const int64_t step = UNIT ? B : c.inPixelStep;
    for (int b = 0; b < CB; ++b) {
        const VFloat bias = loadu<VFloat>(c.bias + (cob + b) * B);
        for (int i = 0; i < TW; ++i) acc[b][i] = bias;
    }
    __m512 sums[CB][TW];
    for (int b = 0; b < CB; ++b)
        for (int i = 0; i < TW; ++i) sums[b][i] = __m512(acc[b][i]);
    const uint16_t* weights = c.pairWeights + cob * c.weightBlockStride;
    for (int64_t cib = 0; cib < c.cinBlocks; ++cib) {
        const int channels = cib + 1 < c.cinBlocks ? B : c.lastBlockChannels;
        const uint16_t* base = in + cib * c.inBlockStride + j * step;
        const uint16_t* w = weights + cib * c.taps * B * B;
        for (int t = 0; t < c.taps; ++t, w += B * B) {
            const uint16_t* pixels = base + c.tapOffsets[t];
            auto accumulatePair = [&](int pair) {
                __m512bh weight[CB];
                for (int b = 0; b < CB; ++b)
                    weight[b] = __m512bh(_mm512_loadu_si512(w + b * c.weightBlockStride + pair * 2 * B));
#pragma GCC unroll 16
                for (int i = 0; i < TW; ++i) {
                    int32_t bits;
                    std::memcpy(&bits, pixels + i * step + 2 * pair, sizeof(bits));
                    const __m512bh value = __m512bh(_mm512_set1_epi32(bits));
                    for (int b = 0; b < CB; ++b) sums[b][i] = _mm512_dpbf16_ps(sums[b][i], value, weight[b]);
                }
            };
            if (channels == B) {
#pragma GCC unroll 8
                for (int pair = 0; pair < B / 2; ++pair) accumulatePair(pair);
            } else {
                for (int pair = 0; pair < (channels + 1) / 2; ++pair) accumulatePair(pair);
            }
        }
    }
    for (int b = 0; b < CB; ++b)
        for (int i = 0; i < TW; ++i) acc[b][i] = VFloat(sums[b][i]);
#else
    (void)c, (void)in, (void)cob, (void)j, (void)acc;
#endif
}

// B floats rounded to bf16 (nearest even) and stored as B uint16_t (a streamed store when asked: the
// pixel's 32 bytes are aligned in a bf16 blocked tensor whose planes are 64-byte aligned).
inline void storeBf16(uint16_t* p, VFloat v, bool stream) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    const __m256i bits = __m256i(_mm512_cvtneps_pbh(__m512(v)));
    if (stream)
        _mm256_stream_si256(reinterpret_cast<__m256i*>(p), bits);
    else
        _mm256_storeu_si256(reinterpret_cast<__m256i*>(p), bits);
#else
    (void)p, (void)v, (void)stream;
#endif
}

// The output type is a run-time branch per tile (a template parameter would double the instantiations,
// and the compile time, of every tile below).
template <int TW, int CB>
[[gnu::always_inline]] inline void storeWide(const RowContext& c, int64_t cob, int64_t j,
                                             const VFloat (&acc)[CB][TW]) {
    const ActivationDesc activation = c.activation;
    for (int b = 0; b < CB; ++b) {
        const int64_t offset = (cob + b) * c.outBlockStride + j * c.outPixelStep;
        if (kBf16Kernels && c.outBf16) {
            uint16_t* out = c.outBf16 + offset;
            for (int i = 0; i < TW; ++i)
                storeBf16(out + i * c.outPixelStep, applyActivation(acc[b][i], activation), c.streamWide);
        } else if (float* out = c.out + offset; c.streamWide) {
            for (int i = 0; i < TW; ++i)
                streamStore(out + i * c.outPixelStep, applyActivation(acc[b][i], activation));
        } else {
            for (int i = 0; i < TW; ++i)
                storeu(out + i * c.outPixelStep, applyActivation(acc[b][i], activation));
        }
    }
}

// INB: a bf16 input (BI == B).
template <int TW, int CB, int BI, bool UNIT, bool POOL, bool INB>
void wideTile(const RowContext& c, int64_t cob, int64_t j) {
    auto accumulate = [&](int64_t rowOffset, VFloat(&sums)[CB][TW]) {
        if constexpr (INB)
            accumulateWidePairs<TW, CB, UNIT>(c, c.inBf16 + rowOffset, cob, j, sums);
        else
            accumulateWide<TW, CB, BI, UNIT>(c, c.in + rowOffset, cob, j, sums);
    };
    VFloat acc[CB][TW];
    accumulate(0, acc);
    if constexpr (!POOL) {
        storeWide<TW, CB>(c, cob, j, acc);
    } else if constexpr (TW >= 2) {
        // 2x2 max pooling of lattice rows 2r, 2r + 1 and columns j..j + TW (j and TW even). The
        // activations dejag fuses are monotonic, so pooling before them equals pooling after.
        VFloat below[CB][TW];
        accumulate(c.inRowStep, below);
        VFloat pooled[CB][TW / 2];
        for (int b = 0; b < CB; ++b)
            for (int i = 0; i < TW / 2; ++i)
                pooled[b][i] = maximum(maximum(acc[b][2 * i], acc[b][2 * i + 1]),
                                       maximum(below[b][2 * i], below[b][2 * i + 1]));
        storeWide<TW / 2, CB>(c, cob, j / 2, pooled);
    }
}

using TileFunction = void (*)(const RowContext&, int64_t, int64_t);

// Row remainders: tiles of 1..kTileWidth-1 columns, chosen through a table of instantiations.
template <int CB, int BI, bool UNIT, bool POOL, bool INB, size_t... I>
constexpr auto makeWideTails(std::index_sequence<I...>) {
    return std::array<TileFunction, sizeof...(I)>{&wideTile<int(I) + 1, CB, BI, UNIT, POOL, INB>...};
}

// Lattice columns [first, columns) of one row.
template <int CB, int BI, bool UNIT, bool POOL, bool INB>
void wideRow(const RowContext& c, int64_t cob, int64_t columns, int64_t first = 0) {
    static constexpr auto tails =
        makeWideTails<CB, BI, UNIT, POOL, INB>(std::make_index_sequence<kTileWidth - 1>());
    int64_t j = first;
    for (; j + kTileWidth <= columns; j += kTileWidth)
        wideTile<kTileWidth, CB, BI, UNIT, POOL, INB>(c, cob, j);
    if (j < columns) tails[size_t(columns - j - 1)](c, cob, j);
}

template <int BI, bool UNIT, bool POOL, bool INB>
void wideRows(const ConvRowsArgs& a) {
    // Pooling reads lattice columns in pairs; an odd last column has no pooled output.
    const int64_t columns = POOL ? a.pass.columns / 2 * 2 : a.pass.columns;
    const size_t alignment = a.outBf16 ? B * sizeof(uint16_t) : sizeof(VFloat);
    const bool stream =
        a.outShape.block == B && largeOutput(a) && reinterpret_cast<uintptr_t>(a.out) % alignment == 0;
    for (int64_t r = a.rowBegin; r < a.rowEnd; ++r) {
        RowContext c = rowContext(a, r);
        c.streamWide = stream;
        // The row's runs of columns to compute: all of them, or the kept groups.
        const uint8_t* keep = !POOL && a.keep ? a.keep + r * a.keepRowStride : nullptr;
        for (int64_t g = 0; g * (keep ? a.keepGroup : columns) < columns;) {
            int64_t first = 0, last = columns;
            if (keep) {
                while (g * a.keepGroup < columns && !keep[g]) ++g;
                const int64_t start = g;
                while (g * a.keepGroup < columns && keep[g]) ++g;
                if (start == g) break;
                first = start * a.keepGroup, last = std::min(columns, g * a.keepGroup);
            } else {
                g = 1;
            }
            int64_t cob = a.outBlockBegin;
            for (; cob + kTileBlocks <= a.outBlockEnd; cob += kTileBlocks)
                wideRow<kTileBlocks, BI, UNIT, POOL, INB>(c, cob, last, first);
            for (; cob < a.outBlockEnd; ++cob) wideRow<1, BI, UNIT, POOL, INB>(c, cob, last, first);
        }
    }
    if (stream) storeFence();
}

#if defined(DEJAG_SIMD_LEVEL_avx512)
// ---- Planar stride-2 layers: a network's first convolution on an RGB or grey frame -----------------
//
// The wide kernel gives such a layer one broadcast and one multiply-add per input channel and tap for
// each output pixel, with half its lanes idle when it has 8 outputs. Here the lanes are 16 output pixels
// of one output channel instead: a tap's 16 inputs (every other float of 31) are one permute of two
// loads, and each weight is a broadcast operand, so 8 outputs cost 8 multiply-adds per input channel
// and tap for 16 pixels (the wide kernel: 16). The 8 channel vectors are then transposed to pixels.
// Accumulation order and arithmetic are the wide kernel's: the results are bit for bit the same.
constexpr int kPlanarOutChannels = 8;

bool planarStride2Applies(const ConvRowsArgs& a) {
    return !a.pool2x2 && !a.inBf16 && a.inShape.block == 1 && a.inShape.channels <= 16 &&
           a.pass.inStepX == 2 && a.outShape.block == B && a.outShape.channels <= kPlanarOutChannels &&
           a.outBlockBegin == 0 && a.outBlockEnd == 1;
}

// rows[k] (k < 8) holds row k of an 8x8 block; cols[k] becomes its column k.
inline void transpose8x8(const __m256 (&rows)[8], __m256 (&cols)[8]) {
    __m256 t[8], u[8];
    for (int i = 0; i < 8; i += 2) {
        t[i] = _mm256_unpacklo_ps(rows[i], rows[i + 1]);
        t[i + 1] = _mm256_unpackhi_ps(rows[i], rows[i + 1]);
    }
    for (int i = 0; i < 8; i += 4)
        for (int k = 0; k < 2; ++k) {
            u[i + 2 * k] = _mm256_shuffle_ps(t[i + k], t[i + 2 + k], _MM_SHUFFLE(1, 0, 1, 0));
            u[i + 2 * k + 1] = _mm256_shuffle_ps(t[i + k], t[i + 2 + k], _MM_SHUFFLE(3, 2, 3, 2));
        }
    for (int k = 0; k < 4; ++k) {
        cols[k] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x20);
        cols[k + 4] = _mm256_permute2f128_ps(u[k], u[k + 4], 0x31);
    }
}

void planarStride2Rows(const ConvRowsArgs& a) {
    constexpr int K = kPlanarOutChannels;
    const int64_t columns = a.pass.columns, vectorColumns = columns / B * B;
    const size_t alignment = a.outBf16 ? B * sizeof(uint16_t) : sizeof(VFloat);
    const bool stream = largeOutput(a) && reinterpret_cast<uintptr_t>(a.out) % alignment == 0;
    const __m512i evens = _mm512_setr_epi32(0, 2, 4, 6, 8, 10, 12, 14, 16, 18, 20, 22, 24, 26, 28, 30);
    for (int64_t r = a.rowBegin; r < a.rowEnd; ++r) {
        RowContext c = rowContext(a, r);
        c.streamWide = stream;
        // Lanes K.. of every pixel: what the wide kernel computes there (no channel: bias, activation).
        const __m512 rest = __m512(applyActivation(loadu<VFloat>(c.bias), c.activation));
        for (int64_t j = 0; j < vectorColumns; j += B) {
            VFloat acc[K];
            for (int k = 0; k < K; ++k) acc[k] = splat<VFloat>(c.bias[k]);
            for (int64_t ci = 0; ci < c.cinBlocks; ++ci)
                for (int t = 0; t < c.taps; ++t) {
                    const float* p = c.in + ci * c.inBlockStride + c.tapOffsets[t] + 2 * j;
                    const VFloat v = VFloat(_mm512_permutex2var_ps(_mm512_loadu_ps(p), evens,
                                                                   _mm512_maskz_loadu_ps(0x7FFF, p + B)));
                    const float* w = c.weights + (ci * c.taps + t) * B;
#pragma GCC unroll 8
                    for (int k = 0; k < K; ++k) acc[k] += v * w[k];
                }
            __m256 low[K], high[K], lowPixels[K], highPixels[K];
            for (int k = 0; k < K; ++k) {
                const VFloat v = applyActivation(acc[k], c.activation);
                low[k] = __m256(__builtin_shufflevector(v, v, 0, 1, 2, 3, 4, 5, 6, 7));
                high[k] = __m256(__builtin_shufflevector(v, v, 8, 9, 10, 11, 12, 13, 14, 15));
            }
            transpose8x8(low, lowPixels);
            transpose8x8(high, highPixels);
            for (int i = 0; i < B; ++i) {
                const VFloat pixel =
                    VFloat(_mm512_insertf32x8(rest, i < K ? lowPixels[i] : highPixels[i - K], 0));
                const int64_t offset = (j + i) * c.outPixelStep;
                if (c.outBf16)
                    storeBf16(c.outBf16 + offset, pixel, stream);
                else if (stream)
                    streamStore(c.out + offset, pixel);
                else
                    storeu(c.out + offset, pixel);
            }
        }
        wideRow<1, 1, false, false, false>(c, 0, columns, vectorColumns);  // the last columns
    }
    if (stream) storeFence();
}
#endif

template <int BI, bool INB>
void wideRowsFor(const ConvRowsArgs& a) {
    const bool unit = a.pass.inStepX == 1;
    if (a.pool2x2) {
        // Fused pooling is for stride-1 Conv2D layers (see BlockedConv::fuseMaxPool2x2).
        unit ? wideRows<BI, true, true, INB>(a) : wideRows<BI, false, true, INB>(a);
    } else {
        unit ? wideRows<BI, true, false, INB>(a) : wideRows<BI, false, false, INB>(a);
    }
}

// ---- The narrow kernel: lanes = input channels, for layers with a few output channels ----------------
//
// With 1-4 output channels the wide kernel would leave 12-15 of 16 lanes idle. Here each accumulator
// holds one (pixel, output channel) pair's products across a block of input channels, and one transposed
// reduction at the end of the tile sums the lanes of all TW x COUT accumulators at once.
#if !defined(DEJAG_SIMD_LEVEL_scalar)

// Lane indices (into the concatenation a ++ b) that fold segments of S lanes in half: the `offset` half
// (0: first, S/2: second) of every segment of a, then of b.
template <int S>
constexpr std::array<int32_t, B> foldIndices(int offset) {
    std::array<int32_t, B> index{};
    constexpr int half = B / 2;
    for (int lane = 0; lane < B; ++lane) {
        const int position = lane % half, segment = position / (S / 2), k = position % (S / 2);
        index[size_t(lane)] = (lane < half ? 0 : B) + segment * S + offset + k;
    }
    return index;
}

template <int S>
inline constexpr std::array<int32_t, B> kFoldLow = foldIndices<S>(0);
template <int S>
inline constexpr std::array<int32_t, B> kFoldHigh = foldIndices<S>(S / 2);

template <int S>
inline VFloat fold(VFloat a, VFloat b) {
    return shuffleTwo<kFoldLow<S>>(a, b, std::make_index_sequence<B>()) +
           shuffleTwo<kFoldHigh<S>>(a, b, std::make_index_sequence<B>());
}

// v holds S vectors; returns the vector whose lane k is the sum of the lanes of v[k] (fixed order).
template <int S>
inline VFloat reduceLanes(VFloat* v) {
    if constexpr (S == 1) {
        return v[0];
    } else {
#pragma GCC unroll 16
        for (int k = 0; k < S / 2; ++k) v[k] = fold<S>(v[2 * k], v[2 * k + 1]);
        return reduceLanes<S / 2>(v);
    }
}

// For pixel i of a tile, the lanes of the reduced sums holding its COUT outputs (index B: a zero).
template <int COUT>
constexpr std::array<int32_t, B> pixelLanes(int i) {
    std::array<int32_t, B> lanes{};
    for (int lane = 0; lane < B; ++lane) lanes[size_t(lane)] = lane < COUT ? i * COUT + lane : B;
    return lanes;
}
template <int COUT, int I>
inline constexpr std::array<int32_t, B> kPixelLanes = pixelLanes<COUT>(I);

// Pixel I's COUT values (lanes 0..COUT-1, zeros elsewhere), activated, to its output.
template <int COUT, int I, bool STREAM>
inline void storePixel(const RowContext& c, int64_t j, VFloat sums, VFloat zero,
                       const ActivationDesc& activation) {
    const VFloat v = applyActivation(
        shuffleTwo<kPixelLanes<COUT, I>>(sums, zero, std::make_index_sequence<B>()), activation);
    if constexpr (STREAM)
        streamStore(c.out + (j + I) * c.outPixelStep, v);
    else
        storeu(c.out + (j + I) * c.outPixelStep, v);
}

// Keeps v in a register: GCC would otherwise fold a value used by several FMAs into each of them as a
// memory operand, one load per FMA, and this CPU's loads, not its FMAs, would then bound the kernel.
[[gnu::always_inline]] inline void inRegister(VFloat& v) {
    asm("" : "+v"(v));
}

// The reduced sums of G groups of PG pixels from column j: lane i * COUT + co of sums[g] holds pixel
// g * PG + i's output channel co, plus its bias. G = 2 halves the weight loads per FMA (the weights of a
// tap serve twice as many pixels) where the registers allow (G * PG * COUT accumulators).
template <int G, int PG, int COUT, bool UNIT>
[[gnu::always_inline]] inline void narrowSums(const RowContext& c, int64_t j, VFloat (&sums)[G]) {
    static_assert(PG * COUT <= B);
    const int64_t step = UNIT ? B : c.inPixelStep;
    VFloat acc[G][B];
#pragma GCC unroll 16
    for (int k = 0; k < B; ++k)
#pragma GCC unroll 2
        for (int g = 0; g < G; ++g) acc[g][k] = splat<VFloat>(0.0f);
    for (int64_t cib = 0; cib < c.cinBlocks; ++cib) {
        const float* base = c.in + cib * c.inBlockStride + j * step;
        const float* w = c.narrowWeights + cib * c.taps * COUT * B;  // [cib][tap][co][ci lanes]
        for (int t = 0; t < c.taps; ++t, w += COUT * B) {
            const float* pixels = base + c.tapOffsets[t];
            VFloat weight[COUT];
#pragma GCC unroll 4
            for (int co = 0; co < COUT; ++co) weight[co] = loadu<VFloat>(w + co * B);
#pragma GCC unroll 2
            for (int g = 0; g < G; ++g)
#pragma GCC unroll 16
                for (int i = 0; i < PG; ++i) {
                    VFloat value = loadu<VFloat>(pixels + (g * PG + i) * step);
                    inRegister(value);
#pragma GCC unroll 4
                    for (int co = 0; co < COUT; ++co) acc[g][i * COUT + co] += value * weight[co];
                }
        }
    }
#pragma GCC unroll 2
    for (int g = 0; g < G; ++g) sums[g] = reduceLanes<B>(acc[g]) + c.narrowBias;
}

// Output in the blocked layout: a whole vector per pixel (lanes 0..COUT-1, zeros after).
template <int TW, int COUT, bool UNIT, bool STREAM>
void narrowTile(const RowContext& c, int64_t j) {
    VFloat sum[1];
    narrowSums<1, TW, COUT, UNIT>(c, j, sum);
    const VFloat sums = sum[0];
    const VFloat zero = splat<VFloat>(0.0f);
    const ActivationDesc activation = c.activation;
    [&]<size_t... I>(std::index_sequence<I...>) {
        (storePixel<COUT, int(I), STREAM>(c, j, sums, zero, activation), ...);
    }
    (std::make_index_sequence<TW>());
}

// ---- Compact output: OB < B floats per pixel (OB = 1, 2 or 4 >= COUT), B / OB pixels per vector ----
//
// A 16 -> 3 layer at 1080p writes 133 MB in the blocked layout (a 64-byte vector per pixel) but 33 MB
// with 4 floats per pixel: the tile's reduced sums are moved to lanes i * OB + co and stored as one
// vector. For a network's last layer (its output is converted to planes next) and for `dejag bench nn`.

// Lane i * OB + co of the compact output <- lane i * COUT + co of the sums (index B: a zero).
template <int COUT, int OB>
constexpr std::array<int32_t, B> compactLanes() {
    std::array<int32_t, B> lanes{};
    for (int lane = 0; lane < B; ++lane) {
        const int i = lane / OB, co = lane % OB;
        lanes[size_t(lane)] = co < COUT ? i * COUT + co : B;
    }
    return lanes;
}
template <int COUT, int OB>
inline constexpr std::array<int32_t, B> kCompactLanes = compactLanes<COUT, OB>();

enum class CompactStore { Cached, Streamed, Partial };

// G groups of TW pixels (G > 1: TW = B / OB, whole vectors).
template <int G, int TW, int COUT, int OB, bool UNIT, CompactStore STORE>
void compactTile(const RowContext& c, int64_t j) {
    static_assert(TW * OB <= B && COUT <= OB && (G == 1 || TW * OB == B));
    VFloat sums[G];
    // Prefetch the input pixels below the lowest row this tile reads (for a 3x3 kernel, what the next
    // lattice row reads first): one thread alone then waits for memory far less (27 -> 22 ms for a
    // 16 -> 3 layer at 1080p on this machine).
    if constexpr (G > 1 && UNIT) {
        const float* ahead = c.in + j * B + 3 * c.inRowStep;
#pragma GCC unroll 16
        for (int i = 0; i < G * TW; ++i)
            _mm_prefetch(reinterpret_cast<const char*>(ahead + i * B), _MM_HINT_T1);
    }
    narrowSums<G, TW, COUT, UNIT>(c, j, sums);
#pragma GCC unroll 2
    for (int g = 0; g < G; ++g) {
        const VFloat v = shuffleTwo<kCompactLanes<COUT, OB>>(
            applyActivation(sums[g], c.activation), splat<VFloat>(0.0f), std::make_index_sequence<B>());
        float* out = c.out + (j + g * TW) * OB;
        if constexpr (STORE == CompactStore::Streamed) {
            streamStore(out, v);
        } else if constexpr (STORE == CompactStore::Cached) {
            storeu(out, v);
        } else {  // fewer pixels than a vector holds: the pixels after them are not this tile's
            float lanes[B];
            storeu(lanes, v);
            std::memcpy(out, lanes, size_t(TW * OB) * sizeof(float));
        }
    }
}

template <int COUT, int OB, bool UNIT, size_t... I>
constexpr auto makeCompactTiles(std::index_sequence<I...>) {
    return std::array<void (*)(const RowContext&, int64_t), sizeof...(I)>{
        &compactTile<1, int(I) + 1, COUT, OB, UNIT, CompactStore::Partial>...};
}

template <int COUT, int OB, bool UNIT, bool STREAM>
void compactRows(const ConvRowsArgs& a) {
    constexpr int width = B / OB;                                      // pixels per vector
    constexpr int groups = 2 * width * COUT <= 24 && B == 16 ? 2 : 1;  // vectors per tile (registers)
    static constexpr auto partial = makeCompactTiles<COUT, OB, UNIT>(std::make_index_sequence<width - 1>());
    constexpr CompactStore full = STREAM ? CompactStore::Streamed : CompactStore::Cached;
    const int64_t columns = a.pass.columns;
    for (int64_t r = a.rowBegin; r < a.rowEnd; ++r) {
        const RowContext c = rowContext(a, r);
        int64_t j = 0;
        if constexpr (STREAM) {  // streamed stores need aligned vectors: a partial tile up to the first
            const int64_t misaligned = int64_t(reinterpret_cast<uintptr_t>(c.out) / sizeof(float)) % B;
            const int64_t head = std::min<int64_t>(columns, misaligned ? (B - misaligned) / OB : 0);
            if (head > 0) partial[size_t(head - 1)](c, 0);  // aligned vector of output
            j = head;
        }
        for (; j + groups * width <= columns; j += groups * width)
            compactTile<groups, width, COUT, OB, UNIT, full>(c, j);
        for (; j + width <= columns; j += width) compactTile<1, width, COUT, OB, UNIT, full>(c, j);
        if (j < columns) partial[size_t(columns - j - 1)](c, j);
    }
    if constexpr (STREAM) storeFence();
}

template <int COUT, bool UNIT, size_t... I>
constexpr auto makeNarrowTiles(std::index_sequence<I...>) {
    return std::array<void (*)(const RowContext&, int64_t), sizeof...(I)>{
        &narrowTile<int(I) + 1, COUT, UNIT, false>...};
}

template <int COUT, bool UNIT, bool STREAM>
void narrowRows(const ConvRowsArgs& a) {
    constexpr int width = B / COUT;
    static constexpr auto tiles = makeNarrowTiles<COUT, UNIT>(std::make_index_sequence<width>());
    for (int64_t r = a.rowBegin; r < a.rowEnd; ++r) {
        const RowContext c = rowContext(a, r);
        int64_t j = 0;
        for (; j + width <= a.pass.columns; j += width) narrowTile<width, COUT, UNIT, STREAM>(c, j);
        if (j < a.pass.columns) tiles[size_t(a.pass.columns - j - 1)](c, j);
    }
    if constexpr (STREAM) storeFence();  // the streamed stores are visible before the work item ends
}

template <int COUT, bool UNIT>
void narrowRowsStreamedOrNot(const ConvRowsArgs& a) {
    const bool large = largeOutput(a);
    if (a.outShape.block < B) {  // compact (OB = 1, 2 or 4); pixels are a whole number of floats apart
        constexpr int OB = COUT == 1 ? 1 : COUT == 2 ? 2 : 4;
        const bool stream = large && reinterpret_cast<uintptr_t>(a.out) % (OB * sizeof(float)) == 0;
        stream ? compactRows<COUT, OB, UNIT, true>(a) : compactRows<COUT, OB, UNIT, false>(a);
        return;
    }
    const bool stream = large && reinterpret_cast<uintptr_t>(a.out) % sizeof(VFloat) == 0;
    stream ? narrowRows<COUT, UNIT, true>(a) : narrowRows<COUT, UNIT, false>(a);
}

template <bool UNIT>
void narrowRowsFor(const ConvRowsArgs& a) {
    switch (a.outShape.channels) {
        case 1:
            return narrowRowsStreamedOrNot<1, UNIT>(a);
        case 2:
            return narrowRowsStreamedOrNot<2, UNIT>(a);
        case 3:
            return narrowRowsStreamedOrNot<3, UNIT>(a);
        default:
            return narrowRowsStreamedOrNot<4, UNIT>(a);
    }
}
#endif

}  // namespace

void convForwardRows(const ConvRowsArgs& a) {
#if !defined(DEJAG_SIMD_LEVEL_scalar)
    if (a.pass.narrowWeights && !a.pool2x2 && a.inShape.block == B &&
        a.outShape.channels <= kNarrowMaxChannels) {
        a.pass.inStepX == 1 ? narrowRowsFor<true>(a) : narrowRowsFor<false>(a);
        return;
    }
#endif
    if (!kBf16Kernels && (a.inBf16 || a.outBf16))
        throw Error("convForwardRows: bf16 activations need AVX-512 BF16");
    if (a.inBf16 && (a.inShape.block != B || !a.pass.pairWeights))
        throw Error("convForwardRows: a bf16 input needs a blocked layout and pair weights");
    if (a.inBf16) wideRowsFor<B, kBf16Kernels>(a);
#if defined(DEJAG_SIMD_LEVEL_avx512)
    else if (planarStride2Applies(a))
        planarStride2Rows(a);
#endif
    else if (a.inShape.block == 1)
        wideRowsFor<1, false>(a);
    else
        wideRowsFor<B, false>(a);
}

int narrowMaxOutputChannels() {
#if defined(DEJAG_SIMD_LEVEL_scalar)
    return 0;
#else
    return kNarrowMaxChannels;
#endif
}

void convWeightGradient(const WeightGradArgs& a) {
    const ConvPass& p = a.pass;
    const int Bi = a.inShape.block;
    const int channelsInBlock = int(std::min<int64_t>(Bi, a.inShape.channels - a.inBlock * Bi));
    VFloat acc[B];
    for (int c = 0; c < B; ++c) acc[c] = splat<VFloat>(0.0f);
    const int64_t offset = p.tapOffsets[a.tap];
    const int64_t inPixelStep = p.inStepX * Bi, outPixelStep = p.outStepX * B;
    for (int64_t n = 0; n < a.inShape.batch; ++n)
        for (int64_t r = 0; r < p.rows; ++r) {
            const float* in = a.in + a.inShape.offset(n, a.inBlock, p.inY0 + r * p.inStepY, p.inX0) + offset;
            const float* g = a.dout + a.outShape.offset(n, a.outBlock, p.outY0 + r * p.outStepY, p.outX0);
            for (int64_t j = 0; j < p.columns; ++j, in += inPixelStep, g += outPixelStep) {
                const VFloat gradient = loadu<VFloat>(g);
                if (channelsInBlock == B) {
#pragma GCC unroll 16
                    for (int c = 0; c < B; ++c) acc[c] += splat<VFloat>(in[c]) * gradient;
                } else {
                    for (int c = 0; c < channelsInBlock; ++c) acc[c] += splat<VFloat>(in[c]) * gradient;
                }
            }
        }
    for (int c = 0; c < Bi; ++c) storeu(a.dw + c * B, acc[c]);
}

}  // namespace dejag::nn::DEJAG_SIMD_NAMESPACE

// Register-blocked direct convolution micro-kernels (see nn/fast_conv.h), compiled once per SIMD level.
#include "nn/fast_conv_kernels.h"

#include <algorithm>
#include <array>
#include <utility>

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

inline VFloat activate(VFloat v, const ActivationDesc& a) {
    switch (a.kind) {
        case Activation::ReLU:
            return v > 0.0f ? v : splat<VFloat>(0.0f);
        case Activation::LeakyReLU:
            return v > 0.0f ? v : v * a.slope;
        case Activation::Clamp: {
            v = v < a.low ? splat<VFloat>(a.low) : v;
            return v > a.high ? splat<VFloat>(a.high) : v;
        }
        default:
            return v;
    }
}

// One tile: TW lattice columns starting at column j of lattice row r, for CB output blocks from cob.
template <int TW, int CB>
inline void convTile(const ConvRowsArgs& a, int64_t cob, int64_t r, int64_t j) {
    const BlockedShape& is = a.inShape;
    const ConvPass& p = a.pass;
    const int Bi = is.block;  // input channels per block: B, or 1 for planar inputs of few channels
    const int64_t cinBlocks = is.channelBlocks();
    const int64_t weightBlockStride = cinBlocks * p.taps * Bi * B;  // floats per output channel block
    const int64_t inPixelStep = p.inStepX * Bi;
    VFloat acc[CB][TW];
    for (int b = 0; b < CB; ++b) {
        const VFloat bias = loadu<VFloat>(a.bias + (cob + b) * B);
        for (int i = 0; i < TW; ++i) acc[b][i] = bias;
    }
    for (int64_t cib = 0; cib < cinBlocks; ++cib) {
        const int channelsInBlock = int(std::min<int64_t>(Bi, is.channels - cib * Bi));
        const float* base = a.in + is.offset(a.image, cib, p.inY0 + r * p.inStepY, p.inX0 + j * p.inStepX);
        const float* w = p.weights + cob * weightBlockStride + cib * p.taps * Bi * B;
        for (int t = 0; t < p.taps; ++t, w += Bi * B) {
            const float* pixels = base + p.tapOffsets[t];
            auto accumulateChannel = [&](int c) {
                VFloat weight[CB];
                for (int b = 0; b < CB; ++b) weight[b] = loadu<VFloat>(w + b * weightBlockStride + c * B);
#pragma GCC unroll 16
                for (int i = 0; i < TW; ++i) {
                    const VFloat value = splat<VFloat>(pixels[i * inPixelStep + c]);
                    for (int b = 0; b < CB; ++b) acc[b][i] += value * weight[b];
                }
            };
            if (channelsInBlock == B) {
#pragma GCC unroll 4
                for (int c = 0; c < B; ++c) accumulateChannel(c);
            } else {
                // A partial last block (e.g. 3 RGB channels): skip the zero channels.
                for (int c = 0; c < channelsInBlock; ++c) accumulateChannel(c);
            }
        }
    }
    const BlockedShape& os = a.outShape;
    const int64_t outPixelStep = p.outStepX * B;
    for (int b = 0; b < CB; ++b) {
        float* out = a.out + os.offset(a.image, cob + b, p.outY0 + r * p.outStepY, p.outX0 + j * p.outStepX);
        for (int i = 0; i < TW; ++i) storeu(out + i * outPixelStep, activate(acc[b][i], a.activation));
    }
}

// Row remainders: tiles of 1..kTileWidth-1 pixels, chosen through a table of instantiations.
template <int CB, size_t... I>
constexpr auto makeTailTable(std::index_sequence<I...>) {
    return std::array<void (*)(const ConvRowsArgs&, int64_t, int64_t, int64_t), sizeof...(I)>{
        &convTile<int(I) + 1, CB>...};
}

template <int CB>
void convRow(const ConvRowsArgs& a, int64_t cob, int64_t r) {
    static constexpr auto tails = makeTailTable<CB>(std::make_index_sequence<kTileWidth - 1>());
    const int64_t columns = a.pass.columns;
    int64_t j = 0;
    for (; j + kTileWidth <= columns; j += kTileWidth) convTile<kTileWidth, CB>(a, cob, r, j);
    if (j < columns) tails[size_t(columns - j - 1)](a, cob, r, j);
}

}  // namespace

void convForwardRows(const ConvRowsArgs& a) {
    for (int64_t r = a.rowBegin; r < a.rowEnd; ++r) {
        int64_t cob = a.outBlockBegin;
        for (; cob + kTileBlocks <= a.outBlockEnd; cob += kTileBlocks) convRow<kTileBlocks>(a, cob, r);
        for (; cob < a.outBlockEnd; ++cob) convRow<1>(a, cob, r);
    }
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

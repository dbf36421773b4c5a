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

// One tile: TW pixels starting at output (y, x) for CB output blocks starting at cob.
template <int TW, int CB>
inline void convTile(const ConvRowsArgs& a, int64_t cob, int64_t y, int64_t x) {
    const BlockedShape& is = a.inShape;
    const int k = a.kernel, radius = k / 2;
    const int64_t cinBlocks = is.channelBlocks();
    const int64_t weightBlockStride = cinBlocks * k * k * B * B;  // floats per output channel block
    VFloat acc[CB][TW];
    for (int b = 0; b < CB; ++b) {
        const VFloat bias = loadu<VFloat>(a.bias + (cob + b) * B);
        for (int i = 0; i < TW; ++i) acc[b][i] = bias;
    }
    for (int64_t cib = 0; cib < cinBlocks; ++cib) {
        const int channelsInBlock = int(std::min<int64_t>(B, is.channels - cib * B));
        const float* inBlock = a.in + is.offset(a.image, cib, y - radius, x - radius);
        const float* w = a.weights + cob * weightBlockStride + cib * k * k * B * B;
        for (int ky = 0; ky < k; ++ky) {
            const float* row = inBlock + ky * is.rowStride();
            for (int kx = 0; kx < k; ++kx, w += B * B) {
                const float* pixels = row + kx * B;
                auto accumulateChannel = [&](int c) {
                    VFloat weight[CB];
                    for (int b = 0; b < CB; ++b) weight[b] = loadu<VFloat>(w + b * weightBlockStride + c * B);
#pragma GCC unroll 16
                    for (int i = 0; i < TW; ++i) {
                        const VFloat value = splat<VFloat>(pixels[i * B + c]);
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
    }
    const BlockedShape& os = a.outShape;
    for (int b = 0; b < CB; ++b) {
        float* out = a.out + os.offset(a.image, cob + b, y, x);
        for (int i = 0; i < TW; ++i) storeu(out + i * B, activate(acc[b][i], a.activation));
    }
}

// Row remainders: tiles of 1..kTileWidth-1 pixels, chosen through a table of instantiations.
template <int CB, size_t... I>
constexpr auto makeTailTable(std::index_sequence<I...>) {
    return std::array<void (*)(const ConvRowsArgs&, int64_t, int64_t, int64_t), sizeof...(I)>{
        &convTile<int(I) + 1, CB>...};
}

template <int CB>
void convRow(const ConvRowsArgs& a, int64_t cob, int64_t y) {
    static constexpr auto tails = makeTailTable<CB>(std::make_index_sequence<kTileWidth - 1>());
    const int64_t width = a.outShape.width;
    int64_t x = 0;
    for (; x + kTileWidth <= width; x += kTileWidth) convTile<kTileWidth, CB>(a, cob, y, x);
    if (x < width) tails[size_t(width - x - 1)](a, cob, y, x);
}

}  // namespace

void convForwardRows(const ConvRowsArgs& a) {
    for (int64_t y = a.rowBegin; y < a.rowEnd; ++y) {
        int64_t cob = a.outBlockBegin;
        for (; cob + kTileBlocks <= a.outBlockEnd; cob += kTileBlocks) convRow<kTileBlocks>(a, cob, y);
        for (; cob < a.outBlockEnd; ++cob) convRow<1>(a, cob, y);
    }
}

}  // namespace dejag::nn::DEJAG_SIMD_NAMESPACE

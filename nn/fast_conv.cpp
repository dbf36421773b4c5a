#include "nn/fast_conv.h"

#include <algorithm>
#include <cstring>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/fast_conv_kernels.h"

namespace dejag::nn {

Tensor allocateBlocked(const BlockedShape& shape) {
    return Tensor({shape.floatCount()});
}

void toBlocked(float* blocked, const float* plain, const BlockedShape& s) {
    parallelFor(0, s.batch * s.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const int64_t n = plane / s.channels, c = plane % s.channels;
            const float* src = plain + plane * s.height * s.width;
            for (int64_t y = 0; y < s.height; ++y) {
                float* dst = blocked + s.offset(n, c / s.block, y, 0) + c % s.block;
                for (int64_t x = 0; x < s.width; ++x) dst[x * s.block] = src[y * s.width + x];
            }
        }
    });
}

void fromBlocked(float* plain, const float* blocked, const BlockedShape& s) {
    parallelFor(0, s.batch * s.channels, 1, [&](int64_t first, int64_t last) {
        for (int64_t plane = first; plane < last; ++plane) {
            const int64_t n = plane / s.channels, c = plane % s.channels;
            float* dst = plain + plane * s.height * s.width;
            for (int64_t y = 0; y < s.height; ++y) {
                const float* src = blocked + s.offset(n, c / s.block, y, 0) + c % s.block;
                for (int64_t x = 0; x < s.width; ++x) dst[y * s.width + x] = src[x * s.block];
            }
        }
    });
}

bool FastConv2d::supports(const Conv2dDesc& d) {
    return d.strideH == 1 && d.strideW == 1 && d.dilationH == 1 && d.dilationW == 1 &&
           d.kernelHeight == d.kernelWidth && d.kernelHeight % 2 == 1 && d.padTop == d.kernelHeight / 2 &&
           d.padBottom == d.padTop && d.padLeft == d.padTop && d.padRight == d.padTop;
}

FastConv2d::FastConv2d(const Conv2dDesc& desc, const float* weight, const float* bias, Activation activation)
    : desc_(desc), activation_(activation), block_(simdFloatLanes(activeSimdLevel())) {
    desc.validate();
    if (!supports(desc))
        throw Error(
            "FastConv2d: only stride 1, odd square kernels with 'same' padding (dilation 1) are supported");
    if (activation == Activation::Sigmoid)
        throw Error("FastConv2d: sigmoid is not fused; apply it afterwards");
    const int64_t B = block_, k = desc.kernelHeight;
    const int64_t cinBlocks = (desc.inChannels + B - 1) / B, coutBlocks = (desc.outChannels + B - 1) / B;
    packedWeights_.assign(size_t(coutBlocks * cinBlocks * k * k * B * B), 0.0f);
    for (int64_t co = 0; co < desc.outChannels; ++co)
        for (int64_t ci = 0; ci < desc.inChannels; ++ci)
            for (int64_t ky = 0; ky < k; ++ky)
                for (int64_t kx = 0; kx < k; ++kx) {
                    const int64_t packed =
                        ((((co / B) * cinBlocks + ci / B) * k + ky) * k + kx) * B * B + (ci % B) * B + co % B;
                    packedWeights_[size_t(packed)] = weight[((co * desc.inChannels + ci) * k + ky) * k + kx];
                }
    paddedBias_.assign(size_t(coutBlocks * B), 0.0f);
    if (bias && desc.bias) std::copy(bias, bias + desc.outChannels, paddedBias_.begin());
}

BlockedShape FastConv2d::inputShape(int border) const {
    return {desc_.batch, desc_.inChannels, desc_.inHeight, desc_.inWidth, block_, border};
}

BlockedShape FastConv2d::outputShape(int border) const {
    return {desc_.batch, desc_.outChannels, desc_.inHeight, desc_.inWidth, block_, border};
}

void FastConv2d::forward(float* out, const BlockedShape& outShape, const float* in,
                         const BlockedShape& inShape) const {
    if (inShape.block != block_ || outShape.block != block_)
        throw Error("FastConv2d: blocked layout of " + std::to_string(inShape.block) + "/" +
                    std::to_string(outShape.block) + " channels, the kernels use " + std::to_string(block_));
    if (block_ != simdFloatLanes(activeSimdLevel()))
        throw Error("FastConv2d: the SIMD level changed since packing");
    if (inShape.border < desc_.kernelHeight / 2)
        throw Error("FastConv2d: the input border is narrower than the kernel radius");
    if (inShape.channels != desc_.inChannels || outShape.channels != desc_.outChannels ||
        inShape.height != desc_.inHeight || inShape.width != desc_.inWidth ||
        outShape.height != desc_.inHeight || outShape.width != desc_.inWidth ||
        inShape.batch != desc_.batch || outShape.batch != desc_.batch)
        throw Error("FastConv2d: tensor shapes do not match the convolution");
    ConvRowsArgs args;
    args.in = in, args.inShape = inShape, args.out = out, args.outShape = outShape;
    args.weights = packedWeights_.data(), args.bias = paddedBias_.data();
    args.kernel = int(desc_.kernelHeight);
    args.activation.kind = activation_;
    const int64_t coutBlocks = outShape.channelBlocks();
    // Work items: (image, group of output blocks, band of rows); bands small enough for both cores to
    // stay busy on small training patches, large enough to amortise the call at 1080p.
    const int64_t rowsPerItem =
        std::max<int64_t>(1, std::min<int64_t>(8, desc_.inHeight / (4 * threadCount()) + 1));
    const int64_t bands = (desc_.inHeight + rowsPerItem - 1) / rowsPerItem;
    const int64_t blockGroups = (coutBlocks + 1) / 2;
    parallelFor(0, desc_.batch * blockGroups * bands, 1, [&](int64_t first, int64_t last) {
        for (int64_t item = first; item < last; ++item) {
            ConvRowsArgs a = args;
            a.image = item / (blockGroups * bands);
            const int64_t group = (item / bands) % blockGroups;
            a.outBlockBegin = group * 2;
            a.outBlockEnd = std::min(coutBlocks, a.outBlockBegin + 2);
            a.rowBegin = (item % bands) * rowsPerItem;
            a.rowEnd = std::min(desc_.inHeight, a.rowBegin + rowsPerItem);
            DEJAG_SIMD_CALL(convForwardRows, a);
        }
    });
}

}  // namespace dejag::nn

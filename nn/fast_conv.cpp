#include "nn/fast_conv.h"

#include <algorithm>
#include <array>
#include <cstring>

#include "base/error.h"
#include "base/simd.h"
#include "base/thread_pool.h"
#include "nn/fast_conv_kernels.h"

namespace dejag::nn {

namespace {
constexpr int kMaxTaps = 256;
}

Tensor allocateBlocked(const BlockedShape& shape) {
    return Tensor({shape.floatCount()});
}

// Both conversions go row by row (all rows of all images and channel blocks in parallel, so a
// 3-channel input keeps both cores busy) and, within a row, pixel by pixel: each pixel's lanes are
// written (or read) together, one cache line of the blocked tensor at a time. copyRow(blockedRow,
// planeRows, lanes) gets the blocked row and the matching row of each of the block's planes.
template <class Plain, class Blocked, class F>
void forEachBlockedRow(Blocked* blocked, Plain* plain, const BlockedShape& s, const F& copyRow) {
    const int64_t rows = s.batch * s.channelBlocks() * s.height;
    parallelFor(0, rows, 8, [&](int64_t first, int64_t last) {
        for (int64_t r = first; r < last; ++r) {
            const int64_t y = r % s.height, cb = (r / s.height) % s.channelBlocks(),
                          n = r / (s.height * s.channelBlocks());
            const int lanes = int(std::min<int64_t>(s.block, s.channels - cb * s.block));
            Plain* planes[64];
            for (int l = 0; l < lanes; ++l)
                planes[l] = plain + ((n * s.channels + cb * s.block + l) * s.height + y) * s.width;
            copyRow(blocked + s.offset(n, cb, y, 0), planes, lanes);
        }
    });
}

void toBlocked(float* blocked, const float* plain, const BlockedShape& s) {
    if (s.block == 1) {  // planar: a row copy into the bordered plane
        forEachBlockedRow(blocked, plain, s, [&](float* row, const float* const* planes, int) {
            std::memcpy(row, planes[0], size_t(s.width) * sizeof(float));
        });
        return;
    }
    forEachBlockedRow(blocked, plain, s, [&](float* row, const float* const* planes, int lanes) {
        for (int64_t x = 0; x < s.width; ++x)
            for (int l = 0; l < lanes; ++l) row[x * s.block + l] = planes[l][x];
    });
}

void fromBlocked(float* plain, const float* blocked, const BlockedShape& s) {
    forEachBlockedRow(blocked, plain, s, [&](const float* row, float* const* planes, int lanes) {
        for (int64_t x = 0; x < s.width; ++x)
            for (int l = 0; l < lanes; ++l) planes[l][x] = row[x * s.block + l];
    });
}

BlockedConv::BlockedConv(const Conv2dDesc& d, const float* weight, const float* bias,
                         const ActivationDesc& activation, int inputBlock)
    : activation_(activation), block_(simdFloatLanes(activeSimdLevel())), outputBlock_(block_) {
    setInputBlock(inputBlock, d.inChannels);
    d.validate();
    batch_ = d.batch, inChannels_ = d.inChannels, inHeight_ = d.inHeight, inWidth_ = d.inWidth;
    outChannels_ = d.outChannels, outHeight_ = d.outHeight(), outWidth_ = d.outWidth();
    macs_ = d.macs();
    Pass pass;
    pass.rows = outHeight_, pass.columns = outWidth_;
    pass.inY0 = -d.padTop, pass.inStepY = d.strideH, pass.inX0 = -d.padLeft, pass.inStepX = d.strideW;
    const int64_t B = block_, Bi = inputBlock_, coutBlocks = (outChannels_ + B - 1) / B;
    const int64_t cinBlocks = (inChannels_ + Bi - 1) / Bi;
    const int64_t taps = d.kernelHeight * d.kernelWidth;
    kernelArea_ = taps;
    for (int64_t ky = 0; ky < d.kernelHeight; ++ky)
        for (int64_t kx = 0; kx < d.kernelWidth; ++kx) {
            pass.taps.push_back({ky * d.dilationH, kx * d.dilationW});
            pass.kernelTaps.push_back(ky * d.kernelWidth + kx);
        }
    pass.weights.assign(size_t(coutBlocks * cinBlocks * taps * Bi * B), 0.0f);
    for (int64_t co = 0; co < outChannels_; ++co)
        for (int64_t ci = 0; ci < inChannels_; ++ci)
            for (int64_t t = 0; t < taps; ++t)
                pass.weights[size_t((((co / B) * cinBlocks + ci / Bi) * taps + t) * Bi * B + (ci % Bi) * B +
                                    co % B)] = weight[(co * inChannels_ + ci) * taps + t];
    passes_.push_back(std::move(pass));
    finish(d.bias ? bias : nullptr);
}

BlockedConv::BlockedConv(const ConvTranspose2dDesc& d, const float* weight, const float* bias,
                         const ActivationDesc& activation, int inputBlock)
    : activation_(activation), block_(simdFloatLanes(activeSimdLevel())), outputBlock_(block_) {
    setInputBlock(inputBlock, d.inChannels);
    d.validate();
    batch_ = d.batch, inChannels_ = d.inChannels, inHeight_ = d.inHeight, inWidth_ = d.inWidth;
    outChannels_ = d.outChannels, outHeight_ = d.outHeight(), outWidth_ = d.outWidth();
    macs_ = d.macs();
    const int64_t B = block_, Bi = inputBlock_, coutBlocks = (outChannels_ + B - 1) / B;
    const int64_t cinBlocks = (inChannels_ + Bi - 1) / Bi;
    transposed_ = true;
    kernelArea_ = d.kernelHeight * d.kernelWidth;
    // Output oy = iy * s - pad + ky * dilation. For the outputs oy = py + r * s of parity class py, the
    // taps with (py + pad - ky * dilation) divisible by s reach them, from input row r + dy.
    auto tapsFor = [](int64_t parity, int64_t pad, int64_t kernel, int64_t dilation, int64_t stride) {
        std::vector<std::pair<int64_t, int64_t>> taps;  // (k, d)
        for (int64_t k = 0; k < kernel; ++k) {
            const int64_t v = parity + pad - k * dilation;
            if (((v % stride) + stride) % stride == 0) taps.push_back({k, v / stride});
        }
        return taps;
    };
    for (int64_t py = 0; py < d.strideH; ++py)
        for (int64_t px = 0; px < d.strideW; ++px) {
            Pass pass;
            pass.rows = py < outHeight_ ? (outHeight_ - py + d.strideH - 1) / d.strideH : 0;
            pass.columns = px < outWidth_ ? (outWidth_ - px + d.strideW - 1) / d.strideW : 0;
            if (pass.rows == 0 || pass.columns == 0) continue;
            pass.outY0 = py, pass.outStepY = d.strideH, pass.outX0 = px, pass.outStepX = d.strideW;
            const auto rowsTaps = tapsFor(py, d.padH, d.kernelHeight, d.dilationH, d.strideH);
            const auto columnTaps = tapsFor(px, d.padW, d.kernelWidth, d.dilationW, d.strideW);
            std::vector<std::pair<int64_t, int64_t>> kernelIndex;
            for (const auto& [ky, dy] : rowsTaps)
                for (const auto& [kx, dx] : columnTaps) {
                    pass.taps.push_back({dy, dx});
                    pass.kernelTaps.push_back(ky * d.kernelWidth + kx);
                    kernelIndex.push_back({ky, kx});
                }
            const int64_t taps = int64_t(pass.taps.size());
            pass.weights.assign(size_t(std::max<int64_t>(1, coutBlocks * cinBlocks * taps * Bi * B)), 0.0f);
            for (int64_t co = 0; co < outChannels_; ++co)
                for (int64_t ci = 0; ci < inChannels_; ++ci)
                    for (int64_t t = 0; t < taps; ++t) {
                        const auto [ky, kx] = kernelIndex[size_t(t)];
                        pass.weights[size_t((((co / B) * cinBlocks + ci / Bi) * taps + t) * Bi * B +
                                            (ci % Bi) * B + co % B)] =
                            weight[((ci * outChannels_ + co) * d.kernelHeight + ky) * d.kernelWidth + kx];
                    }
            passes_.push_back(std::move(pass));
        }
    finish(d.bias ? bias : nullptr);
}

void BlockedConv::finish(const float* bias) {
    if (activation_.kind == Activation::Sigmoid)
        throw Error("BlockedConv: sigmoid is not fused; apply it afterwards");
    const int64_t B = block_, coutBlocks = (outChannels_ + B - 1) / B;
    // A few output channels and a blocked input: the narrow kernel, input channels in the lanes.
    if (inputBlock_ == block_ && outChannels_ <= DEJAG_SIMD_CALL(narrowMaxOutputChannels)) {
        const int64_t cinBlocks = (inChannels_ + B - 1) / B;
        for (Pass& p : passes_) {
            const int64_t taps = int64_t(p.taps.size());
            p.narrowWeights.assign(size_t(std::max<int64_t>(1, cinBlocks * taps * outChannels_ * B)), 0.0f);
            for (int64_t cib = 0; cib < cinBlocks; ++cib)
                for (int64_t t = 0; t < taps; ++t)
                    for (int64_t co = 0; co < outChannels_; ++co)
                        for (int64_t c = 0; c < B; ++c)
                            p.narrowWeights[size_t(((cib * taps + t) * outChannels_ + co) * B + c)] =
                                p.weights[size_t(((cib * taps + t) * B + c) * B + co)];
        }
    }
    paddedBias_.assign(size_t(coutBlocks * B), 0.0f);
    if (bias) std::copy(bias, bias + outChannels_, paddedBias_.begin());
    // The border must hold every input pixel a tap reads outside the image.
    int64_t border = 0;
    for (const Pass& p : passes_) {
        if (int64_t(p.taps.size()) > kMaxTaps) throw Error("BlockedConv: more than 256 kernel taps");
        for (const Tap& t : p.taps) {
            const int64_t top = p.inY0 + t.dy, bottom = p.inY0 + (p.rows - 1) * p.inStepY + t.dy;
            const int64_t left = p.inX0 + t.dx, right = p.inX0 + (p.columns - 1) * p.inStepX + t.dx;
            border = std::max({border, -top, -left, bottom - (inHeight_ - 1), right - (inWidth_ - 1)});
        }
    }
    requiredBorder_ = int(border);
}

void BlockedConv::setInputBlock(int inputBlock, int64_t inChannels) {
    inputBlock_ = inputBlock == 0 ? block_ : inputBlock;
    if (inputBlock_ != block_ && inputBlock_ != 1)
        throw Error("BlockedConv: the input block is the SIMD width or 1, not " + std::to_string(inputBlock));
    if (inputBlock_ == 1 && block_ != 1 && inChannels > 16)
        throw Error("BlockedConv: a planar (block 1) input is for a few channels, not " +
                    std::to_string(inChannels));
}

BlockedShape BlockedConv::inputShape(int border) const {
    return {batch_, inChannels_, inHeight_, inWidth_, inputBlock_, border};
}

BlockedShape BlockedConv::outputShape(int border) const {
    if (pool_) return {batch_, outChannels_, outHeight_ / 2, outWidth_ / 2, outputBlock_, border};
    return {batch_, outChannels_, outHeight_, outWidth_, outputBlock_, border};
}

int BlockedConv::compactOutputBlock() const {
    if (pool_ || passes_.empty() || passes_[0].narrowWeights.empty()) return 0;
    for (const Pass& p : passes_)
        if (p.outStepX != 1) return 0;
    const int compact = outChannels_ == 1 ? 1 : outChannels_ == 2 ? 2 : 4;
    return compact < block_ ? compact : 0;
}

void BlockedConv::useCompactOutput() {
    const int compact = compactOutputBlock();
    if (compact == 0)
        throw Error("BlockedConv: no compact output for this layer (" + std::to_string(outChannels_) +
                    " output channels)");
    outputBlock_ = compact;
}

void BlockedConv::fuseMaxPool2x2() {
    if (transposed_ || passes_.size() != 1 || passes_[0].outStepX != 1 || passes_[0].outStepY != 1)
        throw Error("BlockedConv: max pooling fuses into a Conv2D only");
    if (outputBlock_ != block_) throw Error("BlockedConv: max pooling does not fuse with a compact output");
    if (outHeight_ < 2 || outWidth_ < 2)
        throw Error("BlockedConv: a 2x2 pooling needs an output of at least 2x2 pixels");
    pool_ = true;
}

bool BlockedConv::canReadBf16() const {
    return block_ == 16 && inputBlock_ == block_ && passes_.size() > 0 && passes_[0].narrowWeights.empty();
}

bool BlockedConv::canWriteBf16() const {
    return block_ == 16 && outputBlock_ == block_ && passes_.size() > 0 && passes_[0].narrowWeights.empty();
}

void BlockedConv::useBf16Input() {
    if (!bf16Available()) throw Error("BlockedConv: bf16 activations need a CPU with AVX-512 BF16");
    if (!canReadBf16()) throw Error("BlockedConv: this layer cannot read a bf16 input");
    const int64_t B = block_;
    for (Pass& p : passes_) {
        // From the float packing [...][taps][B ci][B co] to [...][taps][B / 2 pairs][B co][2].
        p.pairWeights.assign(p.weights.size(), 0);
        for (size_t tap = 0; tap < p.weights.size() / size_t(B * B); ++tap) {
            const float* w = p.weights.data() + tap * size_t(B * B);
            uint16_t* pw = p.pairWeights.data() + tap * size_t(B * B);
            for (int64_t ci = 0; ci < B; ++ci)
                for (int64_t co = 0; co < B; ++co)
                    pw[((ci / 2) * B + co) * 2 + ci % 2] = toBf16(w[ci * B + co]);
        }
    }
    bf16Input_ = true;
}

void BlockedConv::forward(float* out, const BlockedShape& outShape, const float* in,
                          const BlockedShape& inShape, bool inBf16, bool outBf16,
                          const ColumnKeep* keep) const {
    if ((inBf16 && !bf16Input_) || (outBf16 && !canWriteBf16()))
        throw Error(inBf16 && !bf16Input_ ? "BlockedConv: a bf16 input needs useBf16Input() first"
                                          : "BlockedConv: this layer cannot write a bf16 output");
    if (inShape.block != inputBlock_ || outShape.block != outputBlock_ ||
        block_ != simdFloatLanes(activeSimdLevel()))
        throw Error("BlockedConv: blocked layout of " + std::to_string(inShape.block) +
                    " channels, the kernels use " + std::to_string(simdFloatLanes(activeSimdLevel())) +
                    " (the SIMD level changed since packing?)");
    if (inShape.border < requiredBorder_)
        throw Error("BlockedConv: the input border (" + std::to_string(inShape.border) +
                    ") is narrower than the " + std::to_string(requiredBorder_) + " pixels the kernel reads");
    const BlockedShape expected = outputShape(outShape.border);
    if (inShape.channels != inChannels_ || outShape.channels != outChannels_ || inShape.height != inHeight_ ||
        inShape.width != inWidth_ || outShape.height != expected.height || outShape.width != expected.width ||
        inShape.batch != batch_ || outShape.batch != batch_)
        throw Error("BlockedConv: tensor shapes do not match the convolution");
    const int64_t coutBlocks = outShape.channelBlocks(), blockGroups = (coutBlocks + 1) / 2;  // 1 if compact
    // Tap offsets for this input layout; on the stack (no allocation per call).
    std::array<std::array<int64_t, kMaxTaps>, 16> offsets{};
    if (passes_.size() > offsets.size()) throw Error("BlockedConv: too many passes");
    struct Item {
        int64_t pass, bands, rowsPerBand;
    };
    std::array<Item, 16> items{};
    int64_t totalItems = 0;
    for (size_t p = 0; p < passes_.size(); ++p) {
        const Pass& pass = passes_[p];
        for (size_t t = 0; t < pass.taps.size(); ++t)
            offsets[p][t] = pass.taps[t].dy * inShape.rowStride() + pass.taps[t].dx * inputBlock_;
        // Bands small enough for both cores to stay busy on small patches, large enough to amortise.
        const int64_t rows = pool_ ? pass.rows / 2 : pass.rows;
        const int64_t rowsPerBand =
            std::max<int64_t>(1, std::min<int64_t>(8, rows / (4 * threadCount()) + 1));
        items[p] = {int64_t(p), (rows + rowsPerBand - 1) / rowsPerBand, rowsPerBand};
        totalItems += batch_ * blockGroups * items[p].bands;
    }
    parallelFor(0, totalItems, 1, [&](int64_t first, int64_t last) {
        for (int64_t item = first; item < last; ++item) {
            int64_t index = item;
            size_t p = 0;
            while (index >= batch_ * blockGroups * items[p].bands)
                index -= batch_ * blockGroups * items[p++].bands;
            const Pass& pass = passes_[p];
            ConvRowsArgs a;
            a.in = in, a.inShape = inShape, a.out = out, a.outShape = outShape;
            a.pass = pass.view(offsets[p].data());
            a.pool2x2 = pool_;
            a.bias = paddedBias_.data();
            a.activation = activation_;
            a.inBf16 = inBf16, a.outBf16 = outBf16;
            a.streamBytes = streamBytes_;
            const int64_t bands = items[p].bands;
            a.image = index / (blockGroups * bands);
            const int64_t group = (index / bands) % blockGroups;
            a.outBlockBegin = group * 2;
            a.outBlockEnd = std::min(coutBlocks, a.outBlockBegin + 2);
            a.rowBegin = (index % bands) * items[p].rowsPerBand;
            a.rowEnd = std::min(pool_ ? pass.rows / 2 : pass.rows, a.rowBegin + items[p].rowsPerBand);
            if (keep && passes_.size() == 1 && !pool_ && !transposed_ && batch_ == 1)
                a.keep = keep->keep, a.keepRowStride = keep->rowStride, a.keepGroup = keep->group;
            DEJAG_SIMD_CALL(convForwardRows, a);
        }
    });
}

BlockedShape BlockedConv::bandShape(const BlockedShape& inShape) const {
    const Pass& pass = passes_.front();
    int64_t low = 0, high = 0;
    for (const Tap& t : pass.taps) low = std::min(low, t.dy), high = std::max(high, t.dy);
    BlockedShape band = inShape;
    band.batch = 1;
    band.height = (kBandRows - 1) * pass.inStepY + high - low + 1;
    return band;
}

void BlockedConv::forwardBanded(float* out, const BlockedShape& outShape, const BlockedShape& inShape,
                                BandInput& input, float* const* buffers, int bufferCount,
                                bool outBf16) const {
    if (!canBandInput()) throw Error("BlockedConv: a banded input needs a single-pass Conv2D of one image");
    if ((outBf16 && !canWriteBf16()) || inShape.block != inputBlock_ || outShape.block != outputBlock_ ||
        block_ != simdFloatLanes(activeSimdLevel()) || inShape.border < requiredBorder_ ||
        inShape.channels != inChannels_ || inShape.height != inHeight_ || inShape.width != inWidth_ ||
        outShape.channels != outChannels_ || outShape.height != outHeight_ || outShape.width != outWidth_ ||
        bufferCount < 1)
        throw Error("BlockedConv: tensor shapes do not match the convolution");
    const Pass& pass = passes_.front();
    const BlockedShape band = bandShape(inShape);
    int64_t low = 0;
    for (const Tap& t : pass.taps) low = std::min(low, t.dy);
    std::array<int64_t, kMaxTaps> offsets{};
    for (size_t t = 0; t < pass.taps.size(); ++t)
        offsets[t] = pass.taps[t].dy * band.rowStride() + pass.taps[t].dx * inputBlock_;
    const int64_t bands = (pass.rows + kBandRows - 1) / kBandRows;
    parallelFor(0, bufferCount, 1, [&](int64_t first, int64_t last) {
        for (int64_t k = first; k < last; ++k)
            for (int64_t b = k; b < bands; b += bufferCount) {
                ConvRowsArgs a;
                a.rowBegin = b * kBandRows, a.rowEnd = std::min(pass.rows, a.rowBegin + kBandRows);
                // The band's first input row: the top tap of its first lattice row.
                const int64_t firstRow = pass.inY0 + a.rowBegin * pass.inStepY + low;
                input.fill(
                    firstRow,
                    (a.rowEnd - 1 - a.rowBegin) * pass.inStepY + band.height - (kBandRows - 1) * pass.inStepY,
                    buffers[k], band);
                a.in = buffers[k], a.inShape = band, a.out = out, a.outShape = outShape;
                a.pass = pass.view(offsets.data());
                a.pass.inY0 -= firstRow;  // lattice row r reads band row inY0 + r * inStepY - firstRow
                a.bias = paddedBias_.data();
                a.activation = activation_;
                a.outBf16 = outBf16;
                a.streamBytes = streamBytes_;
                a.outBlockBegin = 0, a.outBlockEnd = outShape.channelBlocks();
                DEJAG_SIMD_CALL(convForwardRows, a);
            }
    });
}

void BlockedConv::backwardWeights(float* dweight, float* dbias, const float* dout,
                                  const BlockedShape& doutShape, const float* in,
                                  const BlockedShape& inShape) const {
    if (pool_) throw Error("BlockedConv::backwardWeights: a convolution with fused pooling is for inference");
    if (inShape.border < requiredBorder_ || inShape.block != inputBlock_ || doutShape.block != block_ ||
        inShape.channels != inChannels_ || doutShape.channels != outChannels_ ||
        doutShape.height != outHeight_ || doutShape.width != outWidth_ || inShape.height != inHeight_ ||
        inShape.width != inWidth_)
        throw Error("BlockedConv::backwardWeights: tensor shapes do not match the convolution");
    const int64_t B = block_, Bi = inputBlock_, cinBlocks = inShape.channelBlocks(),
                  coutBlocks = doutShape.channelBlocks();
    struct Item {
        int64_t pass, tap;
    };
    std::vector<Item> taps;
    std::vector<std::vector<int64_t>> offsets(passes_.size());
    for (size_t p = 0; p < passes_.size(); ++p)
        for (size_t t = 0; t < passes_[p].taps.size(); ++t) {
            taps.push_back({int64_t(p), int64_t(t)});
            offsets[p].push_back(passes_[p].taps[t].dy * inShape.rowStride() +
                                 passes_[p].taps[t].dx * inputBlock_);
        }
    const int64_t items = int64_t(taps.size()) * coutBlocks * cinBlocks;
    parallelFor(0, items, 1, [&](int64_t first, int64_t last) {
        std::vector<float> block(size_t(Bi * B));
        for (int64_t item = first; item < last; ++item) {
            const Item& tap = taps[size_t(item / (coutBlocks * cinBlocks))];
            const Pass& pass = passes_[size_t(tap.pass)];
            WeightGradArgs a;
            a.in = in, a.inShape = inShape, a.dout = dout, a.outShape = doutShape;
            a.pass = pass.view(offsets[size_t(tap.pass)].data());
            a.tap = int(tap.tap);
            a.outBlock = (item / cinBlocks) % coutBlocks;
            a.inBlock = item % cinBlocks;
            a.dw = block.data();
            DEJAG_SIMD_CALL(convWeightGradient, a);
            const int64_t k = pass.kernelTaps[size_t(tap.tap)];
            for (int64_t c = 0; c < Bi; ++c) {
                const int64_t ci = a.inBlock * Bi + c;
                if (ci >= inChannels_) break;
                for (int64_t o = 0; o < B; ++o) {
                    const int64_t co = a.outBlock * B + o;
                    if (co >= outChannels_) break;
                    const int64_t index = transposed_ ? (ci * outChannels_ + co) * kernelArea_ + k
                                                      : (co * inChannels_ + ci) * kernelArea_ + k;
                    dweight[index] += block[size_t(c * B + o)];
                }
            }
        }
    });
    if (dbias) {
        parallelFor(0, outChannels_, 1, [&](int64_t first, int64_t last) {
            for (int64_t co = first; co < last; ++co) {
                double sum = 0.0;
                for (int64_t n = 0; n < doutShape.batch; ++n)
                    for (int64_t y = 0; y < outHeight_; ++y) {
                        const float* g = dout + doutShape.offset(n, co / B, y, 0) + co % B;
                        for (int64_t x = 0; x < outWidth_; ++x) sum += g[x * B];
                    }
                dbias[co] += float(sum);
            }
        });
    }
}

std::optional<BlockedConv> BlockedConv::inputGradient(const Conv2dDesc& d, const float* weight) {
    // dIn[iy] = sum_ky w[ky] dOut[oy] with iy = oy * s - padTop + ky * dilation: a ConvTranspose2D with
    // padding padTop and the output padding that restores the input size.
    ConvTranspose2dDesc t;
    t.batch = d.batch, t.inChannels = d.outChannels, t.outChannels = d.inChannels;
    t.inHeight = d.outHeight(), t.inWidth = d.outWidth();
    t.kernelHeight = d.kernelHeight, t.kernelWidth = d.kernelWidth;
    t.strideH = d.strideH, t.strideW = d.strideW, t.dilationH = d.dilationH, t.dilationW = d.dilationW;
    t.padH = d.padTop, t.padW = d.padLeft;
    t.bias = false;
    // With no output padding the transposed conv yields outHeight(); the difference to the input size is
    // the output padding it needs.
    t.outputPaddingH = t.outputPaddingW = 0;
    const int64_t opH = d.inHeight - t.outHeight(), opW = d.inWidth - t.outWidth();
    if (opH < 0 || opW < 0 || (opH >= t.strideH && opH >= t.dilationH) ||
        (opW >= t.strideW && opW >= t.dilationW))
        return std::nullopt;
    t.outputPaddingH = int(opH), t.outputPaddingW = int(opW);
    return BlockedConv(t, weight, nullptr, ActivationDesc{Activation::None});
}

std::optional<BlockedConv> BlockedConv::inputGradient(const ConvTranspose2dDesc& d, const float* weight) {
    // dIn[iy] = sum_ky w[ky] dOut[iy * s - pad + ky * dilation]: a Conv2D of stride s, padding pad before
    // and max(0, pad - outputPadding) after (those reads only ever meet zeros).
    Conv2dDesc c;
    c.batch = d.batch, c.inChannels = d.outChannels, c.outChannels = d.inChannels;
    c.inHeight = d.outHeight(), c.inWidth = d.outWidth();
    c.kernelHeight = d.kernelHeight, c.kernelWidth = d.kernelWidth;
    c.strideH = d.strideH, c.strideW = d.strideW, c.dilationH = d.dilationH, c.dilationW = d.dilationW;
    c.padTop = d.padH, c.padLeft = d.padW;
    c.padBottom = std::max(0, d.padH - d.outputPaddingH), c.padRight = std::max(0, d.padW - d.outputPaddingW);
    c.bias = false;
    if (c.outHeight() != d.inHeight || c.outWidth() != d.inWidth) return std::nullopt;
    return BlockedConv(c, weight, nullptr, ActivationDesc{Activation::None});
}

}  // namespace dejag::nn

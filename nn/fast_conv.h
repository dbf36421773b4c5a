// dejag/nn: the fast convolution kernels (issue "nn: fast CPU kernels"), on the blocked layout of
// nn/blocked.h. They are tested against the reference kernels of nn/layers.h on every SIMD path.
//
// Design, measured against oneDNN in `dejag bench nn`: a register-blocked direct convolution. One
// micro-kernel computes a tile of TW output pixels x 2 blocks of B output channels (2 TW accumulators of
// one vector each); for every input channel and kernel tap it loads two vectors of B weights and
// multiplies them with TW broadcast input values. Every weight vector is reused TW times and every input
// value 2B times, so the loop is FMA-bound, with no im2col copy and no packing of activations.
// A Conv2D of any stride, padding and dilation is one pass of that kernel over the output; a
// ConvTranspose2D of stride s is s^2 passes, one per output parity class, each a small stride-1
// convolution with the kernel taps that reach that class (no zero-stuffing, no scatter).
#pragma once

#include <optional>
#include <vector>

#include "nn/blocked.h"
#include "nn/fast_conv_kernels.h"
#include "nn/layers.h"

namespace dejag::nn {

class BlockedConv {
  public:
    // Weights in the PyTorch layouts of nn/layers.h; packed once here. Throws dejag::Error for a sigmoid
    // activation (not fused: apply it afterwards) or an invalid descriptor.
    // inputBlock: channels per block of the input layout: 0 = the SIMD width (like every activation), or
    // 1 = planar, for inputs of a few channels (an RGB or grey image), which then cost 1/B of the memory
    // traffic and need no conversion beyond the zero border.
    BlockedConv(const Conv2dDesc& desc, const float* weight, const float* bias,
                const ActivationDesc& activation, int inputBlock = 0);
    BlockedConv(const ConvTranspose2dDesc& desc, const float* weight, const float* bias,
                const ActivationDesc& activation, int inputBlock = 0);

    // The input border the taps need (reads there must be zero), for the descriptor's input size.
    int requiredInputBorder() const { return requiredBorder_; }
    BlockedShape inputShape(int border) const;
    BlockedShape outputShape(int border) const;
    // in: blocked input with border >= requiredInputBorder(); out: blocked output, border untouched.
    // inBf16 / outBf16: the input / output holds bf16 elements (uint16_t, nn/blocked.h's toBf16) in the
    // same layout, pointers cast to float*; for inference where bf16Available(). A bf16 input needs
    // useBf16Input() first; a bf16 output is rounded after the activation.
    // keep (optional): output columns to compute per output row, as ConvRowsArgs::keep (a single-pass
    // Conv2D only; the wide kernel honours it, the others compute everything).
    struct ColumnKeep {
        const uint8_t* keep = nullptr;
        int64_t rowStride = 0, group = 0;
    };
    void forward(float* out, const BlockedShape& outShape, const float* in, const BlockedShape& inShape,
                 bool inBf16 = false, bool outBf16 = false, const ColumnKeep* keep = nullptr) const;

    // An input made a band of rows at a time, never stored whole (a frame streamed into a network's
    // first layer): for a single-pass Conv2D without pooling on one image (canBandInput()).
    struct BandInput {
        // Input rows [firstRow, firstRow + rows) into `band`, row y at bandShape.offset(0, c, y - firstRow,
        // 0); rows outside the image must be zero. The band's border columns are zero and must stay so.
        virtual void fill(int64_t firstRow, int64_t rows, float* band, const BlockedShape& bandShape) = 0;

      protected:
        ~BandInput() = default;
    };
    static constexpr int64_t kBandRows = 8;  // output rows per band
    bool canBandInput() const { return passes_.size() == 1 && !pool_ && !transposed_ && batch_ == 1; }
    // The shape of a band buffer for an input of shape inShape (its width, block and border).
    BlockedShape bandShape(const BlockedShape& inShape) const;
    // As forward(), the input given band by band: the bands are shared out among bufferCount chunks run
    // in parallel, chunk k filling buffers[k] (zeroed once, bandShape(inShape).floatCount() floats).
    void forwardBanded(float* out, const BlockedShape& outShape, const BlockedShape& inShape,
                       BandInput& input, float* const* buffers, int bufferCount, bool outBf16 = false) const;

    // Packs the weights rounded to bf16 in input-channel pairs, for forward() with a bf16 input (the
    // activations and weights in bf16, the sums in float: vdpbf16ps). Throws dejag::Error when
    // bf16Available() is false, or for an input that is not blocked or a layer the narrow kernel runs.
    void useBf16Input();
    bool bf16Input() const { return bf16Input_; }
    // Whether forward() can take a bf16 input or write a bf16 output for this layer (the wide kernel, a
    // blocked input for the former; not a compact output).
    bool canReadBf16() const;
    bool canWriteBf16() const;

    // Training: ADDS the weight gradient (in the PyTorch layout of the forward's weights) and the bias
    // gradient, from the forward's blocked input and the blocked gradient of its output (before the
    // activation). Deterministic: each gradient element is summed by one thread in a fixed order.
    void backwardWeights(float* dweight, float* dbias, const float* dout, const BlockedShape& doutShape,
                         const float* in, const BlockedShape& inShape) const;

    // The convolution computing a layer's input gradient from its output gradient, when it is one:
    // Conv2D -> ConvTranspose2D and back, same weights (their PyTorch layouts coincide). None when the
    // adjoint's output padding would be negative (e.g. 'same' stride 2 with the extra row after).
    static std::optional<BlockedConv> inputGradient(const Conv2dDesc& desc, const float* weight);
    static std::optional<BlockedConv> inputGradient(const ConvTranspose2dDesc& desc, const float* weight);

    // Fuses a 2x2 max pooling of stride 2 (no padding, floor mode) into a stride-1 Conv2D: forward() then
    // writes the pooled output (outputShape() is pooled) and the full-size output is never stored.
    // For inference only (backwardWeights() refuses). Throws dejag::Error for a ConvTranspose2D.
    void fuseMaxPool2x2();
    bool pooled() const { return pool_; }

    // A layer with 1-4 output channels run by the narrow kernel (a stride-1 lattice, no fused pooling)
    // can write a compact output: OB = 1, 2 or 4 floats per pixel instead of a vector of B (a 16 -> 3
    // layer at 1080p: 33 MB instead of 133 MB). Returns OB, or 0 when this layer cannot.
    int compactOutputBlock() const;
    // From now on outputShape() and forward() use the compact output block. Throws dejag::Error when
    // compactOutputBlock() is 0. The compact layout is read by fromBlocked() and the elementwise ops,
    // not by another convolution.
    void useCompactOutput();

    // Outputs larger than this many bytes (as stored, bf16 or float) are written with non-temporal stores
    // that bypass the caches, so a 1080p frame's 133 MB activation does not first read every line it
    // overwrites; smaller ones stay in the caches for the next layer, which reads them at once. The
    // default, 32 MB, was measured: dejag-fast's largest bf16 activation at 1080p (16.6 MB) streamed took
    // its frames 3 % longer. Tests lower it to run the streamed path on smaller layers.
    void setStreamedOutputBytes(int64_t bytes) { streamBytes_ = bytes; }

    int block() const { return block_; }
    int64_t macs() const { return macs_; }

  private:
    struct Tap {
        int64_t dy, dx;
    };
    struct Pass {
        int64_t rows = 0, columns = 0;
        int64_t outY0 = 0, outStepY = 1, outX0 = 0, outStepX = 1;
        int64_t inY0 = 0, inStepY = 1, inX0 = 0, inStepX = 1;
        std::vector<Tap> taps;
        std::vector<int64_t> kernelTaps;    // per tap: ky * kernelWidth + kx in the PyTorch weights
        std::vector<float> weights;         // [Cout blocks][Cin blocks][taps][B ci][B co]
        std::vector<float> narrowWeights;   // [Cin blocks][taps][Cout][B ci], for a few output channels
        std::vector<uint16_t> pairWeights;  // bf16 [Cout blocks][Cin blocks][taps][B / 2][B co][2]
        // The kernel's view of this pass, with tap offsets for one input layout.
        ConvPass view(const int64_t* tapOffsets) const {
            return {rows,
                    columns,
                    outY0,
                    outStepY,
                    outX0,
                    outStepX,
                    inY0,
                    inStepY,
                    inX0,
                    inStepX,
                    int(taps.size()),
                    tapOffsets,
                    weights.data(),
                    narrowWeights.empty() ? nullptr : narrowWeights.data(),
                    pairWeights.empty() ? nullptr : pairWeights.data()};
        }
    };
    void finish(const float* bias);
    void setInputBlock(int inputBlock, int64_t inChannels);

    int64_t batch_ = 1, inChannels_ = 1, inHeight_ = 1, inWidth_ = 1;
    int64_t outChannels_ = 1, outHeight_ = 1, outWidth_ = 1;
    ActivationDesc activation_;
    int block_;
    int inputBlock_ = 1;
    int outputBlock_;  // block_, or the compact block after useCompactOutput()
    int requiredBorder_ = 0;
    int64_t macs_ = 0;
    bool transposed_ = false;  // weights (Cin, Cout, kh, kw) instead of (Cout, Cin, kh, kw)
    bool pool_ = false;        // fused 2x2 max pooling
    bool bf16Input_ = false;   // pairWeights packed
    int64_t streamBytes_ = kDefaultStreamedOutputBytes;
    int64_t kernelArea_ = 1;
    std::vector<Pass> passes_;
    std::vector<float> paddedBias_;
};

}  // namespace dejag::nn

// dejag/nn: a model compiled for fast inference at one input size.
//
// The plan packs every convolution's weights for the fast kernels (nn/fast_conv.h), keeps every
// activation in the blocked layout, and places all of them in one arena whose regions are reused once a
// tensor's last consumer has run (Open Image Denoise plans its activations the same way). After
// construction, run() allocates nothing: no allocation per frame. Build a new plan for another input
// size, another SIMD level, or after the weights change.
#pragma once

#include <cstdint>
#include <memory>

#include "nn/model.h"
#include "nn/tensor.h"

namespace dejag::nn {

// Float32: every activation in float. BFloat16 (CPUs with AVX-512 BF16 only: bf16Available()): the
// activations that only convolutions and pixel shuffles read are stored as bf16 and the convolutions
// reading them multiply bf16 pairs into float sums (vdpbf16ps), twice the multiply-adds per instruction
// and half the memory traffic; the model's input, its output and whatever else reads an activation stay
// float. Each bf16 value carries 8 significant bits (a relative error up to 2^-9 per rounding).
enum class InferencePrecision { Float32, BFloat16 };

// Gives the input rows InferencePlan::runStreamed() asks for: row y of image n into one pointer per input
// channel (inputShape()[3] floats each). Calls come from several threads at once; a row may be asked
// for more than once.
class InputRowSource {
  public:
    virtual void row(int64_t n, int64_t y, float* const* channels) = 0;

  protected:
    ~InputRowSource() = default;
};

// Takes the output rows of InferencePlan::runInPlace() and runStreamed(): row y of image n, one pointer per
// output channel to outputShape()[3] floats, valid during the call. Calls come from several threads at once,
// each with another row.
class OutputRowSink {
  public:
    virtual void row(int64_t n, int64_t y, const float* const* channels) = 0;
    // Row y of image n is the input's, bit for bit (a kernel-predicting network passing the whole row
    // through, setPassThrough()): a sink that can copy it from where the input came from does so and
    // returns true, and the row is not made; false (the default) has it made and given to row().
    virtual bool passRow(int64_t n, int64_t y) {
        (void)n, (void)y;
        return false;
    }
    // A sink that takes a network's output rows as the plan holds them (a network whose output stage is a
    // layer of its own: not a kernel-predicting or residual output) returns true here, and is then
    // called on rowStrided() and never on row(): channel c's pixel x at channels[c][x * stride], with no
    // conversion of the whole output first.
    virtual bool takesStridedRows() const { return false; }
    virtual void rowStrided(int64_t n, int64_t y, const float* const* channels, int64_t stride) {
        (void)n, (void)y, (void)channels, (void)stride;
    }

  protected:
    ~OutputRowSink() = default;
};

class InferencePlan {
  public:
    // inputShape: (N, Cin, H, W). Throws dejag::Error if the model cannot take it, or for BFloat16 on a
    // CPU (or a forced SIMD level) without AVX-512 BF16.
    InferencePlan(const Model& model, const Shape& inputShape,
                  InferencePrecision precision = InferencePrecision::Float32);
    InferencePlan(InferencePlan&&) noexcept;
    InferencePlan& operator=(InferencePlan&&) noexcept;
    ~InferencePlan();

    // input must have the plan's shape and be finite; the result lives until the next run().
    const Tensor& run(const Tensor& input);
    // As run(), without the finiteness check (the caller has checked).
    const Tensor& runUnchecked(const Tensor& input);

    // Frames without a copy in and out (the CNN filter's path): write the input's rows in place through
    // inputRow() — channel c, row y of image n, inputShape()[3] floats, straight into the plan's own
    // input buffer when only convolutions and the output stages read it, else into a staging tensor —
    // then runInPlace() hands every image's output rows [rowBegin, rowEnd) to `sink` as they are made
    // (a kernel-predicting or residual network's output stage computes no other rows; outputs of other
    // networks are made whole first). No finiteness check; the output tensor is not written.
    float* inputRow(int64_t n, int64_t c, int64_t y);
    void runInPlace(OutputRowSink& sink, int64_t rowBegin, int64_t rowEnd);
    // As runInPlace(), with the input never stored whole: its rows are asked of `source` a band at a time
    // as the first layers and the output stage need them, and used while they are in the caches. For a
    // planar input of one image read only by single-pass convolutions and the output stage
    // (canStreamInput(); dejag-fast is one).
    bool canStreamInput() const;

    // A kernel-predicting network's output stage passes a pixel through — its output the input, bit for
    // bit — where the input's kernel x kernel neighbourhood spans at most `span` in every channel, in
    // groups of 32 columns of a row: the filter, a convex combination of that neighbourhood, could move
    // such a pixel by no more than span, and its logits and softmax are not computed. 0 (the default)
    // turns it off; other networks ignore it. passedThroughFraction(): of the last run's groups.
    void setPassThrough(float span);
    double passedThroughFraction() const;
    void runStreamed(InputRowSource& source, OutputRowSink& sink, int64_t rowBegin, int64_t rowEnd);

    const Shape& inputShape() const;
    const Shape& outputShape() const;
    size_t arenaBytes() const;     // all activations together
    size_t unpackedBytes() const;  // what one buffer per activation would need
    int64_t macs() const;
    InferencePrecision precision() const;
    int bf16Activations() const;  // activations stored as bf16 (0 for Float32)

  private:
    struct Impl;
    std::unique_ptr<Impl> impl_;
};

}  // namespace dejag::nn

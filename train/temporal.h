// dejag/train: training a recurrent (temporal) network — one step unrolled over a batch of sequences,
// with backpropagation through time.
//
// The network's input for frame t (channels, in order; docs/train.md):
//   colour    3         the jittered frame, sRGB-encoded
//   history   3 + S     its own output for frame t - 1 (RGB and S state channels), not yet warped: the
//                       graph warps it by the motion itself; where the history restarts (a sequence's
//                       first frame, a cut) the colour and S zeros
//   motion    2         pixels moved since frame t - 1 (+x right, +y down), 0 where the history restarts
//   jitter    2         the frame's image shift in pixels (+y down), constant planes
//   depth     0 or 2    the frame's depth and the previous frame's (divided by the far plane), for a
//                       network that takes them (2 more input channels); where the history restarts
//                       the previous depth is the frame's
// and its output is the frame's RGB and S state channels, the next frame's history. S = outputs - 3.
#pragma once

#include <cstdint>
#include <vector>

#include "data/sequences.h"
#include "nn/losses.h"
#include "nn/model.h"

namespace dejag::train {

struct TemporalLayout {
    int history = 3;     // RGB + state channels
    bool depth = false;  // depth and previous depth after the jitter
    int inputChannels() const { return 3 + history + 4 + (depth ? 2 : 0); }
    int motionChannel() const { return 3 + history; }
};
// The layout a model's channels give; throws dejag::Error when they are not a temporal network's.
TemporalLayout temporalLayout(const nn::Model& model);

// Frame t's input (N, layout.inputChannels(), P, P) from the batch's frame and the previous frame's output
// (N, layout.history, P, P; null for the first frame).
void makeTemporalInput(nn::Tensor& input, const data::SequenceFrame& frame, const nn::Tensor* previous,
                       const TemporalLayout& layout);

struct TemporalLoss {
    nn::CompositeLoss perFrame = nn::CompositeLoss::parse("0.84*ssim+0.16*l1");
    // Weight of the temporal term: the mean over pixels and channels of |(X_t - X_t-1) - (R_t - R_t-1)|
    // (the flicker of docs/metrics.md against the truth's own change), over the frames whose history
    // continues.
    double temporalWeight = 0.0;
};

// One training step's forward (and backward) over a batch of sequences: the loss is the mean over the
// frames of the per-frame loss on the RGB output, plus the temporal term. The backward pass runs from
// the last frame to the first, recomputing each frame's forward from its saved input (the model keeps
// one frame's activations), and passes each frame's gradient w.r.t. its history input on to the frame
// before: backpropagation through time.
class Unroller {
  public:
    explicit Unroller(nn::Model& model, TemporalLoss loss = {});
    // The loss; with `backward`, its gradient w.r.t. the parameters in model.gradientData(). NaN (and no
    // gradient) when a frame's output is not finite: outputs from that frame on are not made.
    double run(const data::SequenceBatch& batch, bool backward);
    // Frame t's output (N, history, P, P) from the last run.
    const nn::Tensor& output(int t) const { return outputs_[size_t(t)]; }

  private:
    nn::Model& model_;
    TemporalLoss loss_;
    TemporalLayout layout_;
    std::vector<nn::Tensor> inputs_, outputs_;
    nn::Tensor rgb_, dout_, drgb_, carried_;
    std::vector<float> gradientSum_;
};

}  // namespace dejag::train

// dejag/infer: the recurrent network filter (`--method cnn-temporal`): a temporal network trained on
// dejag's sequences (train/temporal.h) run on whole frames, its output the next frame's history.
//
// Per frame: the network's input is the frame's colour, its own previous output (RGB and state, which
// the network warps by the motion itself), the motion and the frame's jitter (train/temporal.h has the
// channel layout); the RGB of its output, clamped to [0, 1], is the filtered frame, and the whole output
// is kept as the history. The history restarts at reset() (a cut, a gap in a sequence's numbering), on a
// size change and on the first frame: there the colour stands in for it and the motion is 0.
//
// The inference plan (nn/inference.h) is made once per frame size: after the first frame of a size,
// apply() allocates nothing.
#pragma once

#include "infer/filter.h"

namespace dejag::infer {

MethodSpec cnnTemporalMethod();

}  // namespace dejag::infer

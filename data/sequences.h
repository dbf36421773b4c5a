// dejag/data: the training sampler of sequence datasets (dejag data generate --sequence-length K). A
// batch is N crops of `frames` consecutive frames, each crop at one place of one sequence across its
// frames (the camera moves under it; the motion vectors say where each pixel was), with one of the 8
// flips and transposes applied to colour, truth, motion and jitter alike. Batch k depends only on the
// seed and k.
#pragma once

#include <cstdint>
#include <string>
#include <vector>

#include "data/dataset.h"
#include "nn/tensor.h"

namespace dejag::data {

struct SequenceOptions {
    int patchSize = 64;
    int batchSize = 8;
    int frames = 0;  // frames per crop (0: the dataset's sequence length)
    Split split = Split::Train;
    bool augment = true;  // flips and transposes
    uint64_t seed = 1;
    std::vector<std::string> families;  // only sequences of these families (empty: all)
    bool depth = false;                 // also keep depth and previous depth (taa-hq reads them)
};

// One frame of a batch. Values of colour and truth are sRGB-encoded in [0, 1]; motion in pixels (+x right,
// +y down: the previous frame's pixel p - motion is where p was); jitter the frame's image shift in pixels
// (+y down), per crop.
struct SequenceFrame {
    nn::Tensor colour, truth;  // (N, 3, P, P)
    nn::Tensor motion;         // (N, 2, P, P)
    // With SequenceOptions::depth: depth and the previous frame's depth (N, 1, P, P), divided by the far
    // plane (render.json's depth_far), what taa-hq's disocclusion test reads; else empty.
    nn::Tensor depth, previousDepth;
    std::vector<float> jitter;  // N pairs (x, y)
    // Per crop: the history restarts at this frame (the crop's first frame, or a cut). Its motion is 0.
    std::vector<uint8_t> fresh;
};
struct SequenceBatch {
    std::vector<SequenceFrame> frames;
    std::vector<int> items;  // manifest index of each crop
};

class SequenceSampler {
  public:
    // Loads every sequence of the split into memory; throws dejag::Error if the folder is not a dataset
    // of sequences, there is none, or a crop does not fit.
    SequenceSampler(const std::string& folder, const SequenceOptions& options);

    SequenceBatch assemble(uint64_t index) const;
    // Sequence i whole (a batch of one: every frame at full size, no flip), what validation scores.
    SequenceBatch whole(int i) const;
    int sequenceCount() const { return int(sequences_.size()); }
    int frames() const { return frames_; }

  private:
    struct Sequence {
        int index = 0, width = 0, height = 0, length = 0;
        std::vector<float> colour, truth, motion;  // per frame, planar: 3, 3 and 2 planes
        std::vector<float> depth;                  // per frame, planar: depth and previous depth / far
        std::vector<float> jitter;                 // per frame (x, y)
        std::vector<uint8_t> cut;                  // per frame
    };
    SequenceOptions options_;
    int frames_ = 0;
    std::vector<Sequence> sequences_;
};

}  // namespace dejag::data

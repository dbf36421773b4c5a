// dejag/data: the training patch sampler. Random crops of (aliased input, truth) pairs from one split
// of a dataset, biased towards patches that contain aliasing (an object-ID or depth discontinuity, or a
// large aliased-vs-truth difference) with a tunable fraction of uniform patches; the 8 flips/rotations
// and mild brightness and hue jitter; an optional grey (luma) mode for the seed2020 replica. Batches are
// assembled on a background thread, and batch k depends only on the seed and k: the same seed gives the
// same batches whatever the timing.
#pragma once

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <functional>
#include <mutex>
#include <string>
#include <thread>
#include <vector>

#include "data/dataset.h"
#include "nn/tensor.h"

namespace dejag::data {

struct PatchOptions {
    int patchSize = 96;
    int batchSize = 16;
    Split split = Split::Train;
    double uniformFraction = 0.25;  // the rest are centred near an aliasing pixel
    bool augment = true;            // flips and 90-degree rotations
    double brightnessJitter = 0.1;  // gain in [1 - b, 1 + b], same for input and truth
    double hueJitter = 0.03;        // per-channel gain in [1 - h, 1 + h]
    bool grayscale = false;         // luma 0.21 R + 0.72 G + 0.07 B of the sRGB-encoded values
    uint64_t seed = 1;
    int prefetch = 2;                   // batches assembled ahead on the background thread
    uint64_t firstBatch = 0;            // next() starts at this batch (a resumed training run)
    std::vector<std::string> families;  // only items of these families (empty: all)
    // Applied to each item's input (sRGB-encoded RGB, (height, width, 3) interleaved) once at loading,
    // after its aliasing sources are found: a method the network runs after (dejag train --input-method).
    std::function<void(float* rgb, int width, int height)> inputTransform;
    // A guide beside the input (dejag train --guide-method): this method's result on each item's input,
    // made once at loading, becomes channels 3..5 of the batch's input (augmented with it). RGB only.
    std::function<void(float* rgb, int width, int height)> guideTransform;
    // Each batch carries its patches' texture masks (the texture region of data/evaluation.h: pixels 3 px
    // or more from every geometric edge whose truth has detail), for the loss's texharm term. Needs the
    // items' id and depth buffers.
    bool textureMask = false;
};

// Values are sRGB-encoded in [0, 1] (the networks see display-referred images, like FXAA).
struct Batch {
    nn::Tensor input, target;  // (N, C, P, P), C = 3 or 1; a guided input: 6 (the frame, the guide)
    nn::Tensor texture;        // (N, 1, P, P): 1 on texture pixels (PatchOptions::textureMask), else empty
    std::vector<int> items;    // manifest index of each patch
    double edgeFraction = 0;   // fraction of the batch's pixels marked as aliasing sources
};

class PatchSampler {
  public:
    // Loads every item of the split into memory; throws dejag::Error if there is none or a patch does
    // not fit in an item.
    PatchSampler(const std::string& folder, const PatchOptions& options);
    ~PatchSampler();
    PatchSampler(const PatchSampler&) = delete;
    PatchSampler& operator=(const PatchSampler&) = delete;

    Batch next();  // the next batch, in order
    int itemCount() const { return int(items_.size()); }
    int channels() const { return options_.grayscale ? 1 : 3; }  // of the target (and the frame)

    // Batch `index` computed on the calling thread (what next() returns as its index-th batch).
    Batch assemble(uint64_t index) const;

  private:
    struct Item {
        int index = 0, width = 0, height = 0;
        std::vector<uint16_t> input, truth;  // sRGB-encoded RGB, value * 65535
        std::vector<uint16_t> guide;         // the guide method's result on the input (if any), as input
        std::vector<uint8_t> aliasing;       // 1 where a pixel is an aliasing source
        std::vector<uint8_t> texture;        // 1 on a texture pixel (PatchOptions::textureMask)
        std::vector<int> aliasingPixels;     // their positions y * width + x
    };
    void produce();

    PatchOptions options_;
    std::vector<Item> items_;
    std::thread worker_;
    std::mutex mutex_;
    std::condition_variable changed_;
    std::deque<Batch> ready_;
    uint64_t produced_ = 0;
    bool stopping_ = false;
};

}  // namespace dejag::data

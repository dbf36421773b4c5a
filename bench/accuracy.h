// dejag/bench: the numerical-stress figures of `dejag bench stability` that run a whole network —
// accumulation error of the float32 inference on a large frame against a double-precision forward, and
// what denormal inputs cost (FTZ/DAZ on, as dejag runs, and off, for contrast).
#pragma once

#include <string>
#include <vector>

namespace dejag::bench {

// A deterministic RGB test frame in [0, 1] (sRGB-encoded values, planar (3, H, W)): hard edges at many
// angles, a zone plate (texture at every frequency up to Nyquist), thin lines and smooth gradients.
std::vector<float> accuracyTestFrame(int width, int height);

struct AccumulationResult {
    std::string model;
    int width = 0, height = 0;
    double normwise = 0;  // |y32 - y64|_2 / |y64|_2 over the output
    double largest = 0;   // max |y32 - y64| / max |y64|
    double floatMs = 0;   // the float32 inference (one run after a warm-up)
    double doubleSeconds = 0;
};
// The model's float32 inference plan (the filter's kernels, this SIMD level and thread count) against
// nn::forwardInDouble on accuracyTestFrame(width, height) (a grey model sees its luma).
AccumulationResult benchAccumulation(const std::string& modelPath, int width, int height);

struct DenormalResult {
    int width = 0, height = 0, threads = 0, repeat = 0;
    double normalMs = 0, denormalMs = 0;                // medians, FTZ/DAZ on (every dejag thread)
    double normalMsNoFlush = 0, denormalMsNoFlush = 0;  // one thread with FTZ/DAZ off
};
// Inference on the test frame and on the same frame scaled into the denormal range (x 1e-39).
DenormalResult benchDenormals(const std::string& modelPath, int width, int height, int repeat);

// Determinism: `steps` training steps of the built-in fast network (seed 1, Adam, 1 - SSIM + L1, batches
// cut from the test frame) run twice at each thread count, and the inference of the model file on the
// test frame at each thread count.
struct DeterminismResult {
    int steps = 0;
    std::vector<int> threadCounts;
    bool trainingRepeatable = true;     // same seed and threads: bit-identical weights, every thread count
    bool inferenceRepeatable = true;    // same input and threads: bit-identical output
    double trainingAcrossThreads = 0;   // largest |w_a - w_b| / max |w| between thread counts
    double inferenceAcrossThreads = 0;  // largest |y_a - y_b| / max |y| between thread counts
};
DeterminismResult benchDeterminism(const std::string& modelPath, int steps, int width, int height);

}  // namespace dejag::bench

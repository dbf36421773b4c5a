// dejag/bench: `dejag bench stability` — property-based gradient checks of every nn layer and loss.
//
// For each of N random configurations (shapes, strides, paddings, dilations, biases, factors, data
// ranges), round-robin over the layer and loss kinds: the backward in double against central finite
// differences of L = sum(y * r) (relative error per coordinate, |numeric - analytic| / (|numeric| +
// |analytic|), the denominator at least a thousandth of the gradient's largest component; for the
// piecewise-linear kinds — max
// pooling, ReLU-like activations, L1 — a coordinate whose two one-sided differences disagree sits on a
// kink and is counted as skipped, not checked), and the float32 forward and backward against the double
// ones on the same inputs (normwise relative error).
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace dejag::bench {

struct StabilityOptions {
    int configurations = 1000;
    uint64_t seed = 1;
    double tolerance = 1e-6;  // for the double gradient checks
};

struct StabilityRow {
    std::string kind;
    int configurations = 0, coordinates = 0, kinks = 0, overTolerance = 0;
    double worstGradient = 0, medianGradient = 0;  // double backward vs finite differences
    double worstFloat = 0;                         // float32 vs double, outputs and gradients
};

std::vector<StabilityRow> benchStability(const StabilityOptions& options);

// The 1 - SSIM loss on degenerate patches (docs/metrics.md: finite and continuous): constant images (zero
// variance), a single bright pixel, HDR values up to 1e4, tiny values (1e-8), a checkerboard at Nyquist.
// For each, in double: the loss and gradient are finite; the gradient's derivative along a random
// direction matches the central difference; and the loss is continuous there — the largest
// |L(t + dt) - L(t)| / dt over a sweep of t around the patch, at dt = h and dt = h / 100, which a jump
// would multiply by 100 (continuous: it stays bounded, ratio <= 2). Both checks allow the loss's own
// rounding (64 ulps of 1 over the step): near a perfect match 1 - SSIM is known to ~1e-16, no better.
struct SsimDegenerateRow {
    std::string patch;
    double loss = 0;
    bool finite = false;
    double directionalError = 0;      // |central difference - analytic| / max(|both|, floor)
    double slope = 0, slopeFine = 0;  // largest |dL| / dt at dt = h and h / 100
    bool passed = false;
};
std::vector<SsimDegenerateRow> ssimDegenerateChecks();

}  // namespace dejag::bench

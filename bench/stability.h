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

}  // namespace dejag::bench

// The error measure of dejag's PyTorch goldens (tests/nn/ops_test.cpp, golden_test.cpp): max |got - want|
// over the tensor divided by max |want| (torch's values in float64).
#pragma once

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace dejag::nn {

inline double relativeError(const std::vector<float>& got, const std::vector<double>& want) {
    EXPECT_EQ(got.size(), want.size());
    double worst = 0.0, scale = 0.0;
    for (size_t i = 0; i < std::min(got.size(), want.size()); ++i) {
        worst = std::max(worst, std::abs(double(got[i]) - want[i]));
        scale = std::max(scale, std::abs(want[i]));
    }
    return scale > 0 ? worst / scale : worst;
}

}  // namespace dejag::nn

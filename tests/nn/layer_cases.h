// The layer level of the op harness (tests/nn/ops_test.cpp): the functions of nn/layers.h with their
// descriptors, each case run in float against its PyTorch golden (tests/golden/make_nn_golden.py) when it
// has one, and in double against central differences. A case holds a generic forward and backward, so the
// same lambda serves both precisions.
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

namespace dejag::nn::harness {

template <class T>
struct LayerCall {
    std::vector<const T*> in;  // the differentiable arguments: the inputs, then the weight and bias
    T* out = nullptr;
};
template <class T>
struct LayerGradient {
    std::vector<const T*> in;
    const T* out = nullptr;   // the forward's output
    const T* dOut = nullptr;  // the gradient arriving at it
    std::vector<T*> dIn;      // per argument (null: not differentiated)
};

struct LayerCase {
    std::string label;   // what it is and its descriptor, printed when a check fails
    std::string golden;  // the fixture's name in tests/golden/nn ("" for none)
    // The arguments' names (their fixture keys: "input", "weight", "bias", "logits") and sizes.
    std::vector<std::string> names;
    std::vector<size_t> sizes;
    size_t outputSize = 0;
    bool piecewise = false;  // max or ReLU kinks
    double inputLow = -1, inputHigh = 1;
    std::function<void(const LayerCall<float>&)> forwardFloat;
    std::function<void(const LayerGradient<float>&)> backwardFloat;
    std::function<void(const LayerCall<double>&)> forwardDouble;
    std::function<void(const LayerGradient<double>&)> backwardDouble;
};

inline void PrintTo(const LayerCase& c, std::ostream* os) {
    *os << c.label;
}

// forward(call) and backward(gradient) generic lambdas over float and double.
template <class F, class B>
LayerCase layerCase(std::string label, std::vector<std::string> names, std::vector<size_t> sizes,
                    size_t outputSize, F forward, B backward) {
    LayerCase c;
    c.label = std::move(label), c.names = std::move(names), c.sizes = std::move(sizes);
    c.outputSize = outputSize;
    c.forwardFloat = forward, c.forwardDouble = forward;
    c.backwardFloat = backward, c.backwardDouble = backward;
    return c;
}

// One case per golden fixture of a layer; the random shapes the gradient checks draw.
std::vector<LayerCase> goldenLayerCases();
std::vector<LayerCase> randomLayerCases();

}  // namespace dejag::nn::harness

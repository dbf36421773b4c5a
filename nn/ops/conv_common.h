// dejag/nn: what conv2d and conv_transpose2d read from their JSON alike (nn/ops/conv2d.cpp,
// nn/ops/conv_transpose2d.cpp).
#pragma once

#include "nn/ops.h"

namespace dejag::nn {

// out_channels, kernel, stride, dilation, bias, padding, output_padding, init_scale and the activation,
// each bounded; appends the weight and the bias.
void parseConvolution(GraphNode& n, const OpParse& p, bool transposed);
OpCard convolutionCard(const GraphNode& n);

}  // namespace dejag::nn

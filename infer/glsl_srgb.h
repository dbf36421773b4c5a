// dejag/infer: the sRGB curves of base/srgb.h as GLSL functions, for the methods' GPU forms: the same
// polynomial in the mantissa times a factor by exponent, in the same float operations as the SIMD
// kernels' decodeSrgbBy / encodeSrgbBy (every one `precise`, none fused), so a pass decodes and encodes as
// the CPU filter does.
#pragma once

#include <string>

namespace dejag::infer {

// GLSL source defining `float decodeSrgb(float v)` (sRGB-encoded to linear, v clamped to [0, 1], a NaN
// read as 0) by the curve of degree `decodeDegree`, and `float encodeSrgb(float x)` (linear to
// sRGB-encoded, x clamped to [0, 1)) by the curve of degree `encodeDegree` (each 1..7).
std::string glslSrgbFunctions(int decodeDegree, int encodeDegree);

}  // namespace dejag::infer

// dejag/base: the luma every stage uses — grey networks' input, their training targets, the region
// masks, the CNN gate: 0.21 R + 0.72 G + 0.07 B of sRGB-encoded values (docs/seed-cnn.md: the seed
// network's grey input). One definition, so a grey model sees in dejag filter what it saw in training.
#pragma once

namespace dejag {

inline constexpr float kLumaRed = 0.21f, kLumaGreen = 0.72f, kLumaBlue = 0.07f;

// For floats and for SIMD vectors of floats alike (the same products and sums in the same order, so
// every SIMD level rounds as the scalar code does where contraction is off).
template <class V>
inline V luma(V r, V g, V b) {
    return kLumaRed * r + kLumaGreen * g + kLumaBlue * b;
}
inline float luma(const float* rgb) {
    return luma(rgb[0], rgb[1], rgb[2]);
}

}  // namespace dejag

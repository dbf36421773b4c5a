// dejag/base: the sRGB curves by exponent and mantissa (base/srgb_simd.h has the idea and the SIMD forms),
// and the one sRGB encoding every stage uses (data/image.h's linearToSrgb): the degree-7 curve, within 2e-7
// of the double-precision formula, in float operations that every form repeats exactly: the scalar code
// here, the SIMD kernels, and the GLSL passes that take a rendered frame on the GPU (infer/glsl_filter.h),
// so a method gives the same bits on a frame encoded by any of them.
#pragma once

#include <cmath>
#include <cstdint>
#include <cstring>
#include <utility>

namespace dejag {

inline constexpr float kSrgbDecodeKnee = 0.04045f, kSrgbEncodeKnee = 0.0031308f;

struct PowerCurve {
    alignas(64) float factor[16];  // 2^(e p) (times `gain`), by biased exponent mod 16
    float c[8] = {};               // the polynomial's coefficients in m - 1.5, lowest first
    int degree = 0;
};

// x^p's curve (times gain) for x in (0, 1] by a polynomial of `degree` (at most 7).
inline PowerCurve fitPower(double p, int degree, double gain) {
    PowerCurve curve{};
    curve.degree = degree;
    const int n = degree + 1;
    double m[8][9] = {};
    for (int i = 0; i < n; ++i) {
        const double s = 0.5 * std::cos(M_PI * (2 * i + 1) / (2 * n));  // node: m = 1.5 + s
        for (int j = 0; j < n; ++j) m[i][j] = std::pow(s, j);
        m[i][n] = std::pow(1.5 + s, p);
    }
    for (int col = 0; col < n; ++col) {  // Gauss-Jordan with partial pivoting
        int pivot = col;
        for (int r = col + 1; r < n; ++r)
            if (std::abs(m[r][col]) > std::abs(m[pivot][col])) pivot = r;
        std::swap(m[col], m[pivot]);
        for (int r = 0; r < n; ++r)
            if (r != col) {
                const double k = m[r][col] / m[col][col];
                for (int j = col; j <= n; ++j) m[r][j] -= k * m[col][j];
            }
    }
    for (int j = 0; j < n; ++j) curve.c[j] = float(m[j][n] / m[j][j]);
    for (int biased = 112; biased < 128; ++biased)  // e = biased - 127 in [-15, 0]
        curve.factor[biased & 15] = float(gain * std::pow(2.0, p * (biased - 127)));
    return curve;
}

// The curves at degree 7 (within 2e-7 of the double-precision formulas, rounding included), fitted once.
inline const PowerCurve& srgbDecodeCurve7() {
    static const PowerCurve curve = fitPower(2.4, 7, 1.0);
    return curve;
}
inline const PowerCurve& srgbEncodeCurve7() {
    static const PowerCurve curve = fitPower(1 / 2.4, 7, 1.055);
    return curve;
}

// Linear light to sRGB-encoded by the degree-7 curve, with the same operations as encodeSrgbBy<7> of
// base/srgb_simd.h: 12.92 x at and below the knee, the curve below 1, the formula (std::pow) from 1 on
// (which callers clamp to 1); NaN stays NaN.
inline float encodeSrgb(float x) {
    if (!(x > kSrgbEncodeKnee)) return x != x ? x : x * 12.92f;
    if (x >= 1.0f) return 1.055f * std::pow(x, 1.0f / 2.4f) - 0.055f;
    const PowerCurve& curve = srgbEncodeCurve7();
    int32_t bits;
    std::memcpy(&bits, &x, sizeof bits);
    const int32_t mantissa = (bits & 0x7fffff) | 0x3f800000;
    float m;
    std::memcpy(&m, &mantissa, sizeof m);
    const float s = m - 1.5f;
    float poly = curve.c[7];
    for (int j = 6; j >= 0; --j) poly = poly * s + curve.c[j];
    return curve.factor[(bits >> 23) & 15] * poly - 0.055f;
}

}  // namespace dejag

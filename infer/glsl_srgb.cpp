// The sRGB curves in GLSL: see infer/glsl_srgb.h.
#include "infer/glsl_srgb.h"

#include "base/error.h"
#include "base/srgb.h"
#include "nn/glsl.h"

namespace dejag::infer {
namespace {

std::string floats(const float* values, int count) {
    std::string text;
    for (int i = 0; i < count; ++i) text += (i ? ", " : "") + nn::glslFloat(values[i]);
    return text;
}

}  // namespace

std::string glslSrgbFunctions(int decodeDegree, int encodeDegree) {
    if (decodeDegree < 1 || decodeDegree > 7 || encodeDegree < 1 || encodeDegree > 7)
        throw Error("the sRGB curves' degrees are 1..7");
    const PowerCurve decode = decodeDegree == 7 ? srgbDecodeCurve7() : fitPower(2.4, decodeDegree, 1.0);
    const PowerCurve encode = encodeDegree == 7 ? srgbEncodeCurve7() : fitPower(1 / 2.4, encodeDegree, 1.055);
    return "const float SRGB_DECODE_C[8] = float[](" + floats(decode.c, 8) +
           ");\nconst float SRGB_DECODE_FACTOR[16] = float[](" + floats(decode.factor, 16) +
           ");\nconst float SRGB_ENCODE_C[8] = float[](" + floats(encode.c, 8) +
           ");\nconst float SRGB_ENCODE_FACTOR[16] = float[](" + floats(encode.factor, 16) +
           ");\nconst int SRGB_DECODE_DEGREE = " + std::to_string(decodeDegree) +
           ", SRGB_ENCODE_DEGREE = " + std::to_string(encodeDegree) + ";\n" +
           "const float SRGB_DECODE_LINEAR = " + nn::glslFloat(1.0f / 12.92f) +
           ", SRGB_DECODE_SCALE = " + nn::glslFloat(1.0f / 1.055f) +
           ", SRGB_DECODE_OFFSET = " + nn::glslFloat(0.055f / 1.055f) +
           ", SRGB_DECODE_KNEE = " + nn::glslFloat(kSrgbDecodeKnee) +
           ", SRGB_ENCODE_KNEE = " + nn::glslFloat(kSrgbEncodeKnee) +
           ", SRGB_ENCODE_TOP = " + nn::glslFloat(0.99999994f) + ";\n" + R"(
// x^p as factor(exponent) * polynomial(mantissa - 1.5), x > 0 a normal float.
float srgbPower(float x, const float c[8], int degree, const float factor[16]) {
    int bits = floatBitsToInt(x);
    precise float s = intBitsToFloat((bits & 0x7fffff) | 0x3f800000) - 1.5;
    precise float poly = c[degree];
    for (int j = degree - 1; j >= 0; --j) poly = poly * s + c[j];
    precise float v = factor[(bits >> 23) & 15] * poly;
    return v;
}
float decodeSrgb(float v) {
    v = isnan(v) ? 0.0 : clamp(v, 0.0, 1.0);
    precise float x = v * SRGB_DECODE_SCALE + SRGB_DECODE_OFFSET;
    precise float linear = v * SRGB_DECODE_LINEAR;
    return v <= SRGB_DECODE_KNEE ? linear : srgbPower(x, SRGB_DECODE_C, SRGB_DECODE_DEGREE, SRGB_DECODE_FACTOR);
}
float encodeSrgb(float x) {
    x = isnan(x) ? 0.0 : clamp(x, 0.0, SRGB_ENCODE_TOP);
    precise float linear = x * 12.92;
    precise float curve = srgbPower(x, SRGB_ENCODE_C, SRGB_ENCODE_DEGREE, SRGB_ENCODE_FACTOR) - 0.055;
    return x <= SRGB_ENCODE_KNEE ? linear : curve;
}
)";
}

}  // namespace dejag::infer

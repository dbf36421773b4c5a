// The kernel filter over one row (see nn/kernel_filter_kernels.h), compiled once per SIMD level: the
// pixels whose whole neighbourhood lies inside the row are done kFloatLanes at a time, the few at each
// end (edges repeated) one at a time with the same arithmetic.
#include "nn/kernel_filter_kernels.h"

#include <algorithm>
#include <cstring>

#include "base/simd_vector.h"

namespace dejag::nn::DEJAG_SIMD_NAMESPACE {
using namespace ::dejag::DEJAG_SIMD_NAMESPACE;  // VFloat, kFloatLanes, loadu, storeu, splat
namespace {

#if defined(DEJAG_SIMD_LEVEL_scalar)
using VInt = int32_t;
#else
typedef int32_t VInt __attribute__((vector_size(kFloatLanes * sizeof(int32_t))));
#endif

template <class To, class From>
inline To bitCast(From v) {
    static_assert(sizeof(To) == sizeof(From));
    To to;
    std::memcpy(&to, &v, sizeof(To));
    return to;
}

// e^x for x <= 0 (the softmax's logits minus their maximum), relative error about 2e-7: x = n ln 2 + r
// with |r| <= ln 2 / 2, e^r by its degree-6 Taylor polynomial, 2^n put in the exponent bits. Below -87
// the result is e^-87 (1.6e-38) instead of a denormal or zero: a weight that small is zero to the sum.
template <class V, class I>
inline V expNonPositive(V x) {
    const V magic = splat<V>(12582912.0f);  // 1.5 * 2^23: adding it rounds to an integer
    x = x < -87.0f ? splat<V>(-87.0f) : x;
    const V shifted = x * 1.44269504f + magic;
    const V n = shifted - magic;
    const V r = x - n * 0.693145752f - n * 1.42860677e-6f;  // ln 2 in two parts
    V p = splat<V>(1.0f / 720.0f);
    p = p * r + 1.0f / 120.0f;
    p = p * r + 1.0f / 24.0f;
    p = p * r + 1.0f / 6.0f;
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    const I exponent = (bitCast<I>(shifted) - bitCast<I>(magic) + 127) << 23;
    return p * bitCast<V>(exponent);
}

// The pixels from x (as many as V has lanes), all of whose taps x + dx lie in [0, width) unless `clampX`.
template <class V, class I, int K>
inline void filterPixels(const KernelFilterRowArgs& a, int64_t x, bool clampX) {
    constexpr int kTaps = K * K, kRadius = K / 2, kCentre = kTaps / 2;
    V weight[kTaps];
    V largest = splat<V>(-3.4e38f);
    for (int j = 0; j < kTaps; ++j) {
        weight[j] = loadu<V>(a.logits + j * a.width + x);
        if (j == kCentre) weight[j] = weight[j] + a.centreBias;
        largest = largest < weight[j] ? weight[j] : largest;
    }
    V sum = splat<V>(0.0f);
    for (int j = 0; j < kTaps; ++j) sum = sum + (weight[j] = expNonPositive<V, I>(weight[j] - largest));
    const V scale = 1.0f / sum;
    int64_t column[K];
    for (int dx = -kRadius; dx <= kRadius; ++dx)
        column[dx + kRadius] = clampX ? std::clamp<int64_t>(x + dx, 0, a.width - 1) : x + dx;
    for (int c = 0; c < a.channels; ++c) {
        V value = splat<V>(0.0f);
        for (int dy = 0; dy < K; ++dy) {
            const float* row = a.in[c * K + dy];
            for (int dx = 0; dx < K; ++dx) value = value + weight[dy * K + dx] * loadu<V>(row + column[dx]);
        }
        storeu(a.out[c] + x, value * scale);
    }
}

template <int K>
void filterRow(const KernelFilterRowArgs& a) {
    constexpr int kRadius = K / 2;
    const int64_t W = a.width;
    int64_t x = 0;
    for (; x < std::min<int64_t>(kRadius, W); ++x) filterPixels<float, int32_t, K>(a, x, true);
    for (; x + kFloatLanes + kRadius <= W; x += kFloatLanes) filterPixels<VFloat, VInt, K>(a, x, false);
    for (; x < W; ++x) filterPixels<float, int32_t, K>(a, x, true);
}

}  // namespace

void kernelFilterRow(const KernelFilterRowArgs& args) {
    switch (args.kernel) {
        case 1:
            return filterRow<1>(args);
        case 3:
            return filterRow<3>(args);
        case 5:
            return filterRow<5>(args);
        case 7:
            return filterRow<7>(args);
        default:
            return;
    }
}

}  // namespace dejag::nn::DEJAG_SIMD_NAMESPACE

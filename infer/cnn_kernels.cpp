#include "infer/cnn_kernels.h"

#include <algorithm>
#include <cmath>

#include "infer/pixel_simd.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {
using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

void splitRgbRow(const float* pixels, int channels, int64_t count, float* r, float* g, float* b) {
    int64_t x = 0;
    if (channels == 3) {
        for (; x + kFloatLanes <= count; x += kFloatLanes) {
            VFloat vr, vg, vb;
            loadRgb(pixels + 3 * x, vr, vg, vb);
            storeu(r + x, vr), storeu(g + x, vg), storeu(b + x, vb);
        }
    }
    for (const float* p = pixels + x * channels; x < count; ++x, p += channels)
        r[x] = p[0], g[x] = p[1], b[x] = p[2];
}

void joinRgbRowClamped(const float* r, const float* g, const float* b, int64_t count, int channels,
                       float* pixels) {
    int64_t x = 0;
    if (channels == 3) {
        for (; x + kFloatLanes <= count; x += kFloatLanes)
            storeRgb(pixels + 3 * x, clamp01(loadu<VFloat>(r + x)), clamp01(loadu<VFloat>(g + x)),
                     clamp01(loadu<VFloat>(b + x)));
    }
    for (float* p = pixels + x * channels; x < count; ++x, p += channels) {
        p[0] = std::clamp(r[x], 0.0f, 1.0f);
        p[1] = std::clamp(g[x], 0.0f, 1.0f);
        p[2] = std::clamp(b[x], 0.0f, 1.0f);
    }
}

void clampRgbRow(const float* pixels, int channels, int64_t count, float* out) {
    int64_t x = 0;
    if (channels == 3) {  // R G B R G B ...: the values in order
        for (; x + kFloatLanes <= 3 * count; x += kFloatLanes)
            storeu(out + x, clamp01(loadu<VFloat>(pixels + x)));
        for (; x < 3 * count; ++x) out[x] = std::clamp(pixels[x], 0.0f, 1.0f);
        return;
    }
    for (; x < count; ++x)
        for (int c = 0; c < 3; ++c) out[x * channels + c] = std::clamp(pixels[x * channels + c], 0.0f, 1.0f);
}

namespace {
// Luma as the gate computes it everywhere (this file is built without contracted multiply-adds, so
// every level rounds as the scalar code does).
template <class V>
inline V lumaOf(V r, V g, V b) {
    return 0.21f * r + 0.72f * g + 0.07f * b;
}
inline float lumaAt(const float* p) {
    return lumaOf(p[0], p[1], p[2]);
}
}  // namespace

bool rowHasLumaStep(const float* row, const float* below, int channels, int64_t width, int64_t first,
                    int64_t last, float threshold) {
    int64_t x = first;
#if !defined(DEJAG_SIMD_LEVEL_scalar)
    if (channels == 3) {
        // Vectors of pixels whose right neighbours all exist.
        for (; x + kFloatLanes <= last + 1 && x + kFloatLanes < width; x += kFloatLanes) {
            VFloat r, g, b;
            loadRgb(row + 3 * x, r, g, b);
            const VFloat here = lumaOf(r, g, b);
            loadRgb(row + 3 * (x + 1), r, g, b);
            const VFloat right = lumaOf(r, g, b);
            loadRgb(below + 3 * x, r, g, b);
            const VFloat down = lumaOf(r, g, b);
            if (any(vabs(right - here) > threshold) || any(vabs(down - here) > threshold)) return true;
        }
    }
#endif
    for (; x <= last; ++x) {
        const float here = lumaAt(row + x * channels);
        const float right = x + 1 < width ? lumaAt(row + (x + 1) * channels) : here;
        if (std::abs(right - here) > threshold || std::abs(lumaAt(below + x * channels) - here) > threshold)
            return true;
    }
    return false;
}

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

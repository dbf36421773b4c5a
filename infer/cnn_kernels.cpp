#include "infer/cnn_kernels.h"

#include <algorithm>

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

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

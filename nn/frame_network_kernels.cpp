#include "nn/frame_network_kernels.h"

#include <algorithm>

#include "base/pixel_simd.h"

namespace dejag::nn::DEJAG_SIMD_NAMESPACE {
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

}  // namespace dejag::nn::DEJAG_SIMD_NAMESPACE

#include "infer/cnn_temporal_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "base/pixel_simd.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {
using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

namespace {
// A row of frameWidth floats (or zeros) into `out`, then its last value repeated to width.
void padRow(const float* in, float* out, int64_t frameWidth, int64_t width) {
    if (in)
        std::memcpy(out, in, sizeof(float) * size_t(frameWidth));
    else
        std::fill_n(out, frameWidth, 0.0f);
    std::fill(out + frameWidth, out + width, out[frameWidth - 1]);
}
}  // namespace

void temporalPrepassRow(const TemporalPrepassRow& a) {
    const int64_t frameW = a.frameWidth, W = a.width;
    const int C = a.channels;
    int64_t x = 0;
#if !defined(DEJAG_SIMD_LEVEL_scalar)
    if (C == 3)
        for (; x + kFloatLanes <= frameW; x += kFloatLanes) {
            VFloat r, g, b;
            loadRgb(a.colour + 3 * x, r, g, b);
            storeu(a.planes[0] + x, r), storeu(a.planes[1] + x, g), storeu(a.planes[2] + x, b);
        }
#endif
    for (; x < frameW; ++x)
        for (int c = 0; c < 3; ++c) a.planes[c][x] = a.colour[x * C + c];
    for (int c = 0; c < 3; ++c) std::fill(a.planes[c] + frameW, a.planes[c] + W, a.planes[c][frameW - 1]);
    if (a.motionOut) {
        std::memcpy(a.motionOut, a.motion, sizeof(float) * 2 * size_t(frameW));
        for (int64_t p = frameW; p < W; ++p)
            a.motionOut[2 * p] = a.motion[2 * frameW - 2], a.motionOut[2 * p + 1] = a.motion[2 * frameW - 1];
    }
    if (a.moving) {
        const float t = a.stillMotion;
        x = 0;
#if !defined(DEJAG_SIMD_LEVEL_scalar)
        typedef uint8_t Bytes __attribute__((vector_size(kFloatLanes)));
        for (; x + kFloatLanes <= frameW; x += kFloatLanes) {
            VFloat mx, my;
            loadPairs(a.motion + 2 * x, mx, my);
            const VInt still = (vabs(mx) <= t) & (vabs(my) <= t);  // (false for a NaN)
            const Bytes moving = __builtin_convertvector(~still & 1, Bytes);
            std::memcpy(a.moving + x, &moving, sizeof(moving));
        }
#endif
        for (; x < frameW; ++x)
            a.moving[x] = !(std::fabs(a.motion[2 * x]) <= t && std::fabs(a.motion[2 * x + 1]) <= t);
        std::fill(a.moving + frameW, a.moving + W, a.moving[frameW - 1]);
    }
    if (a.depthOut) padRow(a.depth, a.depthOut, frameW, W);
    if (a.previousDepthOut) padRow(a.previousDepth, a.previousDepthOut, frameW, W);
}

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

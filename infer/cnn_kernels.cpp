#include "infer/cnn_kernels.h"

#include <algorithm>
#include <cmath>

#include "base/luma.h"
#include "base/pixel_simd.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {
using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

namespace {
// Luma as every stage computes it (base/luma.h; this file is built without contracted multiply-adds, so
// every level rounds as the scalar code does).
using ::dejag::luma;
inline float lumaAt(const float* p) {
    return luma(p);
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
            const VFloat here = luma(r, g, b);
            loadRgb(row + 3 * (x + 1), r, g, b);
            const VFloat right = luma(r, g, b);
            loadRgb(below + 3 * x, r, g, b);
            const VFloat down = luma(r, g, b);
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

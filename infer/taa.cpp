#include "infer/taa.h"

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/thread_pool.h"
#include "infer/taa_kernels.h"

namespace dejag::infer {

Taa::Taa(const TaaOptions& options) : options_(options) {
    if (!(options.feedbackMin >= 0 && options.feedbackMin <= options.feedbackMax && options.feedbackMax < 1))
        throw Error("TAA feedback must satisfy 0 <= min <= max < 1");
    if (!(options.motionBlurScale >= 0 && options.motionBlurScale <= 100) ||
        options.motionBlurMaxSamples < 1 || options.motionBlurMaxSamples > 256)
        throw Error("TAA motion blur: the scale must be in [0, 100] and the samples in 1..256");
}

void Taa::apply(const TaaFrame& f, float* out) {
    const int W = f.width, H = f.height;
    if (W < 1 || H < 1 || !f.colour || !f.depth || !f.motion)
        throw Error("TAA needs colour, depth and motion buffers");
    const bool improved = options_.improved;
    if (improved && (!f.albedo || !f.ids || !f.previousDepth))
        throw Error("the Sobel-improved TAA needs albedo, IDs and the previous depth too");
    if (size_t(W) * size_t(H) * 3 > size_t(INT32_MAX))
        throw Error("TAA: frame too large (" + std::to_string(W) + "x" + std::to_string(H) + ")");
    // Four bands per thread balance the load; each band recomputes a few rows of its neighbours.
    const int bands = std::min(H, 4 * threadCount());
    const bool fresh = W != width_ || H != height_;
    if (fresh) {
        width_ = W, height_ = H;
        stride_ = (size_t(W) + 15) / 16 * 16 + 16;  // full vectors at the end of a row stay inside it
        const size_t plane = stride_ * size_t(H);
        // (+32: the kernel's windowed reads may run past the last row's end; what they read there is unused)
        history_.assign(plane * 3 + 32, 0.0f), nextHistory_.assign(plane * 3 + 32, 0.0f);
        sobel_.assign(plane + 32, 0.0f), nextSobel_.assign(plane + 32, 0.0f);
    }
    if (fresh || bands != bands_) {
        bands_ = bands;
        scratch_.assign(taaScratchFloats(W) * size_t(bands), 0.0f);
    }
    TaaBandInputs in;
    in.width = W, in.height = H;
    in.colour = f.colour, in.albedo = f.albedo, in.depth = f.depth, in.motion = f.motion;
    in.ids = f.ids, in.previousDepth = f.previousDepth;
    in.history = history_.data(), in.nextHistory = nextHistory_.data();
    in.sobelHistory = sobel_.data(), in.nextSobelHistory = nextSobel_.data();
    in.stride = stride_, in.planeFloats = stride_ * size_t(H);
    in.out = out;
    in.improved = improved, in.sharpen = options_.sharpen, in.fresh = fresh;
    in.feedbackMin = options_.feedbackMin, in.feedbackMax = options_.feedbackMax;
    in.depthThreshold = options_.depthThreshold;
    const size_t scratchFloats = taaScratchFloats(W);
    parallelFor(0, bands, 1, [&](int64_t first, int64_t last) {
        for (int64_t b = first; b < last; ++b) {
            const int y0 = int(int64_t(H) * b / bands), y1 = int(int64_t(H) * (b + 1) / bands);
            DEJAG_SIMD_CALL(taaBand, in, y0, y1, scratch_.data() + size_t(b) * scratchFloats);
        }
    });
    std::swap(history_, nextHistory_);
    if (improved) std::swap(sobel_, nextSobel_);
    if (options_.motionBlur) blurAlongMotion(f, out);
}

void Taa::blurAlongMotion(const TaaFrame& f, float* out) {
    const int W = f.width, H = f.height;
    const size_t floats = size_t(W) * size_t(H) * 3;
    if (unblurred_.size() != floats) unblurred_.assign(floats, 0.0f);  // on a size change only
    parallelFor(0, H, 16, [&](int64_t first, int64_t last) {
        std::copy(out + size_t(first) * size_t(W) * 3, out + size_t(last) * size_t(W) * 3,
                  unblurred_.begin() + std::ptrdiff_t(size_t(first) * size_t(W) * 3));
    });
    TaaBlurInputs in;
    in.width = W, in.height = H;
    in.source = unblurred_.data(), in.motion = f.motion, in.out = out;
    in.scale = options_.motionBlurScale, in.maxSamples = options_.motionBlurMaxSamples;
    parallelFor(0, H, 4, [&](int64_t first, int64_t last) {
        DEJAG_SIMD_CALL(taaMotionBlurRows, in, int(first), int(last));
    });
}

}  // namespace dejag::infer

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
    const float* source = unblurred_.data();
    // Bilinear, clamp to edge, at pixel coordinates (pixel (i, j)'s centre at (i + 0.5, j + 0.5)).
    auto sample = [&](float px, float py, float rgb[3]) {
        // (Positions far outside read the border; clamped first so the conversions stay in range.)
        const float fx = std::clamp(px, -1.0f, float(W) + 1.0f) - 0.5f,
                    fy = std::clamp(py, -1.0f, float(H) + 1.0f) - 0.5f;
        const float x0f = std::floor(fx), y0f = std::floor(fy);
        const float tx = fx - x0f, ty = fy - y0f;
        const int x0 = int(x0f), y0 = int(y0f);
        const int xa = std::clamp(x0, 0, W - 1), xb = std::clamp(x0 + 1, 0, W - 1);
        const int ya = std::clamp(y0, 0, H - 1), yb = std::clamp(y0 + 1, 0, H - 1);
        const float* a = source + (size_t(ya) * size_t(W) + size_t(xa)) * 3;
        const float* b = source + (size_t(ya) * size_t(W) + size_t(xb)) * 3;
        const float* c = source + (size_t(yb) * size_t(W) + size_t(xa)) * 3;
        const float* d = source + (size_t(yb) * size_t(W) + size_t(xb)) * 3;
        for (int k = 0; k < 3; ++k) {
            const float top = a[k] + tx * (b[k] - a[k]), bottom = c[k] + tx * (d[k] - c[k]);
            rgb[k] = top + ty * (bottom - top);
        }
    };
    const float scale = options_.motionBlurScale;
    const int maxSamples = options_.motionBlurMaxSamples;
    parallelFor(0, H, 4, [&](int64_t first, int64_t last) {
        for (int64_t y = first; y < last; ++y)
            for (int x = 0; x < W; ++x) {
                const size_t i = size_t(y) * size_t(W) + size_t(x);
                const float vx = f.motion[2 * i] * scale, vy = f.motion[2 * i + 1] * scale;
                const float speed = std::sqrt(vx * vx + vy * vy);
                if (!(speed >= 2.0f && std::isfinite(speed))) continue;  // one sample: the pixel as it is
                const int samples = speed < float(maxSamples) ? int(speed) : maxSamples;
                if (samples < 2) continue;
                float sum[3] = {source[3 * i], source[3 * i + 1], source[3 * i + 2]}, rgb[3];
                for (int k = 1; k < samples; ++k) {
                    const float t = float(k) / float(samples - 1) - 0.5f;
                    sample(float(x) + 0.5f + vx * t, float(y) + 0.5f + vy * t, rgb);
                    for (int c = 0; c < 3; ++c) sum[c] += rgb[c];
                }
                for (int c = 0; c < 3; ++c) out[3 * i + size_t(c)] = sum[c] / float(samples);
            }
    });
}

}  // namespace dejag::infer

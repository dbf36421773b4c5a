// taa-hq's first implementation, kept as the tests' oracle for its SIMD band kernel: one pixel at a time,
// interleaved buffers, the sRGB formulas, in the order of docs/taa-hq.md.
#include "tests/infer/taa_hq_reference.h"

#include <algorithm>
#include <cmath>

#include "data/image.h"

namespace dejag::infer::reference {

namespace {

constexpr float kStill = 1e-3f;  // motion below this in x and y is none (exactly 0)

struct Ycocg {
    float y, co, cg;
};
Ycocg toYcocg(const float* rgb) {
    return {0.25f * rgb[0] + 0.5f * rgb[1] + 0.25f * rgb[2], 0.5f * (rgb[0] - rgb[2]),
            -0.25f * rgb[0] + 0.5f * rgb[1] - 0.25f * rgb[2]};
}
void toRgb(const Ycocg& c, float* rgb) {
    rgb[0] = c.y + c.co - c.cg, rgb[1] = c.y + c.cg, rgb[2] = c.y - c.co - c.cg;
}
void catmullRom(float t, float* w) {
    const float t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.0f;
    w[2] = -1.5f * t3 + 2.0f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
}
float decode(float v) {
    return srgbToLinear(std::clamp(v, 0.0f, 1.0f));  // (NaN: see below)
}

}  // namespace

void ReferenceTaaHq::apply(int W, int H, const float* colour, const float* motion, const float* depth,
                           const float* previousDepth, float jitterX, float jitterY, float* out) {
    const size_t pixels = size_t(W) * size_t(H);
    const bool fresh = W != width_ || H != height_;
    if (fresh) {
        width_ = W, height_ = H, frame_ = 0;
        history_.assign(pixels * 4, 0.0f), nextHistory_.assign(pixels * 4, 0.0f);
        moved_.assign(pixels, 0), nextMoved_.assign(pixels, 0);
    }
    if (!options_.jitterList.empty()) {
        const auto& j = options_.jitterList[size_t(frame_) % options_.jitterList.size()];
        jitterX = j.first, jitterY = j.second;
    }
    ++frame_;
    auto clampX = [W](int x) { return std::clamp(x, 0, W - 1); };
    auto clampY = [H](int y) { return std::clamp(y, 0, H - 1); };
    const int shiftX = std::clamp(-int(std::floor(-jitterX + 0.5f)), -W, W);
    const int shiftY = std::clamp(-int(std::floor(-jitterY + 0.5f)), -H, H);
    // The current frame as the kernel sees it: pixel p holds the frame's sample p + shift (clamped to the
    // frame), in linear light; and the motion, snapped to 0 below kStill.
    std::vector<float> cur(pixels * 3), snapped(pixels * 2);
    std::vector<uint8_t> movedPixel(pixels);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t p = size_t(y) * size_t(W) + size_t(x);
            const size_t q = size_t(clampY(y + shiftY)) * size_t(W) + size_t(clampX(x + shiftX));
            for (int k = 0; k < 3; ++k) {
                const float v = colour[q * 3 + size_t(k)];
                cur[p * 3 + size_t(k)] = std::isnan(v) ? 0.0f : decode(v);
            }
            const float mx = motion[p * 2], my = motion[p * 2 + 1];
            const bool none = std::abs(mx) < kStill && std::abs(my) < kStill;
            movedPixel[p] = !none;
            snapped[p * 2] = none ? 0.0f : mx, snapped[p * 2 + 1] = none ? 0.0f : my;
        }
    const bool useDepth = depth && previousDepth;
    const float gamma = options_.clipGamma, maxWeight = float(options_.maxSamples);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t p = size_t(y) * size_t(W) + size_t(x);
            const float* c = cur.data() + p * 3;
            bool anyMoved = false;
            for (int dy = -1; dy <= 1; ++dy)
                for (int dx = -1; dx <= 1; ++dx)
                    anyMoved =
                        anyMoved || movedPixel[size_t(clampY(y + dy)) * size_t(W) + size_t(clampX(x + dx))];
            // Where the pixel was: the motion of the nearest surface around it.
            size_t mp = p;
            float curLo = 0, curHi = 0;
            if (depth) {
                float nearest = depth[p];
                curLo = curHi = depth[p];
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const size_t s = size_t(clampY(y + dy)) * size_t(W) + size_t(clampX(x + dx));
                        if (depth[s] < nearest) nearest = depth[s], mp = s;
                        curLo = std::min(curLo, depth[s]), curHi = std::max(curHi, depth[s]);
                    }
            }
            nextMoved_[p] = anyMoved;
            const float hx = float(x) + 0.5f - snapped[mp * 2], hy = float(y) + 0.5f - snapped[mp * 2 + 1];
            float weight = 0;
            float h[3] = {c[0], c[1], c[2]};
            if (!fresh && hx >= 0 && hy >= 0 && hx <= float(W) && hy <= float(H)) {
                const int nx = clampX(int(hx)), ny = clampY(int(hy));
                const size_t np = size_t(ny) * size_t(W) + size_t(nx);
                weight = history_[np * 4 + 3];
                if (useDepth) {
                    float prevLo = 1e30f, prevHi = -1e30f;
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const float d =
                                previousDepth[size_t(clampY(ny + dy)) * size_t(W) + size_t(clampX(nx + dx))];
                            prevLo = std::min(prevLo, d), prevHi = std::max(prevHi, d);
                        }
                    if (prevHi < curLo * (1 - options_.depthTolerance) ||
                        prevLo > curHi * (1 + options_.depthTolerance))
                        weight = 0;
                }
                if (weight > 0) {
                    // Catmull-Rom (or bilinear) over 4x4 texels, deringed to the 2x2 bilinear footprint.
                    const float u = hx - 0.5f, v = hy - 0.5f;
                    const int ix = int(std::floor(u)), iy = int(std::floor(v));
                    const float fx = u - float(ix), fy = v - float(iy);
                    float wx[4], wy[4];
                    catmullRom(fx, wx), catmullRom(fy, wy);
                    if (!options_.catmullRom) {
                        wx[0] = wx[3] = wy[0] = wy[3] = 0;
                        wx[1] = 1 - fx, wx[2] = fx, wy[1] = 1 - fy, wy[2] = fy;
                    }
                    float acc[3] = {0, 0, 0}, lo[3] = {1e30f, 1e30f, 1e30f}, hi[3] = {-1e30f, -1e30f, -1e30f};
                    for (int j = 0; j < 4; ++j)
                        for (int i = 0; i < 4; ++i) {
                            const float* t =
                                history_.data() +
                                (size_t(clampY(iy - 1 + j)) * size_t(W) + size_t(clampX(ix - 1 + i))) * 4;
                            for (int k = 0; k < 3; ++k) acc[k] += wx[i] * wy[j] * t[k];
                            if ((i == 1 || i == 2) && (j == 1 || j == 2))
                                for (int k = 0; k < 3; ++k)
                                    lo[k] = std::min(lo[k], t[k]), hi[k] = std::max(hi[k], t[k]);
                        }
                    for (int k = 0; k < 3; ++k) h[k] = std::clamp(acc[k], lo[k], hi[k]);
                    // Variance clipping in YCoCg, except under the static lock.
                    const bool still = options_.staticLock && !anyMoved && !moved_[np];
                    if (!still) {
                        float sum[3] = {}, sum2[3] = {}, mn[3] = {1e9f, 1e9f, 1e9f},
                              mx[3] = {-1e9f, -1e9f, -1e9f};
                        for (int dy = -1; dy <= 1; ++dy)
                            for (int dx = -1; dx <= 1; ++dx) {
                                const Ycocg n = toYcocg(
                                    cur.data() +
                                    (size_t(clampY(y + dy)) * size_t(W) + size_t(clampX(x + dx))) * 3);
                                const float v3[3] = {n.y, n.co, n.cg};
                                for (int k = 0; k < 3; ++k)
                                    sum[k] += v3[k], sum2[k] += v3[k] * v3[k], mn[k] = std::min(mn[k], v3[k]),
                                                                               mx[k] = std::max(mx[k], v3[k]);
                            }
                        const Ycocg cc = toYcocg(c), hc = toYcocg(h);
                        const float cur3[3] = {cc.y, cc.co, cc.cg}, his3[3] = {hc.y, hc.co, hc.cg};
                        float centre[3], off[3], a = 0;
                        for (int k = 0; k < 3; ++k) {
                            const float mean = sum[k] / 9,
                                        sigma = std::sqrt(std::max(0.0f, sum2[k] / 9 - mean * mean));
                            const float lo2 = std::min(std::max(mn[k], mean - gamma * sigma), cur3[k]);
                            const float hi2 = std::max(std::min(mx[k], mean + gamma * sigma), cur3[k]);
                            centre[k] = 0.5f * (lo2 + hi2);
                            off[k] = his3[k] - centre[k];
                            a = std::max(a, std::abs(off[k]) / (0.5f * (hi2 - lo2) + 1e-6f));
                        }
                        if (a > 1.0f) {
                            toRgb({centre[0] + off[0] / a, centre[1] + off[1] / a, centre[2] + off[2] / a},
                                  h);
                            weight = std::min(weight, options_.clippedSamples);
                        }
                    }
                }
            }
            weight =
                std::min(weight + 1.0f,
                         anyMoved ? float(std::min(options_.movingSamples, options_.maxSamples)) : maxWeight);
            float* n = nextHistory_.data() + p * 4;
            for (int k = 0; k < 3; ++k) n[k] = h[k] + (c[k] - h[k]) / weight;
            n[3] = weight;
            for (int k = 0; k < 3; ++k) out[p * 3 + size_t(k)] = linearToSrgb(std::clamp(n[k], 0.0f, 1.0f));
        }
    std::swap(history_, nextHistory_);
    std::swap(moved_, nextMoved_);
    if (options_.sharpen <= 0) return;
    const std::vector<float> unsharpened(out, out + pixels * 3);
    for (int y = 0; y < H; ++y)
        for (int x = 0; x < W; ++x) {
            const size_t p = size_t(y) * size_t(W) + size_t(x);
            const size_t nb[4] = {
                size_t(clampY(y - 1)) * size_t(W) + size_t(x), size_t(clampY(y + 1)) * size_t(W) + size_t(x),
                size_t(y) * size_t(W) + size_t(clampX(x - 1)), size_t(y) * size_t(W) + size_t(clampX(x + 1))};
            for (int k = 0; k < 3; ++k) {
                const float c = unsharpened[p * 3 + size_t(k)];
                float lo = c, hi = c, around = 0;
                for (const size_t q : nb) {
                    const float v = unsharpened[q * 3 + size_t(k)];
                    lo = std::min(lo, v), hi = std::max(hi, v), around += v;
                }
                out[p * 3 + size_t(k)] = std::clamp(c + options_.sharpen * (c - 0.25f * around), lo, hi);
            }
        }
}

}  // namespace dejag::infer::reference

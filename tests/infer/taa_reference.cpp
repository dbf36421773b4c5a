// The first TAA of dejag, kept as the tests' oracle for infer/taa.cpp's SIMD band kernel: scalar code
// over interleaved planes, one pass per stage, written straight from docs/taa.md.
#include "tests/infer/taa_reference.h"

#include <algorithm>
#include <cmath>

#include "base/error.h"
#include "base/thread_pool.h"

namespace dejag::infer::reference {

namespace {

struct Rgb {
    float r = 0, g = 0, b = 0;
    Rgb operator+(const Rgb& o) const { return {r + o.r, g + o.g, b + o.b}; }
    Rgb operator-(const Rgb& o) const { return {r - o.r, g - o.g, b - o.b}; }
    Rgb operator*(float s) const { return {r * s, g * s, b * s}; }
};
Rgb minimum(const Rgb& a, const Rgb& b) {
    return {std::min(a.r, b.r), std::min(a.g, b.g), std::min(a.b, b.b)};
}
Rgb maximum(const Rgb& a, const Rgb& b) {
    return {std::max(a.r, b.r), std::max(a.g, b.g), std::max(a.b, b.b)};
}
Rgb mix(const Rgb& a, const Rgb& b, float t) {
    return a + (b - a) * t;
}
float luminance(const Rgb& c) {  // docs/taa.md: the feedback's luma
    return 0.25f * c.r + 0.5f * c.g + 0.25f * c.b;
}
float luma(const Rgb& c) {  // Rec. 601, for the Sobel of colours
    return 0.299f * c.r + 0.587f * c.g + 0.114f * c.b;
}

// Clamped reads of interleaved planes.
struct Plane {
    const float* data;
    int width, height, channels;
    const float* at(int x, int y) const {
        x = std::clamp(x, 0, width - 1), y = std::clamp(y, 0, height - 1);
        return data + (size_t(y) * size_t(width) + size_t(x)) * size_t(channels);
    }
    Rgb rgb(int x, int y) const {
        const float* p = at(x, y);
        return {p[0], p[1], p[2]};
    }
    float value(int x, int y) const { return *at(x, y); }
    // Bilinear at pixel coordinates (pixel centres at +0.5), clamp to edge.
    Rgb rgbBilinear(float x, float y) const {
        const float fx = x - 0.5f, fy = y - 0.5f;
        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
        const float tx = fx - float(x0), ty = fy - float(y0);
        return mix(mix(rgb(x0, y0), rgb(x0 + 1, y0), tx), mix(rgb(x0, y0 + 1), rgb(x0 + 1, y0 + 1), tx), ty);
    }
    float valueBilinear(float x, float y) const {
        const float fx = x - 0.5f, fy = y - 0.5f;
        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
        const float tx = fx - float(x0), ty = fy - float(y0);
        const float top = value(x0, y0) + tx * (value(x0 + 1, y0) - value(x0, y0));
        const float bottom = value(x0, y0 + 1) + tx * (value(x0 + 1, y0 + 1) - value(x0, y0 + 1));
        return top + ty * (bottom - top);
    }
};

// Moves q towards the centre of the box [lo, hi] until it is inside (INSIDE's clip_aabb).
Rgb clipToBox(const Rgb& lo, const Rgb& hi, const Rgb& q) {
    const Rgb centre = (lo + hi) * 0.5f;
    const float eps = 1e-6f;
    const Rgb extent = (hi - lo) * 0.5f + Rgb{eps, eps, eps};
    const Rgb v = q - centre;
    const float unit =
        std::max({std::abs(v.r / extent.r), std::abs(v.g / extent.g), std::abs(v.b / extent.b)});
    return unit > 1.0f ? centre + v * (1.0f / unit) : q;
}

// History weight from the luma difference of current and history (docs/taa.md).
float feedback(float current, float history, const TaaOptions& o) {
    const float d = std::abs(current - history) / std::max({current, history, 0.2f});
    const float w = (1.0f - d) * (1.0f - d);
    return o.feedbackMin + (o.feedbackMax - o.feedbackMin) * std::clamp(w, 0.0f, 1.0f);
}

float sobelMagnitude(const Plane& p, int x, int y, bool rgbLuma) {
    auto v = [&](int dx, int dy) { return rgbLuma ? luma(p.rgb(x + dx, y + dy)) : p.value(x + dx, y + dy); };
    const float gx = -v(-1, -1) + v(1, -1) - 2 * v(-1, 0) + 2 * v(1, 0) - v(-1, 1) + v(1, 1);
    const float gy = v(-1, -1) + 2 * v(0, -1) + v(1, -1) - v(-1, 1) - 2 * v(0, 1) - v(1, 1);
    return std::sqrt(gx * gx + gy * gy);
}

}  // namespace

ReferenceTaa::ReferenceTaa(const TaaOptions& options) : options_(options) {
    if (!(options.feedbackMin >= 0 && options.feedbackMin <= options.feedbackMax && options.feedbackMax < 1))
        throw Error("TAA feedback must satisfy 0 <= min <= max < 1");
}

void ReferenceTaa::apply(const TaaFrame& f, float* out) {
    const int W = f.width, H = f.height;
    if (W < 1 || H < 1 || !f.colour || !f.depth || !f.motion)
        throw Error("TAA needs colour, depth and motion buffers");
    const bool improved = options_.improved;
    if (improved && (!f.albedo || !f.ids || !f.previousDepth))
        throw Error("the Sobel-improved TAA needs albedo, IDs and the previous depth too");
    const size_t pixels = size_t(W) * size_t(H);
    const Plane colour{f.colour, W, H, 3}, depth{f.depth, W, H, 1}, motion{f.motion, W, H, 2};
    const bool fresh = W != width_ || H != height_;
    if (fresh) {
        width_ = W, height_ = H;
        history_.assign(f.colour, f.colour + pixels * 3);
        sobelHistory_.assign(pixels, 0.0f);
    }
    blended_.resize(pixels * 3);
    const Plane history{history_.data(), W, H, 3};

    // T-TAA: the Sobel texture, then its own 1-channel TAA (clamp, no sharpen).
    if (improved) {
        sobel_.resize(pixels);
        nextSobel_.resize(pixels);
        // Luma planes of albedo and colour, once per frame (the Sobels read each value nine times).
        albedoLuma_.resize(pixels), colourLuma_.resize(pixels);
        parallelFor(0, H, 16, [&](int64_t first, int64_t last) {
            for (size_t i = size_t(first) * size_t(W); i < size_t(last) * size_t(W); ++i) {
                albedoLuma_[i] = luma({f.albedo[3 * i], f.albedo[3 * i + 1], f.albedo[3 * i + 2]});
                colourLuma_[i] = luma({f.colour[3 * i], f.colour[3 * i + 1], f.colour[3 * i + 2]});
            }
        });
        const Plane albedoLuma{albedoLuma_.data(), W, H, 1}, colourLuma{colourLuma_.data(), W, H, 1};
        parallelFor(0, H, 4, [&](int64_t first, int64_t last) {
            for (int y = int(first); y < int(last); ++y)
                for (int x = 0; x < W; ++x) {
                    const float u = sobelMagnitude(albedoLuma, x, y, false),
                                l = sobelMagnitude(colourLuma, x, y, false);
                    const float d = sobelMagnitude(depth, x, y, false);
                    const float g = std::clamp(0.3f * u + 0.7f * l + d, 0.0f, 1.0f);
                    sobel_[size_t(y) * size_t(W) + size_t(x)] = std::sqrt(g * g * (3.0f - 2.0f * g));
                }
        });
        const Plane sobel{sobel_.data(), W, H, 1}, sobelHistory{sobelHistory_.data(), W, H, 1};
        parallelFor(0, H, 4, [&](int64_t first, int64_t last) {
            for (int y = int(first); y < int(last); ++y)
                for (int x = 0; x < W; ++x) {
                    const size_t i = size_t(y) * size_t(W) + size_t(x);
                    if (fresh) {
                        nextSobel_[i] = sobel_[i];
                        continue;
                    }
                    float lo = 1e30f, hi = -1e30f;
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const float v = sobel.value(x + dx, y + dy);
                            lo = std::min(lo, v), hi = std::max(hi, v);
                        }
                    const float* m = motion.at(x, y);
                    const float previous =
                        std::clamp(sobelHistory.valueBilinear(x + 0.5f - m[0], y + 0.5f - m[1]), lo, hi);
                    const float k = feedback(sobel_[i], previous, options_);
                    nextSobel_[i] = sobel_[i] + (previous - sobel_[i]) * k;
                }
        });
        std::swap(sobelHistory_, nextSobel_);
    }
    const Plane stableSobel{sobelHistory_.data(), W, H, 1};
    const Plane ids{f.ids, W, H, 1}, previousDepth{f.previousDepth, W, H, 1};

    parallelFor(0, H, 4, [&](int64_t first, int64_t last) {
        for (int y = int(first); y < int(last); ++y) {
            // The clamped rows of the 3x3 neighbourhood, found once per row.
            const int ys[3] = {std::max(y - 1, 0), y, std::min(y + 1, H - 1)};
            const float* colourRows[3];
            const float* depthRows[3];
            const float* sobelRows[3] = {};
            const float* idRows[3] = {};
            for (int k = 0; k < 3; ++k) {
                const size_t row = size_t(ys[k]) * size_t(W);
                colourRows[k] = f.colour + row * 3, depthRows[k] = f.depth + row;
                if (improved) sobelRows[k] = sobelHistory_.data() + row, idRows[k] = f.ids + row;
            }
            for (int x = 0; x < W; ++x) {
                const int xs[3] = {std::max(x - 1, 0), x, std::min(x + 1, W - 1)};
                const size_t i = size_t(y) * size_t(W) + size_t(x);
                const Rgb current = colour.rgb(x, y);
                // 1. Neighbourhoods: 3x3 and cross (centre + 4).
                Rgb min9 = current, max9 = current, sum9{}, minCross = current, maxCross = current,
                    sumCross{};
                float closest = 1e30f;
                int cx = x, cy = y;
                for (int dy = 0; dy < 3; ++dy)
                    for (int dx = 0; dx < 3; ++dx) {
                        const float* p = colourRows[dy] + 3 * xs[dx];
                        const Rgb c{p[0], p[1], p[2]};
                        min9 = minimum(min9, c), max9 = maximum(max9, c), sum9 = sum9 + c;
                        if (dx == 1 || dy == 1)
                            minCross = minimum(minCross, c), maxCross = maximum(maxCross, c),
                            sumCross = sumCross + c;
                        // 2. The velocity of the closest depth in the 3x3.
                        const float d = depthRows[dy][xs[dx]];
                        if (d < closest) closest = d, cx = xs[dx], cy = ys[dy];
                    }
                const Rgb avg9 = sum9 * (1.0f / 9.0f), avgCross = sumCross * 0.2f;
                const float* velocity = motion.at(cx, cy);
                // 3. Reproject.
                const Rgb previous =
                    fresh ? current : history.rgbBilinear(x + 0.5f - velocity[0], y + 0.5f - velocity[1]);
                Rgb lo, hi;
                if (!improved) {
                    lo = (min9 + minCross) * 0.5f, hi = (max9 + maxCross) * 0.5f;
                } else {
                    // How aliased this pixel is: Sobel, model index, depth pseudo-variances.
                    const float sobelCentre = stableSobel.value(x, y);
                    float sobel3x3 = 0, sobelCross = 0, different = 0, dmin = 1e30f, dmax = -1e30f, dsum = 0;
                    const float id = ids.value(x, y);
                    for (int dy = 0; dy < 3; ++dy)
                        for (int dx = 0; dx < 3; ++dx) {
                            const float s = sobelRows[dy][xs[dx]];
                            sobel3x3 += s;
                            if (dx == 1 || dy == 1) sobelCross += s;
                            different += idRows[dy][xs[dx]] != id ? 1.0f : 0.0f;
                            const float d = depthRows[dy][xs[dx]];
                            dmin = std::min(dmin, d), dmax = std::max(dmax, d), dsum += d;
                        }
                    sobel3x3 /= 9.0f, sobelCross /= 5.0f;
                    const float modelAverage = different / 9.0f;
                    const float davg = dsum / 9.0f;
                    const float maxDepthDistance = std::min(std::abs(dmin - davg), std::abs(dmax - davg));
                    float depthPV = 0, depthTPV = 0;
                    if (maxDepthDistance >= options_.depthThreshold) {
                        const float pv = std::abs(depth.value(x, y) - davg) / maxDepthDistance;
                        const float prior = previousDepth.value(int(std::floor(x + 0.5f - velocity[0])),
                                                                int(std::floor(y + 0.5f - velocity[1])));
                        const float tpv = std::abs(prior - davg) / maxDepthDistance;
                        depthPV = pv * pv, depthTPV = tpv * tpv * tpv * tpv;
                    }
                    const float sobelAvgMixVal = std::clamp(modelAverage + sobelCentre, 0.0f, 1.0f);
                    const float sobelAvg = sobelCross + (sobel3x3 - sobelCross) * sobelAvgMixVal;
                    const float aliased =
                        std::clamp(sobelAvg + depthPV + depthTPV + modelAverage, 0.0f, 1.0f);
                    const Rgb colorMin = mix(minCross, min9, aliased),
                              colorMax = mix(maxCross, max9, aliased);
                    lo = mix(current, colorMin, aliased), hi = mix(current, colorMax, aliased);
                    (void)avg9, (void)avgCross;
                }
                // 4. Clip (towards the box centre), 5. blend with the luminance feedback.
                const Rgb clipped = clipToBox(lo, hi, previous);
                const float k = fresh ? 0.0f : feedback(luminance(current), luminance(clipped), options_);
                const Rgb blended = mix(current, clipped, k);
                float* b = blended_.data() + i * 3;
                b[0] = blended.r, b[1] = blended.g, b[2] = blended.b;
            }
        }
    });
    // The history keeps the unsharpened result; 6. the output is sharpened.
    const Plane blended{blended_.data(), W, H, 3};
    const float centreWeight = improved ? 2.0f : 5.0f, sideWeight = improved ? -0.25f : -1.0f;
    parallelFor(0, H, 4, [&](int64_t first, int64_t last) {
        for (int y = int(first); y < int(last); ++y)
            for (int x = 0; x < W; ++x) {
                const Rgb c = blended.rgb(x, y);
                Rgb s = c;
                if (options_.sharpen)
                    s = c * centreWeight + (blended.rgb(x - 1, y) + blended.rgb(x + 1, y) +
                                            blended.rgb(x, y - 1) + blended.rgb(x, y + 1)) *
                                               sideWeight;
                float* o = out + (size_t(y) * size_t(W) + size_t(x)) * 3;
                o[0] = std::clamp(s.r, 0.0f, 1.0f), o[1] = std::clamp(s.g, 0.0f, 1.0f),
                o[2] = std::clamp(s.b, 0.0f, 1.0f);
            }
    });
    std::swap(history_, blended_);
}

}  // namespace dejag::infer::reference

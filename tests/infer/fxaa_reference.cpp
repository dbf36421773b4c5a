// The first FXAA of dejag, kept as the tests' oracle for infer/fxaa.cpp's SIMD kernels: scalar code, one
// pixel at a time, step for step as FXAA 3.11's shader.
#include "tests/infer/fxaa_reference.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "base/error.h"
#include "base/thread_pool.h"

namespace dejag::infer::reference {

namespace {

// The search steps of FXAA 3.11's quality presets.
std::vector<float> presetSteps(int preset) {
    switch (preset) {
        case 12:
            return {1.0f, 1.5f, 2.0f, 4.0f, 12.0f};
        case 23:
            return {1.0f, 1.5f, 2.0f, 2.0f, 2.0f, 8.0f};
        case 39:
            return {1.0f, 1.0f, 1.0f, 1.0f, 1.0f, 1.5f, 2.0f, 2.0f, 2.0f, 2.0f, 4.0f, 8.0f};
        default:
            throw Error("FXAA preset " + std::to_string(preset) + " is not one of 12, 23, 39");
    }
}

// Pixel-space views of the frame with the texture unit's clamp-to-edge addressing; (x, y) are pixel
// coordinates with pixel (i, j)'s centre at (i + 0.5, j + 0.5), as texture coordinates times the size.
struct Frame {
    const float* colour;
    const float* luma;  // the plane of the whole frame
    int width, height, channels;
    bool green;

    const float* pixel(int x, int y) const {
        x = std::clamp(x, 0, width - 1), y = std::clamp(y, 0, height - 1);
        return colour + (size_t(y) * size_t(width) + size_t(x)) * size_t(channels);
    }
    float lumaOf(const float* p) const {
        return green ? p[1] : 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2];
    }
    float lumaAt(int x, int y) const {
        x = std::clamp(x, 0, width - 1), y = std::clamp(y, 0, height - 1);
        return luma[size_t(y) * size_t(width) + size_t(x)];
    }
    float lumaBilinear(float x, float y) const {
        const float fx = x - 0.5f, fy = y - 0.5f;
        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
        const float tx = fx - float(x0), ty = fy - float(y0);
        float a, b, c, d;
        if (x0 >= 0 && y0 >= 0 && x0 + 1 < width && y0 + 1 < height) {  // inside: no clamping
            const float* p = luma + size_t(y0) * size_t(width) + size_t(x0);
            a = p[0], b = p[1], c = p[width], d = p[width + 1];
        } else {
            a = lumaAt(x0, y0), b = lumaAt(x0 + 1, y0), c = lumaAt(x0, y0 + 1), d = lumaAt(x0 + 1, y0 + 1);
        }
        const float top = a + tx * (b - a), bottom = c + tx * (d - c);
        return top + ty * (bottom - top);
    }
    void colourBilinear(float x, float y, float* rgb) const {
        const float fx = x - 0.5f, fy = y - 0.5f;
        const int x0 = int(std::floor(fx)), y0 = int(std::floor(fy));
        const float tx = fx - float(x0), ty = fy - float(y0);
        const float* a = pixel(x0, y0);
        const float* b = pixel(x0 + 1, y0);
        const float* c = pixel(x0, y0 + 1);
        const float* d = pixel(x0 + 1, y0 + 1);
        for (int k = 0; k < 3; ++k) {
            const float top = a[k] + tx * (b[k] - a[k]), bottom = c[k] + tx * (d[k] - c[k]);
            rgb[k] = top + ty * (bottom - top);
        }
    }
    // One row of luma into dst[0 .. width).
    void lumaRow(int y, float* __restrict dst) const {
        const float* __restrict p = pixel(0, y);
        if (green) {
            for (int x = 0; x < width; ++x) dst[x] = p[size_t(x) * size_t(channels) + 1];
        } else if (channels == 3) {
            for (int x = 0; x < width; ++x)
                dst[x] = 0.299f * p[3 * x] + 0.587f * p[3 * x + 1] + 0.114f * p[3 * x + 2];
        } else {
            for (int x = 0; x < width; ++x) dst[x] = lumaOf(p + size_t(x) * size_t(channels));
        }
    }
};

constexpr int kBands = 64;

// edge[x] = 1 where the luma range of pixel x and its 4 neighbours reaches the threshold (the image's
// border pixels use their clamped neighbours).
inline uint8_t isEdge(float m, float n, float s, float w, float e, float edgeThreshold,
                      float edgeThresholdMin) {
    const float hi = std::max(std::max(std::max(n, s), std::max(w, e)), m);
    const float lo = std::min(std::min(std::min(n, s), std::min(w, e)), m);
    return (hi - lo) >= std::max(edgeThresholdMin, hi * edgeThreshold) ? 1 : 0;
}

void markEdges(uint8_t* __restrict edge, const float* __restrict up, const float* __restrict mid,
               const float* __restrict down, int width, float edgeThreshold, float edgeThresholdMin) {
    for (int x = 1; x < width - 1; ++x)
        edge[x] = isEdge(mid[x], up[x], down[x], mid[x - 1], mid[x + 1], edgeThreshold, edgeThresholdMin);
    edge[0] =
        isEdge(mid[0], up[0], down[0], mid[0], mid[std::min(1, width - 1)], edgeThreshold, edgeThresholdMin);
    const int last = width - 1;
    edge[last] = isEdge(mid[last], up[last], down[last], mid[std::max(last - 1, 0)], mid[last], edgeThreshold,
                        edgeThresholdMin);
}

}  // namespace

ReferenceFxaa::ReferenceFxaa(const FxaaOptions& options)
    : options_(options), steps_(presetSteps(options.preset)) {
    for (const float v : {options.subpix, options.edgeThreshold, options.edgeThresholdMin})
        if (!(v >= 0.0f && v <= 1.0f)) throw Error("FXAA: subpix and edge thresholds must be in [0, 1]");
}

void ReferenceFxaa::apply(const float* in, float* out, int width, int height, int channels) {
    if (width < 1 || height < 1 || channels < 3) throw Error("FXAA needs an image with R, G, B channels");
    const size_t floats = size_t(width) * size_t(height) * size_t(channels);
    parallelFor(0, int64_t(floats), 1 << 18, [&](int64_t first, int64_t last) {
        std::memcpy(out + first, in + first, size_t(last - first) * sizeof(float));
    });
    applyInPlace(out, width, height, channels);
}

void ReferenceFxaa::applyInPlace(float* frame, int width, int height, int channels) {
    if (width < 1 || height < 1 || channels < 3) throw Error("FXAA needs an image with R, G, B channels");
    const size_t pixels = size_t(width) * size_t(height);
    if (luma_.size() < pixels + 2) luma_.resize(pixels + 2);
    float* luma = luma_.data() + 1;  // luma[-1] and luma[pixels] exist for the row loops' borders
    const Frame f{frame, luma, width, height, channels, options_.greenAsLuma};
    parallelFor(0, height, 16, [&](int64_t first, int64_t last) {
        for (int64_t y = first; y < last; ++y) f.lumaRow(int(y), luma + y * width);
    });
    const float edgeThreshold = options_.edgeThreshold, edgeThresholdMin = options_.edgeThresholdMin;
    const float subpixAmount = options_.subpix;
    const float* steps = steps_.data();
    const int stepCount = int(steps_.size());
    const int bandCount = std::min(kBands, height);
    if (int(bands_.size()) < bandCount) bands_.resize(size_t(bandCount));

    // Each band collects its changes; the frame is only read until every band is done.
    parallelFor(0, bandCount, 1, [&](int64_t firstBand, int64_t lastBand) {
        for (int64_t b = firstBand; b < lastBand; ++b) {
            Band& band = bands_[size_t(b)];
            band.changes.clear();
            band.processed = 0;
            if (band.edge.size() < size_t(width)) band.edge.resize(size_t(width));
            const int y0 = int(int64_t(height) * b / bandCount),
                      y1 = int(int64_t(height) * (b + 1) / bandCount);
            for (int y = y0; y < y1; ++y) {
                const float* up = luma + size_t(std::max(y - 1, 0)) * size_t(width);
                const float* mid = luma + size_t(y) * size_t(width);
                const float* down = luma + size_t(std::min(y + 1, height - 1)) * size_t(width);
                // The contrast test for the whole row at once, vectorised (restrict pointers: the byte stores
                // cannot alias what the loop reads); the two border pixels with clamped neighbours.
                uint8_t* edge = band.edge.data();
                markEdges(edge, up, mid, down, width, edgeThreshold, edgeThresholdMin);
                const uint8_t* edgeEnd = edge + width;
                for (const uint8_t* e = edge; e < edgeEnd; ++e) {
                    // Skip eight flat pixels at a time.
                    while (e + 8 <= edgeEnd) {
                        uint64_t word;
                        std::memcpy(&word, e, 8);
                        if (word) break;
                        e += 8;
                    }
                    if (e >= edgeEnd) break;
                    if (!*e) continue;
                    const int x = int(e - edge);
                    const int xl = std::max(x - 1, 0), xr = std::min(x + 1, width - 1);
                    ++band.processed;
                    const float lumaM = mid[x];
                    float lumaS = down[x], lumaE = mid[xr], lumaN = up[x], lumaW = mid[xl];
                    const float range = std::max({lumaS, lumaE, lumaN, lumaW, lumaM}) -
                                        std::min({lumaS, lumaE, lumaN, lumaW, lumaM});
                    const float lumaNW = up[xl], lumaSE = down[xr], lumaNE = up[xr], lumaSW = down[xl];
                    const float lumaNS = lumaN + lumaS, lumaWE = lumaW + lumaE;
                    const float subpixRcpRange = 1.0f / range;
                    const float subpixNSWE = lumaNS + lumaWE;
                    const float edgeHorz1 = -2.0f * lumaM + lumaNS, edgeVert1 = -2.0f * lumaM + lumaWE;
                    const float lumaNESE = lumaNE + lumaSE, lumaNWNE = lumaNW + lumaNE;
                    const float edgeHorz2 = -2.0f * lumaE + lumaNESE, edgeVert2 = -2.0f * lumaN + lumaNWNE;
                    const float lumaNWSW = lumaNW + lumaSW, lumaSWSE = lumaSW + lumaSE;
                    const float edgeHorz4 = std::abs(edgeHorz1) * 2.0f + std::abs(edgeHorz2);
                    const float edgeVert4 = std::abs(edgeVert1) * 2.0f + std::abs(edgeVert2);
                    const float edgeHorz3 = -2.0f * lumaW + lumaNWSW, edgeVert3 = -2.0f * lumaS + lumaSWSE;
                    const float edgeHorz = std::abs(edgeHorz3) + edgeHorz4,
                                edgeVert = std::abs(edgeVert3) + edgeVert4;
                    const float subpixNWSWNESE = lumaNWSW + lumaNESE;
                    const bool horzSpan = edgeHorz >= edgeVert;  // the edge runs horizontally: search along x
                    float lengthSign = 1.0f;                     // one pixel across the edge
                    const float subpixA = subpixNSWE * 2.0f + subpixNWSWNESE;
                    if (!horzSpan) lumaN = lumaW, lumaS = lumaE;
                    const float subpixB = subpixA * (1.0f / 12.0f) - lumaM;
                    const float gradientN = lumaN - lumaM, gradientS = lumaS - lumaM;
                    float lumaNN = lumaN + lumaM;
                    const float lumaSS = lumaS + lumaM;
                    const bool pairN = std::abs(gradientN) >= std::abs(gradientS);
                    const float gradient = std::max(std::abs(gradientN), std::abs(gradientS));
                    if (pairN) lengthSign = -lengthSign;
                    const float subpixC = std::clamp(std::abs(subpixB) * subpixRcpRange, 0.0f, 1.0f);

                    // Start half a pixel across the edge, towards the side with the larger gradient.
                    const float centreX = float(x) + 0.5f, centreY = float(y) + 0.5f;
                    float bx = centreX, by = centreY;
                    const float offX = horzSpan ? 1.0f : 0.0f, offY = horzSpan ? 0.0f : 1.0f;
                    if (!horzSpan) bx += lengthSign * 0.5f;
                    if (horzSpan) by += lengthSign * 0.5f;
                    float nx = bx - offX * steps[0], ny = by - offY * steps[0];
                    float px = bx + offX * steps[0], py = by + offY * steps[0];
                    const float subpixD = -2.0f * subpixC + 3.0f;
                    float lumaEndN = f.lumaBilinear(nx, ny);
                    const float subpixE = subpixC * subpixC;
                    float lumaEndP = f.lumaBilinear(px, py);
                    if (!pairN) lumaNN = lumaSS;
                    const float gradientScaled = gradient * 0.25f;
                    const float lumaMM = lumaM - lumaNN * 0.5f;
                    const float subpixF = subpixD * subpixE;
                    const bool lumaMLTZero = lumaMM < 0.0f;
                    lumaEndN -= lumaNN * 0.5f;
                    lumaEndP -= lumaNN * 0.5f;
                    bool doneN = std::abs(lumaEndN) >= gradientScaled,
                         doneP = std::abs(lumaEndP) >= gradientScaled;
                    if (stepCount > 1) {
                        if (!doneN) nx -= offX * steps[1], ny -= offY * steps[1];
                        if (!doneP) px += offX * steps[1], py += offY * steps[1];
                    }
                    for (int i = 2; i < stepCount && (!doneN || !doneP); ++i) {
                        if (!doneN) lumaEndN = f.lumaBilinear(nx, ny) - lumaNN * 0.5f;
                        if (!doneP) lumaEndP = f.lumaBilinear(px, py) - lumaNN * 0.5f;
                        doneN = std::abs(lumaEndN) >= gradientScaled;
                        doneP = std::abs(lumaEndP) >= gradientScaled;
                        if (!doneN) nx -= offX * steps[i], ny -= offY * steps[i];
                        if (!doneP) px += offX * steps[i], py += offY * steps[i];
                    }
                    const float dstN = horzSpan ? centreX - nx : centreY - ny;
                    const float dstP = horzSpan ? px - centreX : py - centreY;
                    const bool goodSpanN = (lumaEndN < 0.0f) != lumaMLTZero;
                    const bool goodSpanP = (lumaEndP < 0.0f) != lumaMLTZero;
                    const float spanLength = dstP + dstN;
                    const bool directionN = dstN < dstP;
                    const float dst = std::min(dstN, dstP);
                    const bool goodSpan = directionN ? goodSpanN : goodSpanP;
                    const float subpixG = subpixF * subpixF;
                    const float pixelOffset = dst * (-1.0f / spanLength) + 0.5f;
                    const float subpixH = subpixG * subpixAmount;
                    const float pixelOffsetGood = goodSpan ? pixelOffset : 0.0f;
                    const float pixelOffsetSubpix = std::max(pixelOffsetGood, subpixH);
                    float sx = centreX, sy = centreY;
                    if (!horzSpan) sx += pixelOffsetSubpix * lengthSign;
                    if (horzSpan) sy += pixelOffsetSubpix * lengthSign;
                    Change change;
                    change.offset = int64_t((size_t(y) * size_t(width) + size_t(x)) * size_t(channels));
                    f.colourBilinear(sx, sy, change.rgb);
                    band.changes.push_back(change);
                }
            }
        }
    });
    int64_t processed = 0;
    for (int b = 0; b < bandCount; ++b) processed += bands_[size_t(b)].processed;
    processedFraction_ = double(processed) / (double(width) * double(height));
    parallelFor(0, bandCount, 1, [&](int64_t firstBand, int64_t lastBand) {
        for (int64_t b = firstBand; b < lastBand; ++b)
            for (const Change& c : bands_[size_t(b)].changes)
                std::memcpy(frame + c.offset, c.rgb, sizeof c.rgb);
    });
}

}  // namespace dejag::infer::reference

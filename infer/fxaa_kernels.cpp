// FXAA's kernels (infer/fxaa_kernels.h), compiled once per SIMD level. The resolve is FXAA 3.11's quality
// shader step for step, kFloatLanes pixels at a time: every branch of the shader is a select, the search
// runs until all lanes have found both ends.
#include "infer/fxaa_kernels.h"

#include <algorithm>

#include "infer/pixel_simd.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {

using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

namespace {

constexpr int L = kFloatLanes;

// The resolve's vector: the level's own (a double-width generic vector, two independent search chains in
// flight, measured slower with GCC 12: its lowering spills).
constexpr int WL = kFloatLanes;
using WFloat = VFloat;
using WInt = VInt;
using WMask = VMask;
inline WFloat wgather(const float* base, WInt index) {
    return gather(base, index);
}
inline bool wall(WMask m) {
    return all(m);
}
inline WFloat wabs(WFloat v) {
    return vabs(v);
}
inline WInt wfloor(WFloat v) {
    return floorToInt(v);
}
inline WFloat wfloat(WInt v) {
    return toFloat(v);
}
inline WFloat ws(float v) {
    return splat<VFloat>(v);
}
inline WInt wsi(int32_t v) {
    return splatInt(v);
}
template <class V>
V wmin(V a, V b) {
    return b < a ? b : a;  // std::min's order
}
template <class V>
V wmax(V a, V b) {
    return a < b ? b : a;  // std::max's order
}
template <class V>
V wclamp(V v, V lo, V hi) {
    return wmin(wmax(v, lo), hi);
}
template <class V>
V wsel(WMask m, V a, V b) {
    return m ? a : b;
}

float lumaOf(const FxaaKernelArgs& a, const float* p) {
    return a.greenAsLuma ? p[1] : 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2];
}

// Views of the frame with the texture unit's clamp-to-edge addressing; (x, y) in pixel coordinates,
// pixel (i, j)'s centre at (i + 0.5, j + 0.5).
struct Sampler {
    const FxaaKernelArgs& a;
    WInt lastX = wsi(a.width - 1), lastY = wsi(a.height - 1), zero = wsi(0);
    WInt lumaStride = wsi(int32_t(a.lumaStride)), width = wsi(a.width);

    WFloat luma(WInt x, WInt y) const {  // x may be -1 or width (the pads)
        return wgather(a.luma + kFxaaLumaPad, wclamp(y, zero, lastY) * lumaStride + x);
    }
    WFloat lumaBilinear(WFloat x, WFloat y) const {
        const WFloat fx = x - 0.5f, fy = y - 0.5f;
        const WInt x0 = wfloor(fx), y0 = wfloor(fy);
        const WFloat tx = fx - wfloat(x0), ty = fy - wfloat(y0);
        // Pixels x0 and x0 + 1 clamped to the row: one pair from max(x0, -1) .. min(x0, width - 1) + 1,
        // the pads holding the border pixels.
        const WInt pair = wclamp(x0, wsi(-1), lastX);
        const WInt ra = wclamp(y0, zero, lastY) * lumaStride, rb = wclamp(y0 + 1, zero, lastY) * lumaStride;
        const float* base = a.luma + kFxaaLumaPad;
        WFloat pa, pb, pc, pd;
        gatherPairs(base, ra + pair, pa, pb);
        gatherPairs(base, rb + pair, pc, pd);
        const WFloat top = pa + tx * (pb - pa), bottom = pc + tx * (pd - pc);
        return top + ty * (bottom - top);
    }
    void colourBilinear(WFloat x, WFloat y, WFloat rgb[3]) const {
        const WFloat fx = x - 0.5f, fy = y - 0.5f;
        const WInt x0 = wfloor(fx), y0 = wfloor(fy);
        const WFloat tx = fx - wfloat(x0), ty = fy - wfloat(y0);
        const WInt xa = wclamp(x0, zero, lastX), xb = wclamp(x0 + 1, zero, lastX);
        const WInt ra = wclamp(y0, zero, lastY) * width, rb = wclamp(y0 + 1, zero, lastY) * width;
        const WInt channels = wsi(a.channels);
        const WInt ia = (ra + xa) * channels, ib = (ra + xb) * channels;
        const WInt ic = (rb + xa) * channels, id = (rb + xb) * channels;
        for (int k = 0; k < 3; ++k) {
            const float* base = a.frame + k;
            const WFloat pa = wgather(base, ia), pb = wgather(base, ib);
            const WFloat pc = wgather(base, ic), pd = wgather(base, id);
            const WFloat top = pa + tx * (pb - pa), bottom = pc + tx * (pd - pc);
            rgb[k] = top + ty * (bottom - top);
        }
    }
};

// FXAA 3.11 for WL pixels.
void resolveLanes(const FxaaKernelArgs& a, const Sampler& f, WInt x, WInt y, WFloat rgb[3]) {
    const WInt one = wsi(1);
    const WFloat lumaM = f.luma(x, y);
    WFloat lumaS = f.luma(x, y + one), lumaE = f.luma(x + one, y), lumaN = f.luma(x, y - one),
           lumaW = f.luma(x - one, y);
    const WFloat range = wmax(wmax(wmax(lumaS, lumaE), wmax(lumaN, lumaW)), lumaM) -
                         wmin(wmin(wmin(lumaS, lumaE), wmin(lumaN, lumaW)), lumaM);
    const WFloat lumaNW = f.luma(x - one, y - one), lumaSE = f.luma(x + one, y + one),
                 lumaNE = f.luma(x + one, y - one), lumaSW = f.luma(x - one, y + one);
    const WFloat lumaNS = lumaN + lumaS, lumaWE = lumaW + lumaE;
    const WFloat subpixRcpRange = 1.0f / range;
    const WFloat subpixNSWE = lumaNS + lumaWE;
    const WFloat edgeHorz1 = -2.0f * lumaM + lumaNS, edgeVert1 = -2.0f * lumaM + lumaWE;
    const WFloat lumaNESE = lumaNE + lumaSE, lumaNWNE = lumaNW + lumaNE;
    const WFloat edgeHorz2 = -2.0f * lumaE + lumaNESE, edgeVert2 = -2.0f * lumaN + lumaNWNE;
    const WFloat lumaNWSW = lumaNW + lumaSW, lumaSWSE = lumaSW + lumaSE;
    const WFloat edgeHorz4 = wabs(edgeHorz1) * 2.0f + wabs(edgeHorz2);
    const WFloat edgeVert4 = wabs(edgeVert1) * 2.0f + wabs(edgeVert2);
    const WFloat edgeHorz3 = -2.0f * lumaW + lumaNWSW, edgeVert3 = -2.0f * lumaS + lumaSWSE;
    const WFloat edgeHorz = wabs(edgeHorz3) + edgeHorz4, edgeVert = wabs(edgeVert3) + edgeVert4;
    const WFloat subpixNWSWNESE = lumaNWSW + lumaNESE;
    const WMask horzSpan = edgeHorz >= edgeVert;  // the edge runs horizontally: search along x
    const WFloat subpixA = subpixNSWE * 2.0f + subpixNWSWNESE;
    lumaN = wsel(horzSpan, lumaN, lumaW), lumaS = wsel(horzSpan, lumaS, lumaE);
    const WFloat subpixB = subpixA * (1.0f / 12.0f) - lumaM;
    const WFloat gradientN = lumaN - lumaM, gradientS = lumaS - lumaM;
    WFloat lumaNN = lumaN + lumaM;
    const WFloat lumaSS = lumaS + lumaM;
    const WMask pairN = wabs(gradientN) >= wabs(gradientS);
    const WFloat gradient = wmax(wabs(gradientN), wabs(gradientS));
    const WFloat lengthSign = wsel(pairN, ws(-1.0f), ws(1.0f));
    const WFloat subpixC = wclamp(wabs(subpixB) * subpixRcpRange, ws(0.0f), ws(1.0f));

    // Start half a pixel across the edge, towards the side with the larger gradient.
    const WFloat centreX = wfloat(x) + 0.5f, centreY = wfloat(y) + 0.5f;
    const WFloat bx = wsel(horzSpan, centreX, centreX + lengthSign * 0.5f);
    const WFloat by = wsel(horzSpan, centreY + lengthSign * 0.5f, centreY);
    const WFloat offX = wsel(horzSpan, ws(1.0f), ws(0.0f));
    const WFloat offY = wsel(horzSpan, ws(0.0f), ws(1.0f));
    const float* steps = a.steps;
    WFloat nx = bx - offX * steps[0], ny = by - offY * steps[0];
    WFloat px = bx + offX * steps[0], py = by + offY * steps[0];
    const WFloat subpixD = -2.0f * subpixC + 3.0f;
    WFloat lumaEndN = f.lumaBilinear(nx, ny);
    const WFloat subpixE = subpixC * subpixC;
    WFloat lumaEndP = f.lumaBilinear(px, py);
    lumaNN = wsel(pairN, lumaNN, lumaSS);
    const WFloat gradientScaled = gradient * 0.25f;
    const WFloat lumaMM = lumaM - lumaNN * 0.5f;
    const WFloat subpixF = subpixD * subpixE;
    const WMask lumaMLTZero = lumaMM < ws(0.0f);
    lumaEndN -= lumaNN * 0.5f;
    lumaEndP -= lumaNN * 0.5f;
    WMask doneN = wabs(lumaEndN) >= gradientScaled, doneP = wabs(lumaEndP) >= gradientScaled;
    if (a.stepCount > 1) {
        nx = wsel(doneN, nx, nx - offX * steps[1]), ny = wsel(doneN, ny, ny - offY * steps[1]);
        px = wsel(doneP, px, px + offX * steps[1]), py = wsel(doneP, py, py + offY * steps[1]);
    }
    for (int i = 2; i < a.stepCount && !wall(doneN & doneP); ++i) {
        lumaEndN = wsel(doneN, lumaEndN, f.lumaBilinear(nx, ny) - lumaNN * 0.5f);
        lumaEndP = wsel(doneP, lumaEndP, f.lumaBilinear(px, py) - lumaNN * 0.5f);
        doneN = wabs(lumaEndN) >= gradientScaled;
        doneP = wabs(lumaEndP) >= gradientScaled;
        nx = wsel(doneN, nx, nx - offX * steps[i]), ny = wsel(doneN, ny, ny - offY * steps[i]);
        px = wsel(doneP, px, px + offX * steps[i]), py = wsel(doneP, py, py + offY * steps[i]);
    }
    const WFloat dstN = wsel(horzSpan, centreX - nx, centreY - ny);
    const WFloat dstP = wsel(horzSpan, px - centreX, py - centreY);
    const WMask goodSpanN = (lumaEndN < ws(0.0f)) != lumaMLTZero;
    const WMask goodSpanP = (lumaEndP < ws(0.0f)) != lumaMLTZero;
    const WFloat spanLength = dstP + dstN;
    const WMask directionN = dstN < dstP;
    const WFloat dst = wmin(dstN, dstP);
    const WMask goodSpan = wsel(directionN, goodSpanN, goodSpanP);
    const WFloat subpixG = subpixF * subpixF;
    const WFloat pixelOffset = dst * (-1.0f / spanLength) + 0.5f;
    const WFloat subpixH = subpixG * a.subpix;
    const WFloat pixelOffsetGood = wsel(goodSpan, pixelOffset, ws(0.0f));
    const WFloat pixelOffsetSubpix = wmax(pixelOffsetGood, subpixH);
    const WFloat sx = wsel(horzSpan, centreX, centreX + pixelOffsetSubpix * lengthSign);
    const WFloat sy = wsel(horzSpan, centreY + pixelOffsetSubpix * lengthSign, centreY);
    f.colourBilinear(sx, sy, rgb);
}

}  // namespace

void fxaaLumaRow(const FxaaKernelArgs& a, int y, float* dst) {
    const int W = a.width;
    const float* src = a.frame + size_t(y) * size_t(W) * size_t(a.channels);
    int x = 0;
    if (a.channels == 3 && !a.greenAsLuma)
        for (; x + L <= W; x += L) {
            VFloat r, g, b;
            loadRgb(src + 3 * x, r, g, b);
            storeu(dst + x, 0.299f * r + 0.587f * g + 0.114f * b);
        }
    for (; x < W; ++x) dst[x] = lumaOf(a, src + size_t(x) * size_t(a.channels));
    dst[-1] = dst[0], dst[W] = dst[W - 1];
}

int fxaaEdgesInRow(const FxaaKernelArgs& a, const float* up, const float* mid, const float* down,
                   int32_t* xs) {
    const int W = a.width;
    const VFloat threshold = splat<VFloat>(a.edgeThreshold), thresholdMin = splat<VFloat>(a.edgeThresholdMin);
    int count = 0;
    for (int x = 0; x < W; x += L) {
        const VFloat m = loadu<VFloat>(mid + x), n = loadu<VFloat>(up + x), s = loadu<VFloat>(down + x);
        const VFloat w = loadu<VFloat>(mid + x - 1), e = loadu<VFloat>(mid + x + 1);
        const VFloat hi = vmax(vmax(vmax(n, s), vmax(w, e)), m);
        const VFloat lo = vmin(vmin(vmin(n, s), vmin(w, e)), m);
        uint32_t bits = maskBits((hi - lo) >= vmax(thresholdMin, hi * threshold));
        if (W - x < L) bits &= (1u << (W - x)) - 1u;  // lanes past the row's end
        while (bits) {
            xs[count++] = x + __builtin_ctz(bits);
            bits &= bits - 1;
        }
    }
    return count;
}

void fxaaResolve(const FxaaKernelArgs& a, const int32_t* xs, const int32_t* ys, int count, float* rgb) {
    const Sampler sampler{a};
    for (int i = 0; i < count; i += WL) {
        const int n = std::min(WL, count - i);
        int32_t laneX[WL], laneY[WL];  // a short last group repeats its last pixel
        for (int k = 0; k < WL; ++k)
            laneX[k] = xs[i + std::min(k, n - 1)], laneY[k] = ys[i + std::min(k, n - 1)];
        WInt x, y;
        std::memcpy(&x, laneX, sizeof x), std::memcpy(&y, laneY, sizeof y);
        WFloat result[3];
        resolveLanes(a, sampler, x, y, result);
        float channel[3][WL];
        for (int c = 0; c < 3; ++c) std::memcpy(channel[c], &result[c], sizeof result[c]);
        for (int k = 0; k < n; ++k) {
            float* out = rgb + 3 * size_t(i + k);
            out[0] = channel[0][k], out[1] = channel[1][k], out[2] = channel[2][k];
        }
    }
}

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

// FXAA's kernels (infer/fxaa_kernels.h), compiled once per SIMD level. The resolve is FXAA 3.11's quality
// shader step for step, kFloatLanes pixels at a time: every branch of the shader is a select, the search
// runs until all lanes have found both ends.
#include "infer/fxaa_kernels.h"

#include <algorithm>
#include <cmath>

#include "base/pixel_simd.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {

using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

namespace {

constexpr int L = kFloatLanes;

float lumaOf(const FxaaKernelArgs& a, const float* p) {
    return a.greenAsLuma ? p[1] : 0.299f * p[0] + 0.587f * p[1] + 0.114f * p[2];
}

// Views of the frame with the texture unit's clamp-to-edge addressing; (x, y) in pixel coordinates,
// pixel (i, j)'s centre at (i + 0.5, j + 0.5).
struct Sampler {
    const FxaaKernelArgs& a;
    VInt lastX = splatInt(a.width - 1), lastY = splatInt(a.height - 1), zero = splatInt(0);
    VInt lumaStride = splatInt(int32_t(a.lumaStride)), width = splatInt(a.width);

    VFloat luma(VInt x, VInt y) const {  // x may be -1 or width (the pads)
        return gather(a.luma + kFxaaLumaPad, vclamp(y, zero, lastY) * lumaStride + x);
    }
    VFloat lumaBilinear(VFloat x, VFloat y) const {
        const VFloat fx = x - 0.5f, fy = y - 0.5f;
        const VInt x0 = floorToInt(fx), y0 = floorToInt(fy);
        const VFloat tx = fx - toFloat(x0), ty = fy - toFloat(y0);
        // Pixels x0 and x0 + 1 clamped to the row: one pair from max(x0, -1) .. min(x0, width - 1) + 1,
        // the pads holding the border pixels.
        const VInt pair = vclamp(x0, splatInt(-1), lastX);
        const VInt ra = vclamp(y0, zero, lastY) * lumaStride, rb = vclamp(y0 + 1, zero, lastY) * lumaStride;
        const float* base = a.luma + kFxaaLumaPad;
        VFloat pa, pb, pc, pd;
        gatherPairs(base, ra + pair, pa, pb);
        gatherPairs(base, rb + pair, pc, pd);
        const VFloat top = pa + tx * (pb - pa), bottom = pc + tx * (pd - pc);
        return top + ty * (bottom - top);
    }
    void colourBilinear(VFloat x, VFloat y, VFloat rgb[3]) const {
        bilinearRgb(a.frame, a.width, a.height, a.channels, x, y, rgb);
    }
};

// FXAA 3.11 in four steps over a block of pixels, kept in arrays between them: (1) the neighbourhood
// decisions, kFloatLanes pixels at a time; (2) the search of the pixels whose edge runs vertically, a
// vector of pixels at a time with gathers; (3) the search of those whose edge runs horizontally, one
// pixel at a time with its search positions across the lanes: they lie on one row pair, so two loads
// per row and a permute (AVX-512) replace the gathers; (4) the final offset and colour read, a vector
// of pixels at a time. Every value is computed as the shader does, in its order.
constexpr int kBlock = 256;

struct Block {
    // (1)'s results: the search start, the pair luma, the end threshold, the span direction (-1 / 0)
    alignas(64) float bx[kBlock], by[kBlock], lumaNN[kBlock], gradientScaled[kBlock];
    alignas(64) float lumaMM[kBlock], subpixF[kBlock], lengthSign[kBlock];
    alignas(64) int32_t horz[kBlock];
    // (2) and (3)'s results: where each search ended, and the luma there
    alignas(64) float nx[kBlock], ny[kBlock], px[kBlock], py[kBlock], endN[kBlock], endP[kBlock];
    int32_t vertical[kBlock], horizontal[kBlock];
};

// Lanes of `count` entries of `index` (a short group repeats its last entry) gathered from array.
template <class T>
void laneLoad(const T* array, const int32_t* index, int count, T* lanes) {
    for (int k = 0; k < L; ++k) lanes[k] = array[index[std::min(k, count - 1)]];
}

// The 3x3 luma around each lane's pixel: from three row windows when the lanes share a row and lie
// within 30 pixels (AVX-512; pixels along an edge usually do), else gathers.
void neighbourhood(const FxaaKernelArgs& a, const Sampler& f, VInt x, VInt y, VFloat n[3][3]) {
#if defined(DEJAG_SIMD_LEVEL_avx512)
    const int row = y[0], first = laneMin(x) - 1;
    if (all(y == splatInt(row)) && laneMax(x) + 1 - first < 32) {
        for (int dy = 0; dy < 3; ++dy) {
            const float* r = a.luma + size_t(std::clamp(row + dy - 1, 0, a.height - 1)) * a.lumaStride +
                             kFxaaLumaPad + first;
            const __m512 lo = _mm512_loadu_ps(r), hi = _mm512_loadu_ps(r + 16);
            for (int dx = 0; dx < 3; ++dx)
                n[dy][dx] = VFloat(_mm512_permutex2var_ps(lo, __m512i(x + (dx - 1 - first)), hi));
        }
        return;
    }
#else
    (void)a;
#endif
    for (int dy = 0; dy < 3; ++dy)
        for (int dx = 0; dx < 3; ++dx) n[dy][dx] = f.luma(x + splatInt(dx - 1), y + splatInt(dy - 1));
}

void setupLanes(const FxaaKernelArgs& a, const Sampler& f, VInt x, VInt y, Block& block, int at) {
    VFloat n[3][3];
    neighbourhood(a, f, x, y, n);
    const VFloat lumaM = n[1][1];
    VFloat lumaS = n[2][1], lumaE = n[1][2], lumaN = n[0][1], lumaW = n[1][0];
    const VFloat range = vmax(vmax(vmax(lumaS, lumaE), vmax(lumaN, lumaW)), lumaM) -
                         vmin(vmin(vmin(lumaS, lumaE), vmin(lumaN, lumaW)), lumaM);
    const VFloat lumaNW = n[0][0], lumaSE = n[2][2], lumaNE = n[0][2], lumaSW = n[2][0];
    const VFloat lumaNS = lumaN + lumaS, lumaWE = lumaW + lumaE;
    const VFloat subpixRcpRange = 1.0f / range;
    const VFloat subpixNSWE = lumaNS + lumaWE;
    const VFloat edgeHorz1 = -2.0f * lumaM + lumaNS, edgeVert1 = -2.0f * lumaM + lumaWE;
    const VFloat lumaNESE = lumaNE + lumaSE, lumaNWNE = lumaNW + lumaNE;
    const VFloat edgeHorz2 = -2.0f * lumaE + lumaNESE, edgeVert2 = -2.0f * lumaN + lumaNWNE;
    const VFloat lumaNWSW = lumaNW + lumaSW, lumaSWSE = lumaSW + lumaSE;
    const VFloat edgeHorz4 = vabs(edgeHorz1) * 2.0f + vabs(edgeHorz2);
    const VFloat edgeVert4 = vabs(edgeVert1) * 2.0f + vabs(edgeVert2);
    const VFloat edgeHorz3 = -2.0f * lumaW + lumaNWSW, edgeVert3 = -2.0f * lumaS + lumaSWSE;
    const VFloat edgeHorz = vabs(edgeHorz3) + edgeHorz4, edgeVert = vabs(edgeVert3) + edgeVert4;
    const VFloat subpixNWSWNESE = lumaNWSW + lumaNESE;
    const VMask horzSpan = edgeHorz >= edgeVert;  // the edge runs horizontally: search along x
    const VFloat subpixA = subpixNSWE * 2.0f + subpixNWSWNESE;
    lumaN = select(horzSpan, lumaN, lumaW), lumaS = select(horzSpan, lumaS, lumaE);
    const VFloat subpixB = subpixA * (1.0f / 12.0f) - lumaM;
    const VFloat gradientN = lumaN - lumaM, gradientS = lumaS - lumaM;
    VFloat lumaNN = lumaN + lumaM;
    const VFloat lumaSS = lumaS + lumaM;
    const VMask pairN = vabs(gradientN) >= vabs(gradientS);
    const VFloat gradient = vmax(vabs(gradientN), vabs(gradientS));
    const VFloat lengthSign = select(pairN, splat<VFloat>(-1.0f), splat<VFloat>(1.0f));
    const VFloat subpixC = vclamp(vabs(subpixB) * subpixRcpRange, splat<VFloat>(0.0f), splat<VFloat>(1.0f));
    // Start half a pixel across the edge, towards the side with the larger gradient.
    const VFloat centreX = toFloat(x) + 0.5f, centreY = toFloat(y) + 0.5f;
    const VFloat subpixD = -2.0f * subpixC + 3.0f;
    const VFloat subpixE = subpixC * subpixC;
    lumaNN = select(pairN, lumaNN, lumaSS);
    storeu(block.bx + at, select(horzSpan, centreX, centreX + lengthSign * 0.5f));
    storeu(block.by + at, select(horzSpan, centreY + lengthSign * 0.5f, centreY));
    storeu(block.lumaNN + at, lumaNN);
    storeu(block.gradientScaled + at, gradient * 0.25f);
    storeu(block.lumaMM + at, lumaM - lumaNN * 0.5f);
    storeu(block.subpixF + at, subpixD * subpixE);
    storeu(block.lengthSign + at, lengthSign);
    const VInt horz = select(horzSpan, splatInt(-1), splatInt(0));
    std::memcpy(block.horz + at, &horz, sizeof horz);
}

// (2) Pixels whose edge runs vertically: the search moves along y.
void searchVertical(const FxaaKernelArgs& a, const Sampler& f, Block& block, const int32_t* index,
                    int count) {
    float bxLanes[L], byLanes[L], nnLanes[L], gsLanes[L];
    laneLoad(block.bx, index, count, bxLanes), laneLoad(block.by, index, count, byLanes);
    laneLoad(block.lumaNN, index, count, nnLanes), laneLoad(block.gradientScaled, index, count, gsLanes);
    const VFloat bx = loadu<VFloat>(bxLanes), by = loadu<VFloat>(byLanes);
    const VFloat lumaNN = loadu<VFloat>(nnLanes), gradientScaled = loadu<VFloat>(gsLanes);
    const float* steps = a.steps;
    const VFloat nx = bx, px = bx;
    VFloat ny = by - steps[0], py = by + steps[0];
    VFloat lumaEndN = f.lumaBilinear(nx, ny) - lumaNN * 0.5f;
    VFloat lumaEndP = f.lumaBilinear(px, py) - lumaNN * 0.5f;
    VMask doneN = vabs(lumaEndN) >= gradientScaled, doneP = vabs(lumaEndP) >= gradientScaled;
    if (a.stepCount > 1) ny = select(doneN, ny, ny - steps[1]), py = select(doneP, py, py + steps[1]);
    for (int i = 2; i < a.stepCount && !all(doneN & doneP); ++i) {
        lumaEndN = select(doneN, lumaEndN, f.lumaBilinear(nx, ny) - lumaNN * 0.5f);
        lumaEndP = select(doneP, lumaEndP, f.lumaBilinear(px, py) - lumaNN * 0.5f);
        doneN = vabs(lumaEndN) >= gradientScaled;
        doneP = vabs(lumaEndP) >= gradientScaled;
        ny = select(doneN, ny, ny - steps[i]), py = select(doneP, py, py + steps[i]);
    }
    float lanes[6][L];
    storeu(lanes[0], nx), storeu(lanes[1], ny), storeu(lanes[2], px), storeu(lanes[3], py);
    storeu(lanes[4], lumaEndN), storeu(lanes[5], lumaEndP);
    for (int k = 0; k < count; ++k) {
        const int i = index[k];
        block.nx[i] = lanes[0][k], block.ny[i] = lanes[1][k], block.px[i] = lanes[2][k];
        block.py[i] = lanes[3][k], block.endN[i] = lanes[4][k], block.endP[i] = lanes[5][k];
    }
}

// Luma bilinear at the positions (x, py) of the lanes, all on the row pair of py; the lanes that matter
// read pixels first .. first + 31 of each row (AVX-512: two loads and a permute per row, no gathers).
VFloat lumaAlongRow(const FxaaKernelArgs& a, const Sampler& f, VFloat x, float py, int first) {
    const VFloat fx = x - 0.5f;
    const float fy = py - 0.5f;
    const VInt x0 = floorToInt(fx);
    const int y0 = int(std::floor(fy));
    const VFloat tx = fx - toFloat(x0);
    const float ty = fy - float(y0);
    const VInt xa = vclamp(x0, f.zero, f.lastX), xb = vclamp(x0 + 1, f.zero, f.lastX);
    const float* rowA = a.luma + size_t(std::clamp(y0, 0, a.height - 1)) * a.lumaStride + kFxaaLumaPad;
    const float* rowB = a.luma + size_t(std::clamp(y0 + 1, 0, a.height - 1)) * a.lumaStride + kFxaaLumaPad;
#if defined(DEJAG_SIMD_LEVEL_avx512)
    const __m512i ia = __m512i(xa - first), ib = __m512i(xb - first);
    const __m512 a0 = _mm512_loadu_ps(rowA + first), a1 = _mm512_loadu_ps(rowA + first + 16);
    const __m512 b0 = _mm512_loadu_ps(rowB + first), b1 = _mm512_loadu_ps(rowB + first + 16);
    const VFloat pa = VFloat(_mm512_permutex2var_ps(a0, ia, a1)),
                 pb = VFloat(_mm512_permutex2var_ps(a0, ib, a1));
    const VFloat pc = VFloat(_mm512_permutex2var_ps(b0, ia, b1)),
                 pd = VFloat(_mm512_permutex2var_ps(b0, ib, b1));
#else
    (void)first;
    const VFloat pa = gather(rowA, xa), pb = gather(rowA, xb), pc = gather(rowB, xa), pd = gather(rowB, xb);
#endif
    const VFloat top = pa + tx * (pb - pa), bottom = pc + tx * (pd - pc);
    return top + ty * (bottom - top);
}

// The end of one direction's search from its lumas at the search positions: the first position where
// the search stops, else one step past the last position read.
void searchEnd(const float* reach, int k0, int samples, VFloat end, float gradientScaled, float bx,
               float sign, bool& found, float& endX, float& endLuma) {
    uint32_t done = maskBits(vabs(end) >= splat<VFloat>(gradientScaled));
    if (samples - k0 < L) done &= (1u << (samples - k0)) - 1u;
    float lanes[L];
    storeu(lanes, end);
    if (done) {
        const int k = __builtin_ctz(done);
        endX = bx + sign * reach[k0 + k], endLuma = lanes[k], found = true;
    } else {
        endLuma = lanes[std::min(L, samples - k0) - 1];
    }
}

// (3) One pixel whose edge runs horizontally: the luma at every search position of both directions at
// once, then where each search would have stopped. reach[k] is the distance of search position k from
// the start (positions 0 .. stepCount - 2 are read, padded with the last reach).
void searchAlongRow(const FxaaKernelArgs& a, const Sampler& f, const float* reach, Block& block, int i) {
    const float bx = block.bx[i], by = block.by[i], half = block.lumaNN[i] * 0.5f;
    const float gradientScaled = block.gradientScaled[i];
    const int samples = a.stepCount - 1;
    // The window of each direction: from the farthest position read to the nearest (+1 for the pair).
    const int lastX = a.width - 1;
    const int firstN = std::clamp(int(std::floor(bx - reach[samples - 1] - 0.5f)), 0, lastX);
    const int firstP = std::clamp(int(std::floor(bx + reach[0] - 0.5f)), 0, lastX);
    bool foundN = false, foundP = false;
    float nx = 0, px = 0;
    for (int k0 = 0; k0 < samples && !(foundN && foundP); k0 += L) {
        const VFloat r = loadu<VFloat>(reach + k0);
        const VFloat endN = lumaAlongRow(a, f, bx - r, by, firstN) - half;
        const VFloat endP = lumaAlongRow(a, f, bx + r, by, firstP) - half;
        if (!foundN)
            searchEnd(reach, k0, samples, endN, gradientScaled, bx, -1.0f, foundN, nx, block.endN[i]);
        if (!foundP) searchEnd(reach, k0, samples, endP, gradientScaled, bx, 1.0f, foundP, px, block.endP[i]);
    }
    block.nx[i] = foundN ? nx : bx - reach[samples];
    block.px[i] = foundP ? px : bx + reach[samples];
    block.ny[i] = block.py[i] = by;
}

// (4) The end of the span nearer to the pixel, the sub-pixel term, and the colour there.
void finishLanes(const FxaaKernelArgs& a, const Sampler& f, VInt x, VInt y, const Block& block, int at,
                 VFloat rgb[3]) {
    VInt horzBits;
    std::memcpy(&horzBits, block.horz + at, sizeof horzBits);
    const VMask horzSpan = horzBits != splatInt(0);
    const VFloat centreX = toFloat(x) + 0.5f, centreY = toFloat(y) + 0.5f;
    const VFloat nx = loadu<VFloat>(block.nx + at), ny = loadu<VFloat>(block.ny + at);
    const VFloat px = loadu<VFloat>(block.px + at), py = loadu<VFloat>(block.py + at);
    const VFloat lumaEndN = loadu<VFloat>(block.endN + at), lumaEndP = loadu<VFloat>(block.endP + at);
    const VMask lumaMLTZero = loadu<VFloat>(block.lumaMM + at) < splat<VFloat>(0.0f);
    const VFloat subpixF = loadu<VFloat>(block.subpixF + at),
                 lengthSign = loadu<VFloat>(block.lengthSign + at);
    const VFloat dstN = select(horzSpan, centreX - nx, centreY - ny);
    const VFloat dstP = select(horzSpan, px - centreX, py - centreY);
    const VMask goodSpanN = (lumaEndN < splat<VFloat>(0.0f)) != lumaMLTZero;
    const VMask goodSpanP = (lumaEndP < splat<VFloat>(0.0f)) != lumaMLTZero;
    const VFloat spanLength = dstP + dstN;
    const VMask directionN = dstN < dstP;
    const VFloat dst = vmin(dstN, dstP);
    const VMask goodSpan = select(directionN, goodSpanN, goodSpanP);
    const VFloat subpixG = subpixF * subpixF;
    const VFloat pixelOffset = dst * (-1.0f / spanLength) + 0.5f;
    const VFloat subpixH = subpixG * a.subpix;
    const VFloat pixelOffsetGood = select(goodSpan, pixelOffset, splat<VFloat>(0.0f));
    const VFloat pixelOffsetSubpix = vmax(pixelOffsetGood, subpixH);
    const VFloat sx = select(horzSpan, centreX, centreX + pixelOffsetSubpix * lengthSign);
    const VFloat sy = select(horzSpan, centreY + pixelOffsetSubpix * lengthSign, centreY);
    f.colourBilinear(sx, sy, rgb);
}

void resolveBlock(const FxaaKernelArgs& a, const Sampler& f, const int32_t* xs, const int32_t* ys, int count,
                  float* rgb, Block& block) {
    auto lanes = [&](int i, VInt& x, VInt& y) {  // a short last group repeats its last pixel
        int32_t laneX[L], laneY[L];
        for (int k = 0; k < L; ++k) {
            const int j = std::min(i + k, count - 1);
            laneX[k] = xs[j], laneY[k] = ys[j];
        }
        std::memcpy(&x, laneX, sizeof x), std::memcpy(&y, laneY, sizeof y);
    };
    int verticals = 0, horizontals = 0;
    for (int i = 0; i < count; i += L) {
        VInt x, y;
        lanes(i, x, y);
        if (count - i >= L) {
            setupLanes(a, f, x, y, block, i);
        } else {  // the last group's lanes past count go to a spare slot
            Block spare;
            setupLanes(a, f, x, y, spare, 0);
            for (int k = 0; k < count - i; ++k) {
                block.bx[i + k] = spare.bx[k], block.by[i + k] = spare.by[k],
                             block.lumaNN[i + k] = spare.lumaNN[k];
                block.gradientScaled[i + k] = spare.gradientScaled[k], block.lumaMM[i + k] = spare.lumaMM[k];
                block.subpixF[i + k] = spare.subpixF[k], block.lengthSign[i + k] = spare.lengthSign[k];
                block.horz[i + k] = spare.horz[k];
            }
        }
    }
    for (int i = 0; i < count; ++i)
        (block.horz[i] ? block.horizontal[horizontals++] : block.vertical[verticals++]) = i;
    for (int i = 0; i < verticals; i += L)
        searchVertical(a, f, block, block.vertical + i, std::min(L, verticals - i));
    float reach[64];  // search position k's distance from the start: steps[0] + ... + steps[k]
    reach[0] = a.steps[0];
    for (int k = 1; k < a.stepCount; ++k) reach[k] = reach[k - 1] + a.steps[k];
    for (int k = a.stepCount; k < 64; ++k) reach[k] = reach[a.stepCount - 1];
    for (int h = 0; h < horizontals; ++h) searchAlongRow(a, f, reach, block, block.horizontal[h]);
    for (int i = 0; i < count; i += L) {
        VInt x, y;
        lanes(i, x, y);
        const int n = std::min(L, count - i);
        VFloat result[3];
        if (n == L) {
            finishLanes(a, f, x, y, block, i, result);
        } else {
            Block spare;  // the last group: its arrays padded with the last pixel
            for (int k = 0; k < L; ++k) {
                const int j = i + std::min(k, n - 1);
                spare.horz[k] = block.horz[j], spare.nx[k] = block.nx[j], spare.ny[k] = block.ny[j];
                spare.px[k] = block.px[j], spare.py[k] = block.py[j], spare.endN[k] = block.endN[j];
                spare.endP[k] = block.endP[j], spare.lumaMM[k] = block.lumaMM[j],
                spare.subpixF[k] = block.subpixF[j];
                spare.lengthSign[k] = block.lengthSign[j];
            }
            finishLanes(a, f, x, y, spare, 0, result);
        }
        float channel[3][L];
        for (int c = 0; c < 3; ++c) storeu(channel[c], result[c]);
        for (int k = 0; k < n; ++k) {
            float* out = rgb + 3 * size_t(i + k);
            out[0] = channel[0][k], out[1] = channel[1][k], out[2] = channel[2][k];
        }
    }
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
    Block block;
    for (int i = 0; i < count; i += kBlock)
        resolveBlock(a, sampler, xs + i, ys + i, std::min(kBlock, count - i), rgb + 3 * size_t(i), block);
}

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

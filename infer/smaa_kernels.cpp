// SMAA's per-row kernels (infer/smaa_kernels.h), compiled once per SIMD level. The edge decisions are
// threshold comparisons computed in the same order on every level (no contraction), so every level finds
// the same edges; the blending is scalar per blended pixel (they are few) with the sRGB curves of
// base/srgb_simd.h.
#include "infer/smaa_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "base/pixel_simd.h"
#include "base/srgb_simd.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {

using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

namespace {

const PowerCurve& decodeCurve() {
    return srgbDecodeCurve7();
}
const PowerCurve& encodeCurve() {
    return srgbEncodeCurve7();
}

const float* lumaRow(const SmaaKernelArgs& a, int y) {
    return a.luma + size_t(std::clamp(y, 0, a.height - 1)) * a.lumaStride + kSmaaLumaPad;
}

// The thresholds of the left and top boundaries of (x, y): the global one, or with predication the
// global one scaled, lowered where the depth steps across the boundary too.
inline void thresholds(const SmaaKernelArgs& a, int x, int y, float& left, float& top) {
    if (!a.depth) {
        left = top = a.threshold;
        return;
    }
    const float* d = a.depth + size_t(y) * size_t(a.width);
    const float here = d[x];
    const float l = d[std::max(x - 1, 0)], t = y > 0 ? d[x - a.width] : here;
    const float base = a.predicationScale * a.threshold;
    left = base * (1.0f - a.predicationStrength * float(std::abs(here - l) >= a.predicationThreshold));
    top = base * (1.0f - a.predicationStrength * float(std::abs(here - t) >= a.predicationThreshold));
}

// The edge bits of one pixel from its steps: to the left and top (dl, dt), right and bottom (dr, db), and
// beyond the left and top neighbours (dll, dtt). An edge is kept where its step reaches the threshold and
// is at least half the largest step around (local contrast adaptation, factor 2).
inline uint8_t edgeBits(float dl, float dt, float dr, float db, float dll, float dtt, float thLeft,
                        float thTop) {
    const bool el = dl >= thLeft, et = dt >= thTop;
    if (!(el || et)) return 0;
    const float m = std::max(std::max(std::max(dl, dr), dll), std::max(std::max(dt, db), dtt));
    return uint8_t(int(el && 2.0f * dl >= m) | int(et && 2.0f * dt >= m) << 1);
}

// The low byte of each lane to dst[0 .. kFloatLanes).
inline void storeBytes(uint8_t* dst, VInt v) {
#if defined(DEJAG_SIMD_LEVEL_scalar)
    *dst = uint8_t(v);
#else
    typedef uint8_t Bytes __attribute__((vector_size(kFloatLanes)));
    const Bytes bytes = __builtin_convertvector(v, Bytes);
    std::memcpy(dst, &bytes, kFloatLanes);
#endif
}

inline float colourStep(const float* p, const float* q) {
    return std::max(std::max(std::abs(p[0] - q[0]), std::abs(p[1] - q[1])), std::abs(p[2] - q[2]));
}

}  // namespace

void smaaLumaRow(const SmaaKernelArgs& a, int y) {
    const float* src = a.frame + size_t(y) * size_t(a.width) * size_t(a.channels);
    float* dst = a.luma + size_t(y) * a.lumaStride + kSmaaLumaPad;
    const int c = a.channels;
    if (c == 3) {
        int x = 0;
        for (; x + kFloatLanes <= a.width; x += kFloatLanes) {
            VFloat r, g, b;
            loadRgb(src + 3 * x, r, g, b);
            storeu(dst + x, 0.2126f * r + 0.7152f * g + 0.0722f * b);
        }
        for (; x < a.width; ++x)
            dst[x] = 0.2126f * src[3 * x] + 0.7152f * src[3 * x + 1] + 0.0722f * src[3 * x + 2];
    } else {
        for (int x = 0; x < a.width; ++x)
            dst[x] = 0.2126f * src[c * x] + 0.7152f * src[c * x + 1] + 0.0722f * src[c * x + 2];
    }
    for (int k = 1; k <= kSmaaLumaPad; ++k) dst[-k] = dst[0], dst[a.width - 1 + k] = dst[a.width - 1];
}

int smaaEdgeRow(const SmaaKernelArgs& a, int y) {
    uint8_t* e = a.edges + size_t(y + a.edgePad) * a.edgeStride + size_t(a.edgePad);
    int count = 0;
    if (!a.colourEdges) {
        const float *l0 = lumaRow(a, y), *lt = lumaRow(a, y - 1), *ltt = lumaRow(a, y - 2),
                    *lb = lumaRow(a, y + 1);
        if (!a.depth) {
            const float th = a.threshold;
            int x = 0;
            // kFloatLanes pixels at a time, the same comparisons in the same order as edgeBits().
            const VFloat thv = splat<VFloat>(th), two = splat<VFloat>(2.0f);
            for (; x + kFloatLanes <= a.width; x += kFloatLanes) {
                const VFloat L = loadu<VFloat>(l0 + x), Ll = loadu<VFloat>(l0 + x - 1);
                const VFloat Lt = loadu<VFloat>(lt + x);
                const VFloat dl = vabs(L - Ll), dt = vabs(L - Lt);
                const VFloat dr = vabs(L - loadu<VFloat>(l0 + x + 1)), db = vabs(L - loadu<VFloat>(lb + x));
                const VFloat dll = vabs(Ll - loadu<VFloat>(l0 + x - 2)),
                             dtt = vabs(Lt - loadu<VFloat>(ltt + x));
                const VFloat m = vmax(vmax(vmax(dl, dr), dll), vmax(vmax(dt, db), dtt));
                const VMask el = (dl >= thv) & (two * dl >= m), et = (dt >= thv) & (two * dt >= m);
                const VInt bits = select(el, splatInt(1), splatInt(0)) | select(et, splatInt(2), splatInt(0));
                storeBytes(e + x, bits);
                count += __builtin_popcount(maskBits(bits != splatInt(0)));
            }
            for (; x < a.width; ++x) {
                const float L = l0[x];
                const float dl = std::abs(L - l0[x - 1]), dt = std::abs(L - lt[x]);
                const float dr = std::abs(L - l0[x + 1]), db = std::abs(L - lb[x]);
                const float dll = std::abs(l0[x - 1] - l0[x - 2]), dtt = std::abs(lt[x] - ltt[x]);
                e[x] = edgeBits(dl, dt, dr, db, dll, dtt, th, th);
                count += e[x] != 0;
            }
        } else {
            for (int x = 0; x < a.width; ++x) {
                float thLeft, thTop;
                thresholds(a, x, y, thLeft, thTop);
                const float L = l0[x];
                e[x] = edgeBits(std::abs(L - l0[x - 1]), std::abs(L - lt[x]), std::abs(L - l0[x + 1]),
                                std::abs(L - lb[x]), std::abs(l0[x - 1] - l0[x - 2]),
                                std::abs(lt[x] - ltt[x]), thLeft, thTop);
                count += e[x] != 0;
            }
        }
        return count;
    }
    // Colour: the largest of the three channels' steps.
    const size_t c = size_t(a.channels), w = size_t(a.width);
    auto at = [&](int x, int yy) {
        return a.frame +
               (size_t(std::clamp(yy, 0, a.height - 1)) * w + size_t(std::clamp(x, 0, a.width - 1))) * c;
    };
    for (int x = 0; x < a.width; ++x) {
        float thLeft, thTop;
        thresholds(a, x, y, thLeft, thTop);
        const float* p = at(x, y);
        const float* l = at(x - 1, y);
        const float* t = at(x, y - 1);
        e[x] = edgeBits(colourStep(p, l), colourStep(p, t), colourStep(p, at(x + 1, y)),
                        colourStep(p, at(x, y + 1)), colourStep(l, at(x - 2, y)), colourStep(t, at(x, y - 2)),
                        thLeft, thTop);
        count += e[x] != 0;
    }
    return count;
}

void smaaBlendRow(const SmaaKernelArgs& a, int y) {
    const size_t c = size_t(a.channels), w = size_t(a.width);
    const float* in = a.frame + size_t(y) * w * c;
    float* out = a.out + size_t(y) * w * c;
    std::memcpy(out, in, w * c * sizeof(float));
    const uint8_t* e0 = a.edges + size_t(y + a.edgePad) * a.edgeStride + size_t(a.edgePad);
    const uint8_t* e1 = e0 + a.edgeStride;  // the row below (the zero pad below the last row)
    const float* weights = a.weights + size_t(y) * w * 4;
    const int32_t rowStart = int32_t(size_t(y) * w * c);  // (Smaa::apply keeps frames below 2^31 floats)
    const int32_t upStep = y > 0 ? int32_t(w * c) : 0, downStep = y + 1 < a.height ? int32_t(w * c) : 0;
    // The pixels that blend, collected a batch at a time: their offset in the frame, their two
    // neighbours' and the two weights; then mixed kFloatLanes at a time.
    constexpr int kBatch = 128;
    alignas(64) int32_t at[kBatch + kFloatLanes], n1[kBatch + kFloatLanes], n2[kBatch + kFloatLanes];
    alignas(64) float w1[kBatch + kFloatLanes], w2[kBatch + kFloatLanes];
    int count = 0;
    auto flush = [&] {
        if (count == 0) return;
        for (int k = count; k % kFloatLanes != 0; ++k)  // the last vector's spare lanes repeat a pixel
            at[k] = at[count - 1], n1[k] = n1[count - 1], n2[k] = n2[count - 1], w1[k] = w1[count - 1],
            w2[k] = w2[count - 1];
        const PowerCurve &dec = decodeCurve(), &enc = encodeCurve();
        for (int i = 0; i < count; i += kFloatLanes) {
            VInt p, q1, q2;
            std::memcpy(&p, at + i, sizeof(VInt)), std::memcpy(&q1, n1 + i, sizeof(VInt)),
                std::memcpy(&q2, n2 + i, sizeof(VInt));
            const VFloat a1 = loadu<VFloat>(w1 + i), a2 = loadu<VFloat>(w2 + i);
            const VFloat scale = 1.0f / (a1 + a2);
            alignas(64) float result[3][kFloatLanes];
            for (int k = 0; k < 3; ++k) {
                VFloat v0 = gather(a.frame + k, p), v1 = gather(a.frame + k, q1),
                       v2 = gather(a.frame + k, q2);
                if (a.linear)
                    v0 = decodeSrgbBy<7>(dec, v0), v1 = decodeSrgbBy<7>(dec, v1),
                    v2 = decodeSrgbBy<7>(dec, v2);
                // Each weight mixes the pixel toward its neighbour by that amount (a bilinear read at that
                // offset); the two mixes are averaged by the weights.
                VFloat v = (a1 * (v0 + (v1 - v0) * a1) + a2 * (v0 + (v2 - v0) * a2)) * scale;
                if (a.linear) v = encodeSrgbBy<7>(enc, v);
                storeu(result[k], v);
            }
            for (int l = 0; l < std::min(kFloatLanes, count - i); ++l) {
                float* o = a.out + at[i + l];
                o[0] = result[0][l], o[1] = result[1][l], o[2] = result[2][l];
            }
        }
        count = 0;
    };
    for (int x = 0; x < a.width;) {
        // Eight pixels at once where none of them, their right neighbours or the pixels below has an edge
        // (the pads are zero, so the reads past the row's end are in bounds).
        uint64_t here, right, below;
        std::memcpy(&here, e0 + x, 8), std::memcpy(&right, e0 + x + 1, 8), std::memcpy(&below, e1 + x, 8);
        if ((here | right | below) == 0) {
            x += 8;
            continue;
        }
        const int end = std::min(x + 8, a.width);
        for (; x < end; ++x) {
            // The pixel's own weights toward its top and left neighbours, its right neighbour's toward it
            // (that neighbour's left edge), the pixel below's toward it (that pixel's top edge).
            float toTop = 0, toLeft = 0, toRight = 0, toBottom = 0;
            if (e0[x]) toTop = weights[4 * x], toLeft = weights[4 * x + 2];
            if (e0[x + 1]) toRight = weights[4 * x + 7];
            if (e1[x]) toBottom = weights[4 * (w + size_t(x)) + 1];
            if (toTop + toLeft + toRight + toBottom < 1e-5f) continue;
            // The stronger direction wins, with its two weights.
            const int32_t self = rowStart + int32_t(c) * x;
            at[count] = self;
            if (std::max(toRight, toLeft) > std::max(toBottom, toTop)) {
                w1[count] = toRight, w2[count] = toLeft;
                n1[count] = self + (x + 1 < a.width ? int32_t(c) : 0),
                n2[count] = self - (x > 0 ? int32_t(c) : 0);
            } else {
                w1[count] = toBottom, w2[count] = toTop;
                n1[count] = self + downStep, n2[count] = self - upStep;
            }
            if (++count == kBatch) flush();
        }
    }
    flush();
}

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

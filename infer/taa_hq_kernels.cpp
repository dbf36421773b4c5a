// taa-hq's band kernel (infer/taa_hq_kernels.h), compiled once per SIMD level: kFloatLanes pixels of a row
// at a time, the steps of infer/taa_hq.h in its order (docs/taa-hq.md).
#include "infer/taa_hq_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "base/pixel_simd.h"
#include "base/srgb_simd.h"
#include "data/image.h"
#include "infer/row_ring.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {

using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

namespace {

constexpr int L = kFloatLanes;
static_assert(RowRing::kRows == kTaaHqRingRows && RowRing::kPad == kTaaHqRowPad);

// Motion below this (pixels) is none: the static lock's test.
constexpr float kStill = 1e-3f;

// ---- sRGB by exponent and mantissa (base/srgb_simd.h): degree 5 for p = 2.4, 6 for p = 1/2.4 ---------

const PowerCurve& decodeCurve() {  // ((v + 0.055) / 1.055)^2.4
    static const PowerCurve curve = fitPower(2.4, 5, 1.0);
    return curve;
}
const PowerCurve& encodeCurve() {  // 1.055 x^(1/2.4) (- 0.055)
    static const PowerCurve curve = fitPower(1 / 2.4, 6, 1.055);
    return curve;
}

// sRGB-encoded [0, 1] (clamped; NaN reads 0) to linear light, and back.
inline VFloat decodeSrgb(VFloat v) {
    return decodeSrgbBy<5>(decodeCurve(), v);
}
inline VFloat encodeSrgb(VFloat x) {
    return encodeSrgbBy<6>(encodeCurve(), x);
}

// ---- the band ----------------------------------------------------------------------------------------

struct Ycocg {
    VFloat y, co, cg;
};
inline Ycocg toYcocg(VFloat r, VFloat g, VFloat b) {
    return {0.25f * r + 0.5f * g + 0.25f * b, 0.5f * (r - b), -0.25f * r + 0.5f * g - 0.25f * b};
}

// Catmull-Rom weights of the four taps around a sample at fraction t past the second.
inline void catmullRom(VFloat t, VFloat* w) {
    const VFloat t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.0f;
    w[2] = -1.5f * t3 + 2.0f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
}

class Band {
  public:
    Band(const TaaHqBandInputs& in, int y0, int y1, float* scratch)
        : in_(in), W_(in.width), H_(in.height), y0_(y0), y1_(y1), useDepth_(in.depth && in.previousDepth) {
        const size_t rowFloats = taaHqRowFloats(W_);
        float* cursor = scratch;
        linear_.carve(cursor, rowFloats, 3);
        ycocg_.carve(cursor, rowFloats, 3);
        depth_.carve(cursor, rowFloats, 3);
        motion_.carve(cursor, rowFloats, 4);
        output_.carve(cursor, rowFloats, 3);
    }

    void run() {
        if (in_.sharpen > 0) {
            for (int y = y0_; y < y1_; ++y) sharpenRow(y);
        } else {
            for (int y = y0_; y < y1_; ++y) resolve(y, nullptr);
        }
    }

  private:
    const TaaHqBandInputs& in_;
    const int W_, H_, y0_, y1_;
    const bool useDepth_;
    RowRing linear_, ycocg_, depth_, motion_, output_;

    template <class Fill>
    const float* row(RowRing& ring, int y, Fill fill) {
        return ring.row(y, W_, H_, fill);
    }

    // The current frame's in-pixel samples in linear light: row y holds the frame's pixels
    // (clamp(x + shiftX), clamp(y + shiftY)).
    const float* linearRow(int y) {
        return row(linear_, y, [&](int yy, float* r) {
            const int sy = std::clamp(yy + in_.shiftY, 0, H_ - 1), sx = in_.shiftX;
            const float* src = in_.colour + size_t(sy) * size_t(W_) * 3;
            float *g = r + linear_.rowFloats, *b = g + linear_.rowFloats;
            // Columns whose source x + sx lies in the row: [first, last).
            const int first = std::clamp(-sx, 0, W_), last = std::clamp(W_ - sx, first, W_);
            auto one = [&](int x) {
                const float* p = src + 3 * std::clamp(x + sx, 0, W_ - 1);
                r[x] = p[0], g[x] = p[1], b[x] = p[2];
            };
            int x = 0;
            for (; x < first; ++x) one(x);
            for (; x + L <= last; x += L) {
                VFloat vr, vg, vb;
                loadRgb(src + 3 * (x + sx), vr, vg, vb);
                storeu(r + x, vr), storeu(g + x, vg), storeu(b + x, vb);
            }
            for (; x < W_; ++x) one(x);
            for (int k = 0; k < 3; ++k) {
                float* plane = r + size_t(k) * linear_.rowFloats;
                for (x = 0; x < W_; x += L) storeu(plane + x, decodeSrgb(loadu<VFloat>(plane + x)));
            }
        });
    }
    const float* ycocgRow(int y) {
        return row(ycocg_, y, [&](int yy, float* out) {
            const float* r = linearRow(yy);
            const float *g = r + linear_.rowFloats, *b = g + linear_.rowFloats;
            const size_t plane = ycocg_.rowFloats;
            for (int x = 0; x < W_; x += L) {
                const Ycocg v = toYcocg(loadu<VFloat>(r + x), loadu<VFloat>(g + x), loadu<VFloat>(b + x));
                storeu(out + x, v.y), storeu(out + plane + x, v.co), storeu(out + 2 * plane + x, v.cg);
            }
        });
    }
    // Planes: depth, and its smallest and largest over x - 1 .. x + 1 (clamp to edge).
    const float* depthRow(int y) {
        return row(depth_, y, [&](int yy, float* r) {
            std::copy(in_.depth + size_t(yy) * size_t(W_), in_.depth + size_t(yy + 1) * size_t(W_), r);
            r[-1] = r[0], r[W_] = r[W_ - 1];
            float *lo = r + depth_.rowFloats, *hi = lo + depth_.rowFloats;
            for (int x = 0; x < W_; x += L) {
                const VFloat a = loadu<VFloat>(r + x - 1), b = loadu<VFloat>(r + x),
                             c = loadu<VFloat>(r + x + 1);
                storeu(lo + x, vmin(vmin(a, b), c)), storeu(hi + x, vmax(vmax(a, b), c));
            }
        });
    }
    // Planes: motion x and y (below kStill in both, none: exactly 0), whether it is not none (1 or 0; a
    // motion that is not a number counts as moving), and that flag's largest over x - 1 .. x + 1.
    const float* motionRow(int y) {
        return row(motion_, y, [&](int yy, float* r) {
            const float* src = in_.motion + size_t(yy) * size_t(W_) * 2;
            float *v = r + motion_.rowFloats, *moved = v + motion_.rowFloats,
                  *moved3 = moved + motion_.rowFloats;
            splitPairs(src, r, v, W_);
            int x = 0;
            const VFloat still = splat<VFloat>(kStill), zero = splat<VFloat>(0.0f);
            for (x = 0; x < W_; x += L) {
                const VFloat vx = loadu<VFloat>(r + x), vy = loadu<VFloat>(v + x);
                const VMask none = (vabs(vx) < still) & (vabs(vy) < still);
                storeu(r + x, select(none, zero, vx)), storeu(v + x, select(none, zero, vy));
                storeu(moved + x, select(none, zero, splat<VFloat>(1.0f)));
            }
            moved[-1] = moved[0], moved[W_] = moved[W_ - 1];
            for (x = 0; x < W_; x += L)
                storeu(moved3 + x, vmax(vmax(loadu<VFloat>(moved + x - 1), loadu<VFloat>(moved + x)),
                                        loadu<VFloat>(moved + x + 1)));
        });
    }

    // Where the lanes read plane[(x, y)] (rows `stride` floats apart), decided once for the planes that
    // share the coordinates: consecutive pixels of one row (a still view, a pan) by one load; at most two
    // neighbouring rows within a window (smooth motion) by two rows' windows and a permute; else a gather.
    // (Every plane read this way has stride + kWindowFloats readable floats after any of its pixels.)
    struct Taps {
        enum Kind { Contiguous, Windowed, Gathered } kind = Gathered;
        size_t offset = 0;  // Contiguous: the first lane's float; Windowed: the window's first float
        size_t stride = 0;
        bool twoRows = false;
        VInt index;   // Windowed: the lane's float in the window; Gathered: in the plane
        VMask upper;  // Windowed with two rows: lanes on the second

        Taps(VInt x, VInt y, size_t rowStride) : stride(rowStride) {
#if !defined(DEJAG_SIMD_LEVEL_scalar)
            const int row = laneMin(y), first = laneMin(x);
            if (all((x == splatInt(first) + laneIndex()) & (y == splatInt(row)))) {
                kind = Contiguous, offset = size_t(row) * stride + size_t(first);
                return;
            }
            const int rows = laneMax(y) - row;
            if (rows <= 1 && withinWindow(x, x, first)) {
                kind = Windowed, offset = size_t(row) * stride + size_t(first);
                index = x - first, twoRows = rows == 1, upper = y != splatInt(row);
                return;
            }
            index = y * splatInt(int32_t(stride)) + x;
#else
            kind = Contiguous, offset = size_t(y) * stride + size_t(x);
#endif
        }
        VFloat read(const float* plane) const {
#if !defined(DEJAG_SIMD_LEVEL_scalar)
            if (kind == Contiguous) return loadu<VFloat>(plane + offset);
            if (kind == Windowed) {
                const VFloat a = fromWindow(loadWindow(plane + offset), index);
                if (!twoRows) return a;
                return select(upper, fromWindow(loadWindow(plane + offset + stride), index), a);
            }
            return gather(plane, index);
#else
            return plane[offset];
#endif
        }
    };

    // The smallest and largest of plane's 3x3 around (x, y), clamp to edge.
    void range3x3(const float* plane, size_t stride, size_t floats, VInt x, VInt y, VFloat& lo,
                  VFloat& hi) const {
        const VInt zero = splatInt(0), lastX = splatInt(W_ - 1), lastY = splatInt(H_ - 1);
        const VInt xs[3] = {vclamp(x - 1, zero, lastX), x, vclamp(x + 1, zero, lastX)};
        lo = splat<VFloat>(1e30f), hi = splat<VFloat>(-1e30f);
#if !defined(DEJAG_SIMD_LEVEL_scalar)
        const int first = laneMin(x);
        if (first >= 1 && first + L <= W_ - 1 && all(y == splatInt(y[0])) &&
            all(x == splatInt(first) + laneIndex())) {
            // Consecutive pixels of one row, none on the frame's left or right edge: plain loads.
            for (int dy = -1; dy <= 1; ++dy) {
                const float* p =
                    plane + size_t(std::clamp(int(y[0]) + dy, 0, H_ - 1)) * stride + size_t(first);
                for (int dx = -1; dx <= 1; ++dx) {
                    const VFloat v = loadu<VFloat>(p + dx);
                    lo = vmin(lo, v), hi = vmax(hi, v);
                }
            }
            return;
        }
        const int row = laneMin(y);
        const int firstLeft = laneMin(xs[0]);
        const int spread = laneMax(y) - row;
        if (spread <= 1 && withinWindow(xs[0], xs[2], firstLeft) &&
            size_t(std::min(row + 2, H_ - 1)) * stride + size_t(firstLeft) + kWindowFloats <= floats) {
            const VMask shifted = y != splatInt(row);
            for (int r = 0; r < 3 + spread; ++r) {
                const int physical = std::clamp(row - 1 + r, 0, H_ - 1);
                const Window w = loadWindow(plane + size_t(physical) * stride + size_t(firstLeft));
                VFloat rowLo = fromWindow(w, xs[0] - firstLeft), rowHi = rowLo;
                for (int k = 1; k < 3; ++k) {
                    const VFloat v = fromWindow(w, xs[k] - firstLeft);
                    rowLo = vmin(rowLo, v), rowHi = vmax(rowHi, v);
                }
                // (rows row - 1 .. row + 1 for the lanes on `row`, one further for the others)
                const VMask in = r == 0 ? maskNot(shifted) : r == 3 ? shifted : splatInt(-1);
                lo = select(in, vmin(lo, rowLo), lo), hi = select(in, vmax(hi, rowHi), hi);
            }
            return;
        }
#endif
        (void)floats;
        // Lanes whose 3 taps and one more lie inside the row read them as 4 consecutive floats.
        const bool inside = all((x >= splatInt(1)) & (x <= splatInt(W_ - 3)));
        for (int dy = -1; dy <= 1; ++dy) {
            const VInt rowStart = vclamp(y + dy, zero, lastY) * splatInt(int32_t(stride));
            VFloat v[4];
            if (inside) {
                loadQuads(plane, rowStart + xs[0], v);
            } else {
                for (int k = 0; k < 3; ++k) v[k] = gather(plane, rowStart + xs[k]);
            }
            for (int k = 0; k < 3; ++k) lo = vmin(lo, v[k]), hi = vmax(hi, v[k]);
        }
    }

    // The history's R G B at pixel coordinates (hx, hy): 4x4 Catmull-Rom (or bilinear) deringed to the
    // 2x2 bilinear footprint's range.
    void resampleHistory(VFloat hx, VFloat hy, VFloat* h) const {
        const VFloat u = hx - 0.5f, v = hy - 0.5f;
        const VInt ix = floorToInt(u), iy = floorToInt(v);
        const VFloat fx = u - toFloat(ix), fy = v - toFloat(iy);
        VFloat wx[4], wy[4];
        if (in_.catmullRom) {
            catmullRom(fx, wx), catmullRom(fy, wy);
        } else {
            wx[0] = wx[3] = wy[0] = wy[3] = splat<VFloat>(0.0f);
            wx[1] = 1.0f - fx, wx[2] = fx, wy[1] = 1.0f - fy, wy[2] = fy;
        }
        const VInt zero = splatInt(0), lastX = splatInt(W_ - 1), lastY = splatInt(H_ - 1);
        const size_t stride = in_.stride, planeFloats = in_.planeFloats;
        const VInt xs[4] = {vclamp(ix - 1, zero, lastX), vclamp(ix, zero, lastX), vclamp(ix + 1, zero, lastX),
                            vclamp(ix + 2, zero, lastX)};
        VFloat acc[3], lo[3], hi[3];
        for (int k = 0; k < 3; ++k)
            acc[k] = splat<VFloat>(0.0f), lo[k] = splat<VFloat>(1e30f), hi[k] = splat<VFloat>(-1e30f);
        auto horizontal = [&](const VFloat* t) {
            return wx[0] * t[0] + wx[1] * t[1] + wx[2] * t[2] + wx[3] * t[3];
        };
#if !defined(DEJAG_SIMD_LEVEL_scalar)
        const int row = laneMin(iy), first = laneMin(xs[0]);
        const int spread = laneMax(iy) - row;
        if (spread <= 1 && withinWindow(xs[0], xs[3], first)) {
            // Rows row - 1 .. row + 2 (+1): lane with iy = row weighs row - 1 + j by wy[j]; one further for
            // iy = row + 1.
            const VMask shifted = iy != splatInt(row);
            const VFloat zeroF = splat<VFloat>(0.0f);
            for (int r = 0; r < 4 + spread; ++r) {
                const int physical = std::clamp(row - 1 + r, 0, H_ - 1);
                const VFloat weight = select(shifted, r >= 1 ? wy[r - 1] : zeroF, r <= 3 ? wy[r] : zeroF);
                const VMask inner = r == 1   ? maskNot(shifted)
                                    : r == 2 ? splatInt(-1)
                                    : r == 3 ? shifted
                                             : splatInt(0);
                for (int k = 0; k < 3; ++k) {
                    const Window w = loadWindow(in_.history + size_t(k) * planeFloats +
                                                size_t(physical) * stride + size_t(first));
                    VFloat t[4];
                    for (int i = 0; i < 4; ++i) t[i] = fromWindow(w, xs[i] - first);
                    acc[k] = acc[k] + weight * horizontal(t);
                    if (r >= 1 && r <= 3) {
                        lo[k] = select(inner, vmin(lo[k], vmin(t[1], t[2])), lo[k]);
                        hi[k] = select(inner, vmax(hi[k], vmax(t[1], t[2])), hi[k]);
                    }
                }
            }
            for (int k = 0; k < 3; ++k) h[k] = vclamp(acc[k], lo[k], hi[k]);
            return;
        }
#endif
        // Lanes whose 4 taps lie inside the row read them as 4 consecutive floats.
        const bool inside = all((ix >= splatInt(1)) & (ix <= splatInt(W_ - 3)));
        for (int j = 0; j < 4; ++j) {
            const VInt rowStart = vclamp(iy - 1 + j, zero, lastY) * splatInt(int32_t(stride));
            for (int k = 0; k < 3; ++k) {
                const float* plane = in_.history + size_t(k) * planeFloats;
                VFloat t[4];
                if (inside) {
                    loadQuads(plane, rowStart + xs[0], t);
                } else {
                    for (int i = 0; i < 4; ++i) t[i] = gather(plane, rowStart + xs[i]);
                }
                acc[k] = acc[k] + wy[j] * horizontal(t);
                if (j == 1 || j == 2) {
                    lo[k] = vmin(lo[k], vmin(t[1], t[2]));
                    hi[k] = vmax(hi[k], vmax(t[1], t[2]));
                }
            }
        }
        for (int k = 0; k < 3; ++k) h[k] = vclamp(acc[k], lo[k], hi[k]);
    }

    // Steps 1-6 for row y: the output (sRGB) into the output ring's row when `ring` (before the sharpen),
    // else into the frame's output; the history of rows inside the band.
    void resolve(int y, float* ring) {
        const float* lin = linearRow(y);
        const float* yc[3] = {};  // made when a pixel of the row is first clipped
        const float* m[3] = {motionRow(y - 1), motionRow(y), motionRow(y + 1)};
        const float* d[3] = {};
        if (in_.depth)
            for (int k = 0; k < 3; ++k) d[k] = depthRow(y - 1 + k);
        const size_t lp = linear_.rowFloats, yp = ycocg_.rowFloats, mp = motion_.rowFloats;
        const bool inBand = y >= y0_ && y < y1_;
        float* history = inBand ? in_.nextHistory + size_t(y) * in_.stride : nullptr;
        const size_t planeFloats = in_.planeFloats;
        const size_t depthFloats = size_t(W_) * size_t(H_);
        const float* historyWeight = in_.history + 3 * planeFloats;
        const VFloat rowCentre = splat<VFloat>(float(y) + 0.5f);
        const VInt zero = splatInt(0), lastX = splatInt(W_ - 1), lastY = splatInt(H_ - 1);
        const VFloat gamma = splat<VFloat>(in_.clipGamma), maxWeight = splat<VFloat>(in_.maxWeight),
                     movingMaxWeight = splat<VFloat>(in_.movingMaxWeight);
        const VFloat clippedWeight = splat<VFloat>(in_.clippedWeight);
        float* dst = in_.out + size_t(y) * size_t(W_) * 3;
        // (Prefetched a little ahead: the history where a still or slow pixel reads it, the previous depth's
        // next row. The loop body is long, so the core alone keeps too few of these loads in flight.)
        const float* historyRow = in_.history + size_t(y) * in_.stride;
        const float* previousDepthRow =
            useDepth_ ? in_.previousDepth + size_t(std::min(y + 1, H_ - 1)) * size_t(W_) : nullptr;
        // (And the frame's rows the next row will make into ring rows, and the next history's row after
        // this one: made in bursts between rows, they otherwise waited for memory.)
        const size_t input = size_t(std::clamp(y + 2, 0, H_ - 1)) * size_t(W_);
        const float* colourAhead =
            in_.colour + 3 * (size_t(std::clamp(y + 2 + in_.shiftY, 0, H_ - 1)) * size_t(W_));
        const float* motionAhead = in_.motion + 2 * input;
        const float* depthAhead = in_.depth ? in_.depth + input : nullptr;
        float* nextHistoryAhead = in_.nextHistory + size_t(std::min(y + 1, H_ - 1)) * in_.stride;
        constexpr int kLine = 16;  // floats
        for (int x = 0; x < W_; x += L) {
            const int ahead = std::min(x + 8 * L, W_ - 1);
            // (written out here: through a helper, GCC 12 dropped every prefetch once there were six)
            for (int k = 0; k < 4; ++k) __builtin_prefetch(historyRow + size_t(k) * planeFloats + ahead);
            if (previousDepthRow) __builtin_prefetch(previousDepthRow + ahead);
            for (int k = 0; k < 3 * L; k += kLine) __builtin_prefetch(colourAhead + 3 * x + k, 0, 2);
            for (int k = 0; k < 2 * L; k += kLine) __builtin_prefetch(motionAhead + 2 * x + k, 0, 2);
            if (depthAhead) __builtin_prefetch(depthAhead + x, 0, 2);
            for (int k = 0; k < 4; ++k)
                __builtin_prefetch(nextHistoryAhead + size_t(k) * planeFloats + x, 1, 2);
            // 1. The current sample.
            const VFloat c[3] = {loadu<VFloat>(lin + x), loadu<VFloat>(lin + lp + x),
                                 loadu<VFloat>(lin + 2 * lp + x)};
            // Whether anything moved in the 3x3 (the static lock's test).
            const VFloat anyMoved =
                vmax(vmax(loadu<VFloat>(m[0] + 3 * mp + x), loadu<VFloat>(m[1] + 3 * mp + x)),
                     loadu<VFloat>(m[2] + 3 * mp + x));
            const VMask movedNow = anyMoved > splat<VFloat>(0.5f);
            // 2. Where the pixel was: the motion of the nearest surface in the 3x3 (none if none moved);
            // the 3x3's depth range.
            VFloat vx = loadu<VFloat>(m[1] + x), vy = loadu<VFloat>(m[1] + mp + x);
            VFloat curLo = splat<VFloat>(0.0f), curHi = curLo;
            if (in_.depth) {
                if (any(movedNow)) {
                    VFloat closest = loadu<VFloat>(d[1] + x);
                    curLo = closest, curHi = closest;
                    for (int dy = 0; dy < 3; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const VFloat depth = loadu<VFloat>(d[dy] + x + dx);
                            const VMask nearer = depth < closest;
                            closest = select(nearer, depth, closest);
                            vx = select(nearer, loadu<VFloat>(m[dy] + x + dx), vx);
                            vy = select(nearer, loadu<VFloat>(m[dy] + mp + x + dx), vy);
                            curLo = vmin(curLo, depth), curHi = vmax(curHi, depth);
                        }
                } else if (useDepth_) {
                    const size_t dp = depth_.rowFloats;
                    curLo = vmin(vmin(loadu<VFloat>(d[0] + dp + x), loadu<VFloat>(d[1] + dp + x)),
                                 loadu<VFloat>(d[2] + dp + x));
                    curHi = vmax(vmax(loadu<VFloat>(d[0] + 2 * dp + x), loadu<VFloat>(d[1] + 2 * dp + x)),
                                 loadu<VFloat>(d[2] + 2 * dp + x));
                }
            }
            const VFloat centreX = toFloat(splatInt(x) + laneIndex()) + 0.5f;
            VFloat hx = centreX - vx, hy = rowCentre - vy;
            VMask valid = (hx >= splat<VFloat>(0.0f)) & (hy >= splat<VFloat>(0.0f)) &
                          (hx <= splat<VFloat>(float(W_))) & (hy <= splat<VFloat>(float(H_)));
            VFloat weight = splat<VFloat>(0.0f);
            VFloat h[3] = {c[0], c[1], c[2]};
            if (!in_.fresh && any(valid)) {
                hx = select(valid, hx, centreX), hy = select(valid, hy, rowCentre);
                const VInt nx = vclamp(truncateToInt(hx), zero, lastX),
                           ny = vclamp(truncateToInt(hy), zero, lastY);
                const Taps at(nx, ny, in_.stride);
                const VFloat stored = at.read(historyWeight);
                weight = select(valid, vabs(stored), weight);
                const VMask movedThen = stored < splat<VFloat>(0.0f);
                // 3. Disocclusion: the previous 3x3's depths all nearer, or all farther, than the current
                // 3x3's (by more than the tolerance).
                if (useDepth_) {
                    VFloat prevLo, prevHi;
                    range3x3(in_.previousDepth, size_t(W_), depthFloats, nx, ny, prevLo, prevHi);
                    const VMask disoccluded = (prevHi < curLo * (1.0f - in_.depthTolerance)) |
                                              (prevLo > curHi * (1.0f + in_.depthTolerance));
                    weight = select(disoccluded, splat<VFloat>(0.0f), weight);
                }
                const VMask kept = weight > splat<VFloat>(0.0f);
                if (any(kept)) {
                    VFloat previous[3];
                    if (all(hx == toFloat(nx) + 0.5f) & all(hy == toFloat(ny) + 0.5f)) {
                        // On texels (a still view): the filter's weights are 1 there and 0 elsewhere.
                        for (int k = 0; k < 3; ++k)
                            previous[k] = at.read(in_.history + size_t(k) * planeFloats);
                    } else {
                        resampleHistory(hx, hy, previous);
                    }
                    for (int k = 0; k < 3; ++k) h[k] = select(kept, previous[k], c[k]);
                    // 4. Variance clipping, except under the static lock.
                    VMask clip = kept;
                    if (in_.staticLock) clip = clip & (movedNow | movedThen);
                    if (any(clip)) {
                        if (!yc[0])
                            for (int k = 0; k < 3; ++k) yc[k] = ycocgRow(y - 1 + k);
                        Ycocg sum{}, sum2{}, lo, hi;
                        sum.y = sum.co = sum.cg = sum2.y = sum2.co = sum2.cg = splat<VFloat>(0.0f);
                        lo.y = lo.co = lo.cg = splat<VFloat>(1e9f),
                        hi.y = hi.co = hi.cg = splat<VFloat>(-1e9f);
                        for (int dy = 0; dy < 3; ++dy)
                            for (int dx = -1; dx <= 1; ++dx) {
                                const VFloat ny_ = loadu<VFloat>(yc[dy] + x + dx),
                                             nco = loadu<VFloat>(yc[dy] + yp + x + dx),
                                             ncg = loadu<VFloat>(yc[dy] + 2 * yp + x + dx);
                                sum.y = sum.y + ny_, sum.co = sum.co + nco, sum.cg = sum.cg + ncg;
                                sum2.y = sum2.y + ny_ * ny_, sum2.co = sum2.co + nco * nco,
                                sum2.cg = sum2.cg + ncg * ncg;
                                lo.y = vmin(lo.y, ny_), lo.co = vmin(lo.co, nco), lo.cg = vmin(lo.cg, ncg);
                                hi.y = vmax(hi.y, ny_), hi.co = vmax(hi.co, nco), hi.cg = vmax(hi.cg, ncg);
                            }
                        const Ycocg cc{loadu<VFloat>(yc[1] + x), loadu<VFloat>(yc[1] + yp + x),
                                       loadu<VFloat>(yc[1] + 2 * yp + x)};
                        const Ycocg hc = toYcocg(h[0], h[1], h[2]);
                        const VFloat inv = splat<VFloat>(1.0f / 9.0f), eps = splat<VFloat>(1e-6f);
                        VFloat centre[3], off[3], a = splat<VFloat>(0.0f);
                        const VFloat sums[3] = {sum.y, sum.co, sum.cg}, sums2[3] = {sum2.y, sum2.co, sum2.cg};
                        const VFloat los[3] = {lo.y, lo.co, lo.cg}, his[3] = {hi.y, hi.co, hi.cg};
                        const VFloat cur[3] = {cc.y, cc.co, cc.cg}, hist[3] = {hc.y, hc.co, hc.cg};
                        for (int k = 0; k < 3; ++k) {
                            const VFloat mean = sums[k] * inv;
                            const VFloat sigma =
                                vsqrt(vmax(splat<VFloat>(0.0f), sums2[k] * inv - mean * mean));
                            const VFloat boxLo = vmin(vmax(los[k], mean - gamma * sigma), cur[k]);
                            const VFloat boxHi = vmax(vmin(his[k], mean + gamma * sigma), cur[k]);
                            centre[k] = 0.5f * (boxLo + boxHi);
                            const VFloat extent = 0.5f * (boxHi - boxLo) + eps;
                            off[k] = hist[k] - centre[k];
                            a = vmax(a, vabs(off[k]) / extent);
                        }
                        const VMask clipped = clip & (a > splat<VFloat>(1.0f));
                        if (any(clipped)) {
                            const VFloat shrink = 1.0f / a;
                            const VFloat yy = centre[0] + off[0] * shrink, co = centre[1] + off[1] * shrink,
                                         cg = centre[2] + off[2] * shrink;
                            h[0] = select(clipped, yy + co - cg, h[0]);
                            h[1] = select(clipped, yy + cg, h[1]);
                            h[2] = select(clipped, yy - co - cg, h[2]);
                            weight = select(clipped, vmin(weight, clippedWeight), weight);
                        }
                    }
                }
            }
            // 5. One more sample; the history moves toward it by 1 / weight.
            weight = vmin(weight + 1.0f, select(movedNow, movingMaxWeight, maxWeight));
            const VFloat share = 1.0f / weight;
            VFloat next[3], encoded[3];
            for (int k = 0; k < 3; ++k) {
                next[k] = h[k] + share * (c[k] - h[k]);
                encoded[k] = encodeSrgb(next[k]);
            }
            if (history) {
                const VFloat signedWeight = select(movedNow, -weight, weight);
                for (int k = 0; k < 3; ++k) storeu(history + size_t(k) * planeFloats + x, next[k]);
                storeu(history + 3 * planeFloats + x, signedWeight);
            }
            // 6. The output in sRGB.
            if (ring) {
                for (int k = 0; k < 3; ++k) storeu(ring + size_t(k) * output_.rowFloats + x, encoded[k]);
            } else {
                storeRgbFirst(dst + 3 * x, encoded[0], encoded[1], encoded[2], W_ - x);
            }
        }
    }

    const float* outputRow(int y) {
        return row(output_, y, [&](int yy, float* r) { resolve(yy, r); });
    }

    // The output-only sharpen: the cross's Laplacian, limited to the cross's range.
    void sharpenRow(int y) {
        const float* rows[3] = {outputRow(y - 1), outputRow(y), outputRow(y + 1)};
        const size_t plane = output_.rowFloats;
        const VFloat s = splat<VFloat>(in_.sharpen);
        float* dst = in_.out + size_t(y) * size_t(W_) * 3;
        for (int x = 0; x < W_; x += L) {
            VFloat result[3];
            for (int k = 0; k < 3; ++k) {
                const size_t o = size_t(k) * plane + size_t(x);
                const VFloat c = loadu<VFloat>(rows[1] + o);
                VFloat lo = c, hi = c, around = splat<VFloat>(0.0f);
                for (const VFloat q : {loadu<VFloat>(rows[0] + o), loadu<VFloat>(rows[2] + o),
                                       loadu<VFloat>(rows[1] + o - 1), loadu<VFloat>(rows[1] + o + 1)})
                    lo = vmin(lo, q), hi = vmax(hi, q), around = around + q;
                result[k] = vclamp(c + s * (c - 0.25f * around), lo, hi);
            }
            storeRgbFirst(dst + 3 * x, result[0], result[1], result[2], W_ - x);
        }
    }
};

}  // namespace

void taaHqBand(const TaaHqBandInputs& in, int y0, int y1, float* scratch) {
    Band band(in, y0, y1, scratch);
    band.run();
}

void srgbToLinearRow(const float* in, float* out, int n) {
    int i = 0;
    for (; i + L <= n; i += L) storeu(out + i, decodeSrgb(loadu<VFloat>(in + i)));
    for (; i < n; ++i) {
        float lanes[L] = {in[i]};
        storeu(lanes, decodeSrgb(loadu<VFloat>(lanes)));
        out[i] = lanes[0];
    }
}

void linearToSrgbRow(const float* in, float* out, int n) {
    int i = 0;
    for (; i + L <= n; i += L) storeu(out + i, encodeSrgb(loadu<VFloat>(in + i)));
    for (; i < n; ++i) {
        float lanes[L] = {in[i]};
        storeu(lanes, encodeSrgb(loadu<VFloat>(lanes)));
        out[i] = lanes[0];
    }
}

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

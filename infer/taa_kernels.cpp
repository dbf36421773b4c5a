// The TAA band kernel (infer/taa_kernels.h), compiled once per SIMD level: kFloatLanes pixels of a row
// at a time, the formulas of docs/taa.md in the order infer/taa.h describes them.
#include "infer/taa_kernels.h"

#include <algorithm>
#include <cmath>

#include "base/pixel_simd.h"
#include "infer/row_ring.h"

namespace dejag::infer::DEJAG_SIMD_NAMESPACE {

using namespace ::dejag::DEJAG_SIMD_NAMESPACE;

namespace {

constexpr int L = kFloatLanes;

using Ring = RowRing;
static_assert(RowRing::kRows == kTaaRingRows && RowRing::kPad == kTaaRowPad);

// History weight from the luma difference of current and history (docs/taa.md).
struct Feedback {
    VFloat lo, span;
    VFloat operator()(VFloat current, VFloat history) const {
        const VFloat d = vabs(current - history) / vmax(vmax(current, history), splat<VFloat>(0.2f));
        const VFloat w = (1.0f - d) * (1.0f - d);
        return lo + span * clamp01(w);
    }
};

VFloat luma601(VFloat r, VFloat g, VFloat b) {
    return 0.299f * r + 0.587f * g + 0.114f * b;
}

VFloat sobelMagnitude(const float* const rows[3], int x) {
    auto v = [&](int dx, int dy) { return loadu<VFloat>(rows[dy + 1] + x + dx); };
    const VFloat gx = -v(-1, -1) + v(1, -1) - 2.0f * v(-1, 0) + 2.0f * v(1, 0) - v(-1, 1) + v(1, 1);
    const VFloat gy = v(-1, -1) + 2.0f * v(0, -1) + v(1, -1) - v(-1, 1) - 2.0f * v(0, 1) - v(1, 1);
    return vsqrt(gx * gx + gy * gy);
}

class Band {
  public:
    Band(const TaaBandInputs& in, int y0, int y1, float* scratch)
        : in_(in),
          W_(in.width),
          H_(in.height),
          y0_(y0),
          y1_(y1),
          feedback_{splat<VFloat>(in.feedbackMin), splat<VFloat>(in.feedbackMax - in.feedbackMin)} {
        const size_t rowFloats = taaRowFloats(W_);
        float* cursor = scratch;
        colour_.carve(cursor, rowFloats, 3);
        depth_.carve(cursor, rowFloats, 1);
        motion_.carve(cursor, rowFloats, 2);
        albedoLuma_.carve(cursor, rowFloats, 1);
        colourLuma_.carve(cursor, rowFloats, 1);
        sobel_.carve(cursor, rowFloats, 1);
        stableSobel_.carve(cursor, rowFloats, 1);
        ids_.carve(cursor, rowFloats, 1);
        blended_.carve(cursor, rowFloats, 3);
        shifted_ = cursor;
    }

    void run() {
        for (int y = y0_; y < y1_; ++y) sharpenRow(y);
    }

  private:
    const TaaBandInputs& in_;
    const int W_, H_, y0_, y1_;
    const Feedback feedback_;
    Ring colour_, depth_, motion_, albedoLuma_, colourLuma_, sobel_, stableSobel_, ids_, blended_;
    float* shifted_ = nullptr;            // one interleaved RGB row
    bool motionStill_[Ring::kRows] = {};  // by the motion ring's slot: whether that row's motion is all 0
    // Where a segment of the row reads its history (pixel coordinates), and what it read there.
    static constexpr int kSegment = 256;  // pixels, a multiple of every level's lanes
    struct Segment {
        alignas(64) float px[kSegment], py[kSegment], previous[3][kSegment];
    } segment_;

    bool inBand(int y) const { return y >= y0_ && y < y1_; }

    template <class Fill>
    const float* row(Ring& ring, int y, Fill fill) {
        return ring.row(y, W_, H_, fill);
    }

    void copyRow(const float* src, int y, float* dst) const {
        std::copy(src + size_t(y) * size_t(W_), src + size_t(y + 1) * size_t(W_), dst);
    }

    // Row y of an interleaved RGB frame, read bilinearly at p + jitter when un-jittering (into the
    // scratch row), else as it is.
    const float* rgbRow(const float* frame, int y) {
        if (!in_.unjitter) return frame + size_t(y) * size_t(W_) * 3;
        const int ix = int(std::floor(in_.jitterX)), iy = int(std::floor(in_.jitterY));
        const float fx = in_.jitterX - float(ix), fy = in_.jitterY - float(iy);
        const float w00 = (1 - fx) * (1 - fy), w01 = fx * (1 - fy), w10 = (1 - fx) * fy, w11 = fx * fy;
        const float* r0 = frame + size_t(std::clamp(y + iy, 0, H_ - 1)) * size_t(W_) * 3;
        const float* r1 = frame + size_t(std::clamp(y + iy + 1, 0, H_ - 1)) * size_t(W_) * 3;
        float* o = shifted_;
        auto edge = [&](int x) {
            const size_t x0 = size_t(std::clamp(x + ix, 0, W_ - 1)) * 3,
                         x1 = size_t(std::clamp(x + ix + 1, 0, W_ - 1)) * 3;
            for (size_t c = 0; c < 3; ++c)
                o[size_t(x) * 3 + c] =
                    w00 * r0[x0 + c] + w01 * r0[x1 + c] + w10 * r1[x0 + c] + w11 * r1[x1 + c];
        };
        // Columns whose two taps x + ix, x + ix + 1 both lie in the row: one flat pass over their floats.
        const int first = std::clamp(-ix, 0, W_), last = std::clamp(W_ - 1 - ix, first, W_);
        for (int x = 0; x < first; ++x) edge(x);
        const float* a = r0 + ptrdiff_t(ix) * 3;
        const float* b = r1 + ptrdiff_t(ix) * 3;
        const VFloat v00 = splat<VFloat>(w00), v01 = splat<VFloat>(w01), v10 = splat<VFloat>(w10),
                     v11 = splat<VFloat>(w11);
        size_t k = size_t(first) * 3;
        for (; k + L <= size_t(last) * 3; k += L)
            storeu(o + k, v00 * loadu<VFloat>(a + k) + v01 * loadu<VFloat>(a + k + 3) +
                              v10 * loadu<VFloat>(b + k) + v11 * loadu<VFloat>(b + k + 3));
        for (; k < size_t(last) * 3; ++k) o[k] = w00 * a[k] + w01 * a[k + 3] + w10 * b[k] + w11 * b[k + 3];
        for (int x = last; x < W_; ++x) edge(x);
        return o;
    }

    const float* colourRow(int y) {
        return row(colour_, y, [&](int yy, float* r) {
            const float* src = rgbRow(in_.colour, yy);
            float *g = r + colour_.rowFloats, *b = g + colour_.rowFloats;
            int x = 0;
            for (; x + L <= W_; x += L) {
                VFloat vr, vg, vb;
                loadRgb(src + 3 * x, vr, vg, vb);
                storeu(r + x, vr), storeu(g + x, vg), storeu(b + x, vb);
            }
            for (; x < W_; ++x) r[x] = src[3 * x], g[x] = src[3 * x + 1], b[x] = src[3 * x + 2];
        });
    }
    const float* depthRow(int y) {
        return row(depth_, y, [&](int yy, float* r) { copyRow(in_.depth, yy, r); });
    }
    const float* idRow(int y) {
        return row(ids_, y, [&](int yy, float* r) { copyRow(in_.ids, yy, r); });
    }
    const float* motionRow(int y) {
        return row(motion_, y, [&](int yy, float* r) {
            const float* src = in_.motion + size_t(yy) * size_t(W_) * 2;
            float* v = r + motion_.rowFloats;
            splitPairs(src, r, v, W_);
            // Whether every motion of the row is 0 (or -0): its pixels read the history where they are.
            VMask moving = splat<VFloat>(0.0f) != splat<VFloat>(0.0f);
            int x = 0;
            for (; x + L <= W_; x += L)
                moving = moving | (loadu<VFloat>(r + x) != splat<VFloat>(0.0f)) |
                         (loadu<VFloat>(v + x) != splat<VFloat>(0.0f));
            bool still = !any(moving);
            for (; x < W_; ++x) still = still && r[x] == 0.0f && v[x] == 0.0f;
            motionStill_[yy & (Ring::kRows - 1)] = still;
        });
    }
    bool motionStill(int y) {
        motionRow(y);
        return motionStill_[std::clamp(y, 0, H_ - 1) & (Ring::kRows - 1)];
    }
    // Rec. 601 luma of an interleaved RGB row, for the Sobel of colours.
    void lumaRow(const float* src, float* r) const {
        int x = 0;
        for (; x + L <= W_; x += L) {
            VFloat vr, vg, vb;
            loadRgb(src + 3 * x, vr, vg, vb);
            storeu(r + x, luma601(vr, vg, vb));
        }
        for (; x < W_; ++x) r[x] = 0.299f * src[3 * x] + 0.587f * src[3 * x + 1] + 0.114f * src[3 * x + 2];
    }
    const float* albedoLumaRow(int y) {
        return row(albedoLuma_, y, [&](int yy, float* r) { lumaRow(rgbRow(in_.albedo, yy), r); });
    }
    // From the colour ring's planes (no second deinterleaving of the frame's row).
    const float* colourLumaRow(int y) {
        return row(colourLuma_, y, [&](int yy, float* r) {
            const float* red = colourRow(yy);
            const float *green = red + colour_.rowFloats, *blue = green + colour_.rowFloats;
            for (int x = 0; x < W_; x += L)
                storeu(r + x,
                       luma601(loadu<VFloat>(red + x), loadu<VFloat>(green + x), loadu<VFloat>(blue + x)));
        });
    }

    // T-TAA's texture: g = clamp(0.3 Sobel(albedo luma) + 0.7 Sobel(luma) + Sobel(depth)),
    // sobel = sqrt(g^2 (3 - 2g)).
    const float* sobelRow(int y) {
        return row(sobel_, y, [&](int yy, float* r) {
            const float* a[3] = {albedoLumaRow(yy - 1), albedoLumaRow(yy), albedoLumaRow(yy + 1)};
            const float* c[3] = {colourLumaRow(yy - 1), colourLumaRow(yy), colourLumaRow(yy + 1)};
            const float* d[3] = {depthRow(yy - 1), depthRow(yy), depthRow(yy + 1)};
            for (int x = 0; x < W_; x += L) {
                const VFloat g =
                    clamp01(0.3f * sobelMagnitude(a, x) + 0.7f * sobelMagnitude(c, x) + sobelMagnitude(d, x));
                storeu(r + x, vsqrt(g * g * (3.0f - 2.0f * g)));
            }
        });
    }

    // Bilinear reads of `planes` history planes (planeFloats apart) at pixel coordinates (centres at
    // +0.5), clamp to edge.
    template <int planes>
    void historyBilinear(const float* plane, VFloat px, VFloat py, VFloat* result) const {
        const VFloat fx = px - 0.5f, fy = py - 0.5f;
        const VInt x0 = floorToInt(fx), y0 = floorToInt(fy);
        const VFloat tx = fx - toFloat(x0), ty = fy - toFloat(y0);
        const VInt zero = splatInt(0), lastX = splatInt(W_ - 1), lastY = splatInt(H_ - 1);
        const VInt xa = vclamp(x0, zero, lastX), xb = vclamp(x0 + 1, zero, lastX);
        const VInt ya = vclamp(y0, zero, lastY), yb = vclamp(y0 + 1, zero, lastY);
        // Motion by whole pixels (a still camera): every lane reads its top-left tap only, exactly what
        // the weights 1, 0, 0, 0 give.
        const bool whole = all((tx == splat<VFloat>(0.0f)) & (ty == splat<VFloat>(0.0f)));
        VFloat a[planes], b[planes], c[planes], d[planes];
#if !defined(DEJAG_SIMD_LEVEL_scalar)
        // Where the lanes read two rows and a span of at most kWindowFloats pixels (smooth motion: the
        // usual case), two loads per row and a permute replace each gather. The window starts half a
        // vector left of lane 0's tap, so motion that shrinks or grows across the lanes stays inside it.
        const int first = std::max(0, xa[0] - L / 2);
        const int rowA = ya[0], rowB = yb[0];
        if (withinWindow(xa, xb, first) && all((ya == splatInt(rowA)) & (yb == splatInt(rowB)))) {
            const VInt ia = xa - first, ib = xb - first;
            if (whole) {
                for (int k = 0; k < planes; ++k) {
                    const float* pa = plane + size_t(k) * in_.planeFloats + size_t(rowA) * in_.stride + first;
                    result[k] = fromWindow(loadWindow(pa), ia);
                }
                return;
            }
            for (int k = 0; k < planes; ++k) {
                const float* pa = plane + size_t(k) * in_.planeFloats + size_t(rowA) * in_.stride + first;
                const float* pb = plane + size_t(k) * in_.planeFloats + size_t(rowB) * in_.stride + first;
                const Window top = loadWindow(pa), bottom = loadWindow(pb);
                a[k] = fromWindow(top, ia), b[k] = fromWindow(top, ib);
                c[k] = fromWindow(bottom, ia), d[k] = fromWindow(bottom, ib);
            }
        } else
#endif
        {
            const VInt stride = splatInt(int32_t(in_.stride));
            const VInt ra = ya * stride, rb = yb * stride;
            if (whole) {
                for (int k = 0; k < planes; ++k)
                    result[k] = gather(plane + size_t(k) * in_.planeFloats, ra + xa);
                return;
            }
            // Lanes whose two taps lie inside the row read them as consecutive floats (the planes' rows
            // are padded, so the 4 floats read from the tap on are always inside them).
            const bool inside = all((x0 >= zero) & (x0 < lastX));
            for (int k = 0; k < planes; ++k) {
                const float* p = plane + size_t(k) * in_.planeFloats;
                if (inside) {
                    VFloat top[4], bottom[4];
                    loadQuads(p, ra + xa, top), loadQuads(p, rb + xa, bottom);
                    a[k] = top[0], b[k] = top[1], c[k] = bottom[0], d[k] = bottom[1];
                } else {
                    a[k] = gather(p, ra + xa), b[k] = gather(p, ra + xb);
                    c[k] = gather(p, rb + xa), d[k] = gather(p, rb + xb);
                }
            }
        }
        for (int k = 0; k < planes; ++k) {
            const VFloat top = a[k] + tx * (b[k] - a[k]), bottom = c[k] + tx * (d[k] - c[k]);
            result[k] = top + ty * (bottom - top);
        }
    }

    // The previous frame's depth at whole pixels (x, y) of the lanes: where the lanes share a row and
    // lie within a window (a still or smoothly moving camera), two loads and a permute replace the
    // gather, unless the window would run past the end of the buffer.
    VFloat previousDepthAt(VInt x, VInt y) const {
#if !defined(DEJAG_SIMD_LEVEL_scalar)
        const int first = std::max(0, x[0] - L / 2), row = y[0];
        if (withinWindow(x, x, first) && all(y == splatInt(row)) &&
            (size_t(row) * size_t(W_) + size_t(first) + kWindowFloats <= size_t(W_) * size_t(H_))) {
            const float* p = in_.previousDepth + size_t(row) * size_t(W_) + size_t(first);
            return fromWindow(loadWindow(p), x - first);
        }
#endif
        return gather(in_.previousDepth, y * splatInt(W_) + x);
    }

    // The Sobel's own TAA: reprojected with the pixel's motion, clamped to the 3x3 box, no sharpen.
    const float* stableSobelRow(int y) {
        return row(stableSobel_, y, [&](int yy, float* r) {
            const float* s[3] = {sobelRow(yy - 1), sobelRow(yy), sobelRow(yy + 1)};
            float* history = inBand(yy) ? in_.nextSobelHistory + size_t(yy) * in_.stride : nullptr;
            if (in_.fresh) {
                std::copy(s[1], s[1] + W_, r);
                if (history) std::copy(s[1], s[1] + W_, history);
                return;
            }
            const float* m = motionRow(yy);
            const float* mv = m + motion_.rowFloats;
            const bool still = motionStill(yy);  // (the history read where the pixel is)
            const VFloat rowCentre = splat<VFloat>(float(yy) + 0.5f);
            for (int x = 0; x < W_; x += L) {
                VFloat lo = splat<VFloat>(1e30f), hi = splat<VFloat>(-1e30f);
                for (int dy = 0; dy < 3; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const VFloat v = loadu<VFloat>(s[dy] + x + dx);
                        lo = vmin(lo, v), hi = vmax(hi, v);
                    }
                const VFloat xs = toFloat(splatInt(x) + laneIndex());
                VFloat previous;
                if (still && x + L <= W_) {
                    previous = loadu<VFloat>(in_.sobelHistory + size_t(yy) * in_.stride + size_t(x));
                } else {
                    historyBilinear<1>(in_.sobelHistory, xs + 0.5f - loadu<VFloat>(m + x),
                                       rowCentre - loadu<VFloat>(mv + x), &previous);
                }
                previous = vclamp(previous, lo, hi);
                const VFloat current = loadu<VFloat>(s[1] + x);
                const VFloat k = feedback_(current, previous);
                const VFloat stable = current + (previous - current) * k;
                storeu(r + x, stable);
                if (history) storeu(history + x, stable);
            }
        });
    }

    // What the next row's blend will read, asked of the caches a vector at a time while this row
    // blends: the frame's rows it makes into ring rows (y + 2), the history and the next history (y +
    // 1), and the output row the sharpen writes next (y - 1). (The ring rows are made in bursts
    // between rows of blending; without this the core waited for memory in each burst, and one
    // thread's 1080p frame cost about the time in cache plus the time of its bytes. One row ahead
    // measured 10 % faster on one thread; two rows ahead, no faster. Prefetching the output row made
    // U-TAA 6 % faster on one thread, taa-hq no faster.)
    struct Ahead {
        const float *colour, *motion, *depth, *albedo, *ids, *previousDepth, *history, *sobelHistory;
        float *nextHistory, *nextSobelHistory, *out;
        size_t planeFloats;
    };
    Ahead ahead(int y) const {
        const int input = std::min(y + 2, H_ - 1), history = std::min(y + 1, H_ - 1);
        const size_t i = size_t(input) * size_t(W_), h = size_t(history) * in_.stride;
        Ahead a;
        a.colour = in_.colour + 3 * i, a.motion = in_.motion + 2 * i, a.depth = in_.depth + i;
        a.history = in_.history + h, a.nextHistory = in_.nextHistory + h;
        a.planeFloats = in_.planeFloats;
        a.out = in_.out + 3 * size_t(std::max(y - 1, 0)) * size_t(W_);  // the row the sharpen writes next
        a.albedo = a.ids = a.previousDepth = a.sobelHistory = nullptr, a.nextSobelHistory = nullptr;
        if (in_.improved) {
            a.albedo = in_.albedo + 3 * i, a.ids = in_.ids + i, a.previousDepth = in_.previousDepth + i;
            a.sobelHistory = in_.sobelHistory + h, a.nextSobelHistory = in_.nextSobelHistory + h;
        }
        return a;
    }

    // Steps 1-5: neighbourhoods, velocity of the closest depth, reprojection, clip, blend.
    const float* blendedRow(int y) {
        return row(blended_, y, [&](int yy, float* out) { blend(yy, out); });
    }

    void blend(int y, float* out) {
        const bool improved = in_.improved;
        const float* t[3] = {};
        const float* id[3] = {};
        if (improved) {  // first: making these rows reads depth rows further down
            for (int k = 0; k < 3; ++k) t[k] = stableSobelRow(y - 1 + k);
            for (int k = 0; k < 3; ++k) id[k] = idRow(y - 1 + k);
        }
        const float* c[3][3];
        const float* d[3];
        const float* m[3][2];
        for (int k = 0; k < 3; ++k) {
            const float* colour = colourRow(y - 1 + k);
            for (int ch = 0; ch < 3; ++ch) c[k][ch] = colour + size_t(ch) * colour_.rowFloats;
            d[k] = depthRow(y - 1 + k);
            const float* motion = motionRow(y - 1 + k);
            m[k][0] = motion, m[k][1] = motion + motion_.rowFloats;
        }
        const size_t rowFloats = blended_.rowFloats;
        float* history = inBand(y) ? in_.nextHistory + size_t(y) * in_.stride : nullptr;
        const VFloat rowCentre = splat<VFloat>(float(y) + 0.5f);
        const VInt lastX = splatInt(W_ - 1), lastY = splatInt(H_ - 1), zero = splatInt(0);
        // No motion in the three rows (a still camera over a still scene): every pixel reads the history
        // where it is, which is what the steps below give, without the search for the nearest motion.
        const bool still = motionStill(y - 1) && motionStill(y) && motionStill(y + 1);

        // In three loops over a segment of the row, so that each loop's body is short enough for the
        // core to overlap its iterations (one loop doing all of it waited on each vector's history read):
        // 1. the motion of the nearest of the 3x3 (steps 2-3: where the pixel was), 2. the history there,
        // 3. the boxes, the clip and the blend.
        const Ahead next = ahead(y);
        constexpr int kLine = 16;  // floats
        for (int x0 = 0; x0 < W_; x0 += kSegment) {
            const int x1 = std::min(W_, x0 + kSegment);
            for (int x = x0; x < x1; x += L) {
                // (written out here: through a helper, GCC 12 dropped every prefetch once there were six)
                for (int k = 0; k < 3 * L; k += kLine) __builtin_prefetch(next.colour + 3 * x + k, 0, 2);
                for (int k = 0; k < 2 * L; k += kLine) __builtin_prefetch(next.motion + 2 * x + k, 0, 2);
                __builtin_prefetch(next.depth + x, 0, 2);
                for (int k = 0; k < 3; ++k) {
                    __builtin_prefetch(next.history + size_t(k) * next.planeFloats + x, 0, 2);
                    __builtin_prefetch(next.nextHistory + size_t(k) * next.planeFloats + x, 1, 2);
                }
                for (int k = 0; k < 3 * L; k += kLine) __builtin_prefetch(next.out + 3 * x + k, 1, 2);
                if (improved) {
                    for (int k = 0; k < 3 * L; k += kLine) __builtin_prefetch(next.albedo + 3 * x + k, 0, 2);
                    __builtin_prefetch(next.ids + x, 0, 2), __builtin_prefetch(next.previousDepth + x, 0, 2);
                    __builtin_prefetch(next.sobelHistory + x, 0, 2);
                    __builtin_prefetch(next.nextSobelHistory + x, 1, 2);
                }
                VFloat closest = splat<VFloat>(1e30f);
                VFloat vx = loadu<VFloat>(m[1][0] + x), vy = loadu<VFloat>(m[1][1] + x);
                for (int dy = 0; dy < 3 && !still; ++dy)  // (still: every motion around is 0)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const VFloat depth = loadu<VFloat>(d[dy] + x + dx);
                        const VMask nearer = depth < closest;
                        closest = select(nearer, depth, closest);
                        vx = select(nearer, loadu<VFloat>(m[dy][0] + x + dx), vx);
                        vy = select(nearer, loadu<VFloat>(m[dy][1] + x + dx), vy);
                    }
                const VFloat xs = toFloat(splatInt(x) + laneIndex());
                storeu(segment_.px + (x - x0), xs + 0.5f - vx),
                    storeu(segment_.py + (x - x0), rowCentre - vy);
            }
            if (!in_.fresh)
                for (int x = x0; x < x1; x += L) {
                    VFloat previous[3];
                    if (still && x + L <= W_) {  // the history where the pixel is
                        for (int ch = 0; ch < 3; ++ch)
                            storeu(segment_.previous[ch] + (x - x0),
                                   loadu<VFloat>(in_.history + size_t(ch) * in_.planeFloats +
                                                 size_t(y) * in_.stride + size_t(x)));
                        continue;
                    }
                    historyBilinear<3>(in_.history, loadu<VFloat>(segment_.px + (x - x0)),
                                       loadu<VFloat>(segment_.py + (x - x0)), previous);
                    for (int ch = 0; ch < 3; ++ch) storeu(segment_.previous[ch] + (x - x0), previous[ch]);
                }
            for (int x = x0; x < x1; x += L) {
                // The colour box of the cross (centre and its 4 neighbours), then of all 9 taps: the 4
                // corners extend the cross's.
                VFloat current[3], min9[3], max9[3], minCross[3], maxCross[3];
                for (int ch = 0; ch < 3; ++ch) {
                    current[ch] = loadu<VFloat>(c[1][ch] + x);
                    VFloat lo = current[ch], hi = current[ch];
                    for (const VFloat v : {loadu<VFloat>(c[0][ch] + x), loadu<VFloat>(c[1][ch] + x - 1),
                                           loadu<VFloat>(c[1][ch] + x + 1), loadu<VFloat>(c[2][ch] + x)})
                        lo = vmin(lo, v), hi = vmax(hi, v);
                    minCross[ch] = lo, maxCross[ch] = hi;
                    for (const VFloat v : {loadu<VFloat>(c[0][ch] + x - 1), loadu<VFloat>(c[0][ch] + x + 1),
                                           loadu<VFloat>(c[2][ch] + x - 1), loadu<VFloat>(c[2][ch] + x + 1)})
                        lo = vmin(lo, v), hi = vmax(hi, v);
                    min9[ch] = lo, max9[ch] = hi;
                }
                const VFloat px = loadu<VFloat>(segment_.px + (x - x0)),
                             py = loadu<VFloat>(segment_.py + (x - x0));
                VFloat previous[3] = {current[0], current[1], current[2]};
                if (!in_.fresh)
                    for (int ch = 0; ch < 3; ++ch)
                        previous[ch] = loadu<VFloat>(segment_.previous[ch] + (x - x0));
                VFloat lo[3], hi[3];
                if (!improved) {
                    for (int ch = 0; ch < 3; ++ch)
                        lo[ch] = (min9[ch] + minCross[ch]) * 0.5f, hi[ch] = (max9[ch] + maxCross[ch]) * 0.5f;
                } else {
                    // How aliased this pixel is: Sobel, model index, depth pseudo-variances.
                    const VFloat sobelCentre = loadu<VFloat>(t[1] + x), idCentre = loadu<VFloat>(id[1] + x);
                    VFloat sobel3x3 = splat<VFloat>(0.0f), sobelCross = splat<VFloat>(0.0f),
                           different = splat<VFloat>(0.0f), dmin = splat<VFloat>(1e30f),
                           dmax = splat<VFloat>(-1e30f), dsum = splat<VFloat>(0.0f);
                    for (int dy = 0; dy < 3; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const VFloat s = loadu<VFloat>(t[dy] + x + dx);
                            sobel3x3 += s;
                            if (dx == 0 || dy == 1) sobelCross += s;
                            different += select(loadu<VFloat>(id[dy] + x + dx) != idCentre,
                                                splat<VFloat>(1.0f), splat<VFloat>(0.0f));
                            const VFloat depth = loadu<VFloat>(d[dy] + x + dx);
                            dmin = vmin(dmin, depth), dmax = vmax(dmax, depth), dsum += depth;
                        }
                    sobel3x3 /= 9.0f, sobelCross /= 5.0f;
                    const VFloat modelAverage = different / 9.0f;
                    const VFloat davg = dsum / 9.0f;
                    const VFloat maxDepthDistance = vmin(vabs(dmin - davg), vabs(dmax - davg));
                    VFloat depthPV = splat<VFloat>(0.0f), depthTPV = splat<VFloat>(0.0f);
                    const VMask varies = maxDepthDistance >= splat<VFloat>(in_.depthThreshold);
                    if (any(varies)) {
                        const VFloat pv = vabs(loadu<VFloat>(d[1] + x) - davg) / maxDepthDistance;
                        const VInt priorX = vclamp(floorToInt(px), zero, lastX);
                        const VInt priorY = vclamp(floorToInt(py), zero, lastY);
                        const VFloat prior = previousDepthAt(priorX, priorY);
                        const VFloat tpv = vabs(prior - davg) / maxDepthDistance;
                        depthPV = select(varies, pv * pv, depthPV);
                        depthTPV = select(varies, tpv * tpv * tpv * tpv, depthTPV);
                    }
                    const VFloat sobelAvgMixVal = clamp01(modelAverage + sobelCentre);
                    const VFloat sobelAvg = sobelCross + (sobel3x3 - sobelCross) * sobelAvgMixVal;
                    const VFloat aliased = clamp01(sobelAvg + depthPV + depthTPV + modelAverage);
                    for (int ch = 0; ch < 3; ++ch) {
                        const VFloat colorMin = mix(minCross[ch], min9[ch], aliased),
                                     colorMax = mix(maxCross[ch], max9[ch], aliased);
                        lo[ch] = mix(current[ch], colorMin, aliased),
                        hi[ch] = mix(current[ch], colorMax, aliased);
                    }
                }
                // 4. Clip towards the box centre (INSIDE's clip_aabb), 5. blend with the luminance feedback.
                VFloat centre[3], offset[3];
                VFloat unit = splat<VFloat>(0.0f);
                for (int ch = 0; ch < 3; ++ch) {
                    centre[ch] = (lo[ch] + hi[ch]) * 0.5f;
                    // (the reciprocal does not wait for the history read)
                    const VFloat inverseExtent = 1.0f / ((hi[ch] - lo[ch]) * 0.5f + 1e-6f);
                    offset[ch] = previous[ch] - centre[ch];
                    unit = vmax(unit, vabs(offset[ch] * inverseExtent));
                }
                const VMask outside = unit > splat<VFloat>(1.0f);
                const VFloat shrink = 1.0f / unit;
                VFloat clipped[3];
                for (int ch = 0; ch < 3; ++ch)
                    clipped[ch] = select(outside, centre[ch] + offset[ch] * shrink, previous[ch]);
                VFloat k = splat<VFloat>(0.0f);
                if (!in_.fresh)
                    k = feedback_(0.25f * current[0] + 0.5f * current[1] + 0.25f * current[2],
                                  0.25f * clipped[0] + 0.5f * clipped[1] + 0.25f * clipped[2]);
                for (int ch = 0; ch < 3; ++ch) {
                    const VFloat blended = mix(current[ch], clipped[ch], k);
                    storeu(out + size_t(ch) * rowFloats + x, blended);
                    if (history) storeu(history + size_t(ch) * in_.planeFloats + x, blended);
                }
            }
        }
    }

    // 6. The output: the blended row sharpened (U-TAA 5 / -1, T-TAA 2 / -0.25), clamped to [0, 1].
    void sharpenRow(int y) {
        const float* rows[3] = {blendedRow(y - 1), blendedRow(y), blendedRow(y + 1)};
        const size_t rowFloats = blended_.rowFloats;
        const float centreWeight = in_.improved ? 2.0f : 5.0f, sideWeight = in_.improved ? -0.25f : -1.0f;
        float* dst = in_.out + size_t(y) * size_t(W_) * 3;
        for (int x = 0; x < W_; x += L) {
            VFloat result[3];
            for (int ch = 0; ch < 3; ++ch) {
                const size_t plane = size_t(ch) * rowFloats;
                const VFloat c = loadu<VFloat>(rows[1] + plane + x);
                VFloat s = c;
                if (in_.sharpen)
                    s = c * centreWeight +
                        (loadu<VFloat>(rows[1] + plane + x - 1) + loadu<VFloat>(rows[1] + plane + x + 1) +
                         loadu<VFloat>(rows[0] + plane + x) + loadu<VFloat>(rows[2] + plane + x)) *
                            sideWeight;
                result[ch] = clamp01(s);
            }
            storeRgbFirst(dst + 3 * x, result[0], result[1], result[2], W_ - x);
        }
    }
};

inline int largestLane(VInt v) {
#if defined(DEJAG_SIMD_LEVEL_scalar)
    return v;
#else
    int largest = v[0];
    for (int i = 1; i < L; ++i) largest = std::max(largest, int(v[i]));
    return largest;
#endif
}

// Motion blur of the pixels x .. x + L - 1 of row y whose motion is (vx, vy) (`count` of them real; the
// rest have no motion), Chapman's way: a pixel moving s pixels averages itself and n - 1 bilinear
// samples at t = k / (n - 1) - 1/2 of its motion, k = 1 .. n - 1, n = clamp(int(s), 1, maxSamples);
// pixels under 2 pixels of motion (or a non-finite one) keep their colour.
void blurPixels(const TaaBlurInputs& a, int x, int y, VFloat vx, VFloat vy, int count) {
    const int W = a.width, H = a.height;
    vx = vx * a.scale, vy = vy * a.scale;
    const VFloat speed = vsqrt(vx * vx + vy * vy);
    const VMask moving = (speed >= splat<VFloat>(2.0f)) & (speed <= splat<VFloat>(3.0e38f));
    if (!any(moving)) return;
    const VInt samples =
        truncateToInt(vmin(select(moving, speed, splat<VFloat>(1.0f)), splat<VFloat>(float(a.maxSamples))));
    const int most = largestLane(samples);
    const float* centre = a.source + (size_t(y) * size_t(W) + size_t(x)) * 3;
    // The pixels' own colours: the first of the samples.
    float lanes[3][L] = {};
    for (int i = 0; i < count; ++i)
        for (int c = 0; c < 3; ++c) lanes[c][i] = centre[3 * i + c];
    VFloat sum[3] = {loadu<VFloat>(lanes[0]), loadu<VFloat>(lanes[1]), loadu<VFloat>(lanes[2])};
    const VFloat steps = toFloat(select(moving, samples - 1, splatInt(1)));
    const VFloat columns = toFloat(splatInt(x) + laneIndex()) + 0.5f, row = splat<VFloat>(float(y) + 0.5f);
    for (int k = 1; k < most; ++k) {
        const VMask active = moving & (splatInt(k) < samples);
        const VFloat t = splat<VFloat>(float(k)) / steps - 0.5f;
        // (Positions far outside read the border; clamped first so the conversions stay in range.)
        const VFloat px = vclamp(columns + vx * t, splat<VFloat>(-1.0f), splat<VFloat>(float(W) + 1.0f));
        const VFloat py = vclamp(row + vy * t, splat<VFloat>(-1.0f), splat<VFloat>(float(H) + 1.0f));
        VFloat rgb[3];
        bilinearRgb(a.source, W, H, 3, px, py, rgb);
        for (int c = 0; c < 3; ++c) sum[c] = sum[c] + select(active, rgb[c], splat<VFloat>(0.0f));
    }
    const VFloat n = toFloat(samples);
    float* out = a.out + (size_t(y) * size_t(W) + size_t(x)) * 3;
    for (int c = 0; c < 3; ++c) storeu(lanes[c], sum[c] / n);
    for (int i = 0; i < count; ++i)
        for (int c = 0; c < 3; ++c) out[3 * i + c] = lanes[c][i];
}

}  // namespace

void taaBand(const TaaBandInputs& in, int y0, int y1, float* scratch) {
    Band band(in, y0, y1, scratch);
    band.run();
}

void taaMotionBlurRows(const TaaBlurInputs& in, int y0, int y1) {
    const int W = in.width;
    for (int y = y0; y < y1; ++y) {
        const float* motion = in.motion + size_t(y) * size_t(W) * 2;
        int x = 0;
        for (; x + L <= W; x += L) {
            VFloat vx, vy;
            loadPairs(motion + 2 * x, vx, vy);
            blurPixels(in, x, y, vx, vy, L);
        }
        if (x < W) {
            float lanes[2][L] = {};
            for (int i = 0; i < W - x; ++i)
                lanes[0][i] = motion[2 * (x + i)], lanes[1][i] = motion[2 * (x + i) + 1];
            blurPixels(in, x, y, loadu<VFloat>(lanes[0]), loadu<VFloat>(lanes[1]), W - x);
        }
    }
}

}  // namespace dejag::infer::DEJAG_SIMD_NAMESPACE

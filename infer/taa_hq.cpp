#include "infer/taa_hq.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

#include "base/error.h"
#include "base/thread_pool.h"
#include "data/image.h"

namespace dejag::infer {

namespace {

// sRGB decoding and encoding by table with linear interpolation (within 2e-5 of the formulas).
constexpr int kLutSize = 4096;
struct SrgbTables {
    std::array<float, kLutSize + 2> toLinear{}, toSrgb{};
    SrgbTables() {
        for (int i = 0; i <= kLutSize; ++i) {
            const float v = float(i) / kLutSize;
            toLinear[size_t(i)] = srgbToLinear(v);
            toSrgb[size_t(i)] = linearToSrgb(v);
        }
        toLinear[kLutSize + 1] = toLinear[kLutSize], toSrgb[kLutSize + 1] = toSrgb[kLutSize];
    }
};
const SrgbTables& tables() {
    static const SrgbTables t;
    return t;
}
inline float lookup(const std::array<float, kLutSize + 2>& table, float v) {
    v = std::clamp(v, 0.0f, 1.0f) * kLutSize;  // (a NaN becomes 0 through the clamp's comparisons)
    const int i = int(v);
    const float t = v - float(i);
    return table[size_t(i)] + t * (table[size_t(i) + 1] - table[size_t(i)]);
}

// Motion below this (pixels) is none: the static lock's test.
constexpr float kStill = 1e-3f;

struct Ycocg {
    float y, co, cg;
};
inline Ycocg toYcocg(const float* rgb) {
    return {0.25f * rgb[0] + 0.5f * rgb[1] + 0.25f * rgb[2], 0.5f * (rgb[0] - rgb[2]),
            -0.25f * rgb[0] + 0.5f * rgb[1] - 0.25f * rgb[2]};
}
inline void toRgb(const Ycocg& c, float* rgb) {
    rgb[0] = c.y + c.co - c.cg, rgb[1] = c.y + c.cg, rgb[2] = c.y - c.co - c.cg;
}

// Catmull-Rom weights of the four taps around a sample at fraction t past the second.
inline void catmullRom(float t, float* w) {
    const float t2 = t * t, t3 = t2 * t;
    w[0] = -0.5f * t3 + t2 - 0.5f * t;
    w[1] = 1.5f * t3 - 2.5f * t2 + 1.0f;
    w[2] = -1.5f * t3 + 2.0f * t2 + 0.5f * t;
    w[3] = 0.5f * t3 - 0.5f * t2;
}

}  // namespace

std::vector<std::pair<float, float>> parseJitterList(const std::string& text) {
    std::vector<std::pair<float, float>> list;
    std::istringstream in(text);
    std::string entry;
    while (in >> entry) {
        const size_t comma = entry.find(',');
        size_t used1 = 0, used2 = 0;
        float x = 0, y = 0;
        bool ok = comma != std::string::npos;
        try {
            if (ok) {
                x = std::stof(entry.substr(0, comma), &used1);
                y = std::stof(entry.substr(comma + 1), &used2);
            }
        } catch (const std::exception&) {
            ok = false;
        }
        if (!ok || used1 != comma || used2 != entry.size() - comma - 1 || !std::isfinite(x) ||
            !std::isfinite(y) || std::abs(x) > 8 || std::abs(y) > 8)
            throw Error("jitter list: '" + entry + "' is not X,Y (pixels, each within +-8)");
        list.push_back({x, y});
    }
    return list;
}

TaaHq::TaaHq(const TaaHqOptions& o) : options_(o) {
    if (!(o.clipGamma > 0 && o.clipGamma <= 8) || o.maxSamples < 1 || o.maxSamples > 4096 ||
        !(o.clippedSamples >= 0) || !(o.depthTolerance > 0) || !(o.sharpen >= 0 && o.sharpen <= 1))
        throw Error("taa-hq: a parameter is out of range");
}

void TaaHq::apply(int W, int H, const float* colour, const float* motion, const float* depth,
                  const float* previousDepth, float jitterX, float jitterY, float* out) {
    if (W < 1 || H < 1 || !colour || !motion) throw Error("taa-hq needs colour and motion");
    const size_t pixels = size_t(W) * size_t(H);
    const bool fresh = W != width_ || H != height_;
    if (fresh) {
        width_ = W, height_ = H, frame_ = 0;
        linear_.assign(pixels * 3, 0.0f), ycocg_.assign(pixels * 3, 0.0f), pixelMoved_.assign(pixels, 0);
        history_.assign(pixels * 4, 0.0f), nextHistory_.assign(pixels * 4, 0.0f);
        moved_.assign(pixels, 0), nextMoved_.assign(pixels, 0);
    }
    if (!options_.jitterList.empty()) {
        const auto& j = options_.jitterList[size_t(frame_) % options_.jitterList.size()];
        jitterX = j.first, jitterY = j.second;
    }
    ++frame_;
    const bool useDepth = depth && previousDepth;
    const SrgbTables& lut = tables();
    // The current frame in linear light and in YCoCg, and whether each pixel moved.
    parallelFor(0, int64_t(pixels), 1 << 14, [&](int64_t first, int64_t last) {
        for (int64_t i = first * 3; i < last * 3; ++i) linear_[size_t(i)] = lookup(lut.toLinear, colour[i]);
        for (int64_t i = first; i < last; ++i) {
            const Ycocg v = toYcocg(linear_.data() + size_t(i) * 3);
            ycocg_[size_t(i) * 3] = v.y, ycocg_[size_t(i) * 3 + 1] = v.co, ycocg_[size_t(i) * 3 + 2] = v.cg;
            pixelMoved_[size_t(i)] =
                !(std::abs(motion[size_t(i) * 2]) < kStill && std::abs(motion[size_t(i) * 2 + 1]) < kStill);
        }
    });
    // The sample inside pixel p's box is pixel p + shift's: its position from its own centre is -jitter.
    const int shiftX = -int(std::floor(-jitterX + 0.5f)), shiftY = -int(std::floor(-jitterY + 0.5f));
    const float gamma = options_.clipGamma, maxWeight = float(options_.maxSamples);
    const float clippedWeight = options_.clippedSamples, tolerance = options_.depthTolerance;
    const bool catmull = options_.catmullRom, staticLock = options_.staticLock;
    float* const target = options_.sharpen > 0 ? (unsharpened_.resize(pixels * 3), unsharpened_.data()) : out;
    const float* hist = history_.data();
    const uint8_t* moved = moved_.data();
    uint8_t* nextMoved = nextMoved_.data();
    float* next = nextHistory_.data();
    const float* cur = linear_.data();
    const float* yc = ycocg_.data();
    const uint8_t* movedNow = pixelMoved_.data();
    auto clampX = [W](int x) { return std::clamp(x, 0, W - 1); };
    auto clampY = [H](int y) { return std::clamp(y, 0, H - 1); };
    parallelFor(0, H, 4, [&](int64_t firstRow, int64_t lastRow) {
        for (int y = int(firstRow); y < int(lastRow); ++y)
            for (int x = 0; x < W; ++x) {
                const size_t p = size_t(y) * size_t(W) + size_t(x);
                // 1. The current sample and its neighbourhood's statistics (YCoCg).
                const int qx = clampX(x + shiftX), qy = clampY(y + shiftY);
                const float* c = cur + (size_t(qy) * size_t(W) + size_t(qx)) * 3;
                Ycocg sum{0, 0, 0}, sum2{0, 0, 0}, lo{1e9f, 1e9f, 1e9f}, hi{-1e9f, -1e9f, -1e9f};
                for (int dy = -1; dy <= 1; ++dy)
                    for (int dx = -1; dx <= 1; ++dx) {
                        const float* nv =
                            yc + (size_t(clampY(qy + dy)) * size_t(W) + size_t(clampX(qx + dx))) * 3;
                        const Ycocg n{nv[0], nv[1], nv[2]};
                        sum.y += n.y, sum.co += n.co, sum.cg += n.cg;
                        sum2.y += n.y * n.y, sum2.co += n.co * n.co, sum2.cg += n.cg * n.cg;
                        lo = {std::min(lo.y, n.y), std::min(lo.co, n.co), std::min(lo.cg, n.cg)};
                        hi = {std::max(hi.y, n.y), std::max(hi.co, n.co), std::max(hi.cg, n.cg)};
                    }
                // 2. Where the pixel was: the motion of the nearest surface around it.
                int mx = x, my = y;
                if (depth) {
                    float nearest = depth[p];
                    for (int dy = -1; dy <= 1; ++dy)
                        for (int dx = -1; dx <= 1; ++dx) {
                            const int sx = clampX(x + dx), sy = clampY(y + dy);
                            const float d = depth[size_t(sy) * size_t(W) + size_t(sx)];
                            if (d < nearest) nearest = d, mx = sx, my = sy;
                        }
                }
                const size_t mp = size_t(my) * size_t(W) + size_t(mx);
                uint8_t anyMoved = 0;  // something moved in the 3x3
                for (int dy = -1; dy <= 1; ++dy) {
                    const uint8_t* row = movedNow + size_t(clampY(y + dy)) * size_t(W);
                    anyMoved = uint8_t(anyMoved | row[clampX(x - 1)] | row[x] | row[clampX(x + 1)]);
                }
                const bool stillNow = !anyMoved;
                nextMoved[p] = !stillNow;
                const float hx = float(x) + 0.5f - motion[mp * 2], hy = float(y) + 0.5f - motion[mp * 2 + 1];
                float weight = 0;
                float h[3] = {c[0], c[1], c[2]};
                if (!fresh && hx >= 0 && hy >= 0 && hx <= float(W) && hy <= float(H)) {
                    const int nx = clampX(int(hx)), ny = clampY(int(hy));
                    const size_t np = size_t(ny) * size_t(W) + size_t(nx);
                    weight = hist[np * 4 + 3];
                    // 3. Disocclusion: the surfaces the previous frame saw around that place are all
                    // nearer, or all farther, than every surface around the pixel now (by more than the
                    // tolerance). Ranges of 3x3 depths on both sides: the frames' own jitters move edges
                    // by a pixel or two, and a surface thinner than a pixel (a strand, a gap between
                    // slats) is in some frames' samples and not in others'.
                    if (useDepth) {
                        float curLo = depth[p], curHi = depth[p], prevLo = 1e30f, prevHi = -1e30f;
                        for (int dy = -1; dy <= 1; ++dy)
                            for (int dx = -1; dx <= 1; ++dx) {
                                const float dc =
                                    depth[size_t(clampY(y + dy)) * size_t(W) + size_t(clampX(x + dx))];
                                const float dp = previousDepth[size_t(clampY(ny + dy)) * size_t(W) +
                                                               size_t(clampX(nx + dx))];
                                curLo = std::min(curLo, dc), curHi = std::max(curHi, dc);
                                prevLo = std::min(prevLo, dp), prevHi = std::max(prevHi, dp);
                            }
                        if (prevHi < curLo * (1 - tolerance) || prevLo > curHi * (1 + tolerance)) weight = 0;
                    }
                    if (weight > 0) {
                        // 2. Catmull-Rom over 4x4 texels, deringed to the 2x2 bilinear footprint.
                        const float u = hx - 0.5f, v = hy - 0.5f;
                        const int ix = int(std::floor(u)), iy = int(std::floor(v));
                        const float fx = u - float(ix), fy = v - float(iy);
                        if (fx == 0 && fy == 0) {  // on a texel (a still view): the filter reads just it
                            const float* t = hist + (size_t(clampY(iy)) * size_t(W) + size_t(clampX(ix))) * 4;
                            h[0] = t[0], h[1] = t[1], h[2] = t[2];
                        } else {
                            float wx[4], wy[4];
                            catmullRom(fx, wx), catmullRom(fy, wy);
                            if (!catmull) {  // bilinear, for comparison
                                wx[0] = wx[3] = wy[0] = wy[3] = 0;
                                wx[1] = 1 - fx, wx[2] = fx;
                                wy[1] = 1 - fy, wy[2] = fy;
                            }
                            float acc[3] = {0, 0, 0}, fmin[3] = {1e9f, 1e9f, 1e9f},
                                  fmax[3] = {-1e9f, -1e9f, -1e9f};
                            for (int j = 0; j < 4; ++j) {
                                const size_t row = size_t(clampY(iy - 1 + j)) * size_t(W);
                                for (int i = 0; i < 4; ++i) {
                                    const float* t = hist + (row + size_t(clampX(ix - 1 + i))) * 4;
                                    const float w = wx[i] * wy[j];
                                    for (int k = 0; k < 3; ++k) acc[k] += w * t[k];
                                    if ((i == 1 || i == 2) && (j == 1 || j == 2))
                                        for (int k = 0; k < 3; ++k)
                                            fmin[k] = std::min(fmin[k], t[k]),
                                            fmax[k] = std::max(fmax[k], t[k]);
                                }
                            }
                            for (int k = 0; k < 3; ++k) h[k] = std::clamp(acc[k], fmin[k], fmax[k]);
                        }
                        // 4. Variance clipping toward the centre of mean +- gamma sigma within min/max; not
                        // where the view is still (the static lock: nothing moved in the 3x3 now, nor where
                        // the history comes from), whose history is the mean of samples the current 3x3
                        // may not show (a sliver between two sample rows).
                        const bool still = staticLock && stillNow && !moved[np];
                        if (!still) {
                            const float inv = 1.0f / 9.0f;
                            const Ycocg mean{sum.y * inv, sum.co * inv, sum.cg * inv};
                            const Ycocg sigma{std::sqrt(std::max(0.0f, sum2.y * inv - mean.y * mean.y)),
                                              std::sqrt(std::max(0.0f, sum2.co * inv - mean.co * mean.co)),
                                              std::sqrt(std::max(0.0f, sum2.cg * inv - mean.cg * mean.cg))};
                            const Ycocg boxLo{std::max(lo.y, mean.y - gamma * sigma.y),
                                              std::max(lo.co, mean.co - gamma * sigma.co),
                                              std::max(lo.cg, mean.cg - gamma * sigma.cg)};
                            const Ycocg boxHi{std::min(hi.y, mean.y + gamma * sigma.y),
                                              std::min(hi.co, mean.co + gamma * sigma.co),
                                              std::min(hi.cg, mean.cg + gamma * sigma.cg)};
                            // (the current sample is always inside: it is the one thing known to be right)
                            const Ycocg cc = toYcocg(c);
                            const Ycocg lo2{std::min(boxLo.y, cc.y), std::min(boxLo.co, cc.co),
                                            std::min(boxLo.cg, cc.cg)};
                            const Ycocg hi2{std::max(boxHi.y, cc.y), std::max(boxHi.co, cc.co),
                                            std::max(boxHi.cg, cc.cg)};
                            const Ycocg centre{0.5f * (lo2.y + hi2.y), 0.5f * (lo2.co + hi2.co),
                                               0.5f * (lo2.cg + hi2.cg)};
                            const float eps = 1e-6f;
                            const Ycocg extent{0.5f * (hi2.y - lo2.y) + eps, 0.5f * (hi2.co - lo2.co) + eps,
                                               0.5f * (hi2.cg - lo2.cg) + eps};
                            const Ycocg hc = toYcocg(h);
                            const Ycocg off{hc.y - centre.y, hc.co - centre.co, hc.cg - centre.cg};
                            const float a =
                                std::max({std::abs(off.y) / extent.y, std::abs(off.co) / extent.co,
                                          std::abs(off.cg) / extent.cg});
                            if (a > 1.0f) {
                                const Ycocg clipped{centre.y + off.y / a, centre.co + off.co / a,
                                                    centre.cg + off.cg / a};
                                toRgb(clipped, h);
                                weight = std::min(weight, clippedWeight);
                            }
                        }
                    }
                }
                // 5. One more sample, the history moved toward it by 1 / weight.
                weight = std::min(weight + 1.0f, maxWeight);
                const float share = 1.0f / weight;
                float* n = next + p * 4;
                for (int k = 0; k < 3; ++k) n[k] = h[k] + share * (c[k] - h[k]);
                n[3] = weight;
                // 6. The output in sRGB.
                for (int k = 0; k < 3; ++k) target[p * 3 + size_t(k)] = lookup(lut.toSrgb, n[k]);
            }
    });
    std::swap(history_, nextHistory_);
    std::swap(moved_, nextMoved_);
    if (options_.sharpen <= 0) return;
    // The output-only sharpen: the cross's Laplacian, limited to the cross's range.
    const float s = options_.sharpen;
    parallelFor(0, H, 8, [&](int64_t firstRow, int64_t lastRow) {
        for (int y = int(firstRow); y < int(lastRow); ++y)
            for (int x = 0; x < W; ++x) {
                const size_t p = size_t(y) * size_t(W) + size_t(x);
                const float* c = target + p * 3;
                const float* nb[4] = {target + (size_t(clampY(y - 1)) * size_t(W) + size_t(x)) * 3,
                                      target + (size_t(clampY(y + 1)) * size_t(W) + size_t(x)) * 3,
                                      target + (size_t(y) * size_t(W) + size_t(clampX(x - 1))) * 3,
                                      target + (size_t(y) * size_t(W) + size_t(clampX(x + 1))) * 3};
                for (int k = 0; k < 3; ++k) {
                    float lo = c[k], hi = c[k], around = 0;
                    for (const float* q : nb)
                        lo = std::min(lo, q[k]), hi = std::max(hi, q[k]), around += q[k];
                    out[p * 3 + size_t(k)] = std::clamp(c[k] + s * (c[k] - 0.25f * around), lo, hi);
                }
            }
    });
}

namespace {

class TaaHqFilter final : public Filter {
  public:
    explicit TaaHqFilter(const TaaHqOptions& options) : Filter("taa-hq"), taa_(options) {}
    BufferSet needs() const override { return unsigned(Buffer::Motion); }
    BufferSet uses() const override {
        return Buffer::Motion | Buffer::Depth | Buffer::PreviousDepth | Buffer::Jitter;
    }
    bool temporal() const override { return true; }
    void reset() override { taa_.reset(); }

  private:
    void process(const Frame& frame, float* out) override {
        const float* depth = frame.depth && frame.previousDepth ? frame.depth : nullptr;
        const float* previous = depth ? frame.previousDepth : nullptr;
        const float jx = frame.hasJitter ? frame.jitter[0] : 0.0f,
                    jy = frame.hasJitter ? frame.jitter[1] : 0.0f;
        // R G B alone; the other channels pass through.
        taa_.apply(frame.width, frame.height, rgb_.rgb(frame), frame.motion, depth, previous, jx, jy,
                   rgb_.result(frame, out));
        rgb_.finish(frame, out);
    }
    TaaHq taa_;
    RgbScratch rgb_;
};

}  // namespace

MethodSpec taaHqMethod() {
    const TaaHqOptions d;
    MethodSpec spec;
    spec.name = "taa-hq";
    spec.summary =
        "a converging TAA (docs/taa-hq.md): the in-pixel sample at its jittered position accumulated per "
        "pixel, Catmull-Rom history, YCoCg variance clipping, depth disocclusion, sharpen on the output only";
    spec.parameters = {
        {"clip-gamma", "1.25", "variance clipping: mean +- gamma sigma of the 3x3 neighbourhood, (0, 8]"},
        {"max-samples", "32",
         "the accumulated weight's cap (the current frame's share is at least its inverse)"},
        {"clipped-samples", "4", "the weight a history that was clipped keeps at most"},
        {"depth-tolerance", "0.05", "relative depth change that rejects the history (a disocclusion)"},
        {"sharpen", "0", "sharpen of the output only, 0 (off) to 1; the history stays unsharpened"},
        {"history-filter", "catmull-rom", "history resampling: catmull-rom (deringed) or bilinear"},
        {"static-lock", "true",
         "no clipping where nothing moved in the 3x3, now or where the history comes from (a still view "
         "converges to its mean)"},
        {"jitter", "frames",
         "each frame's jitter: 'frames' (render.json's, zero without one) or a cycled list 'X,Y X,Y ...' "
         "(image shift in pixels, +y down)"},
    };
    spec.needs = unsigned(Buffer::Motion);
    spec.optional = Buffer::Depth | Buffer::PreviousDepth | Buffer::Jitter;
    spec.temporal = true;
    spec.make = [](MethodParameters& p) -> std::unique_ptr<Filter> {
        TaaHqOptions o;
        o.clipGamma = float(p.number("clip-gamma", 1e-3, 8));
        o.maxSamples = p.integer("max-samples", 1, 4096);
        o.clippedSamples = float(p.number("clipped-samples", 0, 4096));
        o.depthTolerance = float(p.number("depth-tolerance", 1e-4, 10));
        o.sharpen = float(p.number("sharpen", 0, 1));
        o.staticLock = p.flag("static-lock");
        const std::string filter = p.text("history-filter");
        if (filter != "catmull-rom" && filter != "bilinear")
            throw Error("taa-hq: history-filter is catmull-rom or bilinear, not '" + filter + "'");
        o.catmullRom = filter == "catmull-rom";
        if (const std::string j = p.text("jitter"); j != "frames") {
            o.jitterList = parseJitterList(j);
            if (o.jitterList.empty())
                throw Error("taa-hq: the jitter list is empty (use 'frames' or X,Y pairs)");
        }
        return std::make_unique<TaaHqFilter>(o);
    };
    return spec;
}

}  // namespace dejag::infer

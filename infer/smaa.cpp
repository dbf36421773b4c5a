#include "infer/smaa.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "base/error.h"
#include "base/thread_pool.h"
#include "infer/smaa_area.h"
#include "infer/smaa_kernels.h"

namespace dejag::infer {

SmaaOptions smaaPreset(const std::string& name) {
    SmaaOptions o;
    if (name == "low") {
        o.threshold = 0.15f, o.searchSteps = 4, o.diagonalSteps = 0, o.cornerRounding = 100;
    } else if (name == "medium") {
        o.threshold = 0.1f, o.searchSteps = 8, o.diagonalSteps = 0, o.cornerRounding = 100;
    } else if (name == "high") {
        o.threshold = 0.1f, o.searchSteps = 16, o.diagonalSteps = 8, o.cornerRounding = 25;
    } else if (name == "ultra") {
        o.threshold = 0.05f, o.searchSteps = 32, o.diagonalSteps = 16, o.cornerRounding = 25;
    } else {
        throw Error("SMAA preset '" + name + "' is not one of low, medium, high, ultra");
    }
    return o;
}

Smaa::Smaa(const SmaaOptions& o) : options_(o) {
    if (!(o.threshold > 0.0f && o.threshold <= 0.5f)) throw Error("SMAA: the threshold must be in (0, 0.5]");
    if (o.searchSteps < 1 || o.searchSteps > 112) throw Error("SMAA: search steps must be in [1, 112]");
    if (o.diagonalSteps < 0 || o.diagonalSteps > 20) throw Error("SMAA: diagonal steps must be in [0, 20]");
    if (o.cornerRounding < 0 || o.cornerRounding > 100)
        throw Error("SMAA: corner rounding must be in [0, 100]");
    // The searches read up to 2 x steps + 1 pixels away, the corner tests 2 rows beyond; the blending
    // reads 8 bytes past a row's end.
    pad_ = std::max({2 * o.searchSteps + 4, o.diagonalSteps + 4, 16});
    if (o.diagonalSteps > 0) smaaDiagonalAreaTable();  // computed once per process, before the first frame
}

const float* Smaa::weightsAt(int x, int y) const {
    static const float kZero[4] = {0, 0, 0, 0};
    return edgeAt(x, y) ? weights_.data() + 4 * (size_t(y) * size_t(width_) + size_t(x)) : kZero;
}

void smaaHorizontalRun(const uint8_t* edges, size_t stride, int pad, int x, int y, int steps, int& first,
                       int& last) {
    auto at = [&](int xx, int yy) { return edges[size_t(yy + pad) * stride + size_t(xx + pad)]; };
    auto crossing = [&](int xx) { return (at(xx, y) | at(xx, y - 1)) & 1; };
    const int reach = 2 * steps;
    int l = x, r = x;
    while (x - l < reach - 1 && (at(l - 1, y) & 2) && !crossing(l)) --l;
    while (r - x < reach && (at(r + 1, y) & 2) && !crossing(r + 1)) ++r;
    first = l, last = r;
}

void smaaVerticalRun(const uint8_t* edges, size_t stride, int pad, int x, int y, int steps, int& first,
                     int& last) {
    auto at = [&](int xx, int yy) { return edges[size_t(yy + pad) * stride + size_t(xx + pad)]; };
    auto crossing = [&](int yy) { return ((at(x, yy) | at(x - 1, yy)) >> 1) & 1; };
    const int reach = 2 * steps;
    int t = y, b = y;
    while (y - t < reach - 1 && (at(x, t - 1) & 1) && !crossing(t)) --t;
    while (b - y < reach && (at(x, b + 1) & 1) && !crossing(b + 1)) ++b;
    first = t, last = b;
}

int Smaa::runLength(int x, int y) const {
    const int e = edgeAt(x, y);
    int longest = 0, first, last;
    if (e & 2) {
        smaaHorizontalRun(edges_.data(), edgeStride_, pad_, x, y, options_.searchSteps, first, last);
        longest = last - first + 1;
    }
    if (e & 1) {
        smaaVerticalRun(edges_.data(), edgeStride_, pad_, x, y, options_.searchSteps, first, last);
        longest = std::max(longest, last - first + 1);
    }
    return longest;
}

namespace {

// Pass 2 for one pixel with an edge: its four weights (SMAA's blending weight pass, docs/smaa.md).
class WeightSearch {
  public:
    WeightSearch(const SmaaOptions& o, const uint8_t* edges, size_t stride, int pad)
        : o_(o), edges_(edges), stride_(stride), pad_(pad), diagonal_(smaaDiagonalAreaTable_(o)) {}

    void weights(int x, int y, uint8_t e, float* w) const {
        w[0] = w[1] = w[2] = w[3] = 0.0f;
        bool vertical = e & 1;
        if (e & 2) {
            if (o_.diagonalSteps > 0) diagonalWeights(x, y, e, w);
            if (w[0] + w[1] == 0.0f) {
                horizontalWeights(x, y, w);
            } else {
                vertical = false;  // a diagonal takes both edges of the pixel
            }
        }
        if (vertical) verticalWeights(x, y, w + 2);
    }

  private:
    static const float* smaaDiagonalAreaTable_(const SmaaOptions& o) {
        return o.diagonalSteps > 0 ? smaaDiagonalAreaTable() : nullptr;
    }
    int at(int x, int y) const { return edges_[size_t(y + pad_) * stride_ + size_t(x + pad_)]; }
    int left(int x, int y) const { return at(x, y) & 1; }
    int top(int x, int y) const { return at(x, y) >> 1; }

    // Corner rounding: at an end nearer than the other (both when equal) where the crossing edge goes on
    // for another pixel, the blending toward that side keeps only (rounding) of its weight.
    void corners(int d1, int d2, int beyondNear1, int beyondNear2, int beyondFar1, int beyondFar2,
                 float* w) const {
        if (o_.cornerRounding >= 100) return;
        const float n1 = d1 <= d2 ? 1.0f : 0.0f, n2 = d2 <= d1 ? 1.0f : 0.0f;
        const float k = (1.0f - float(o_.cornerRounding) / 100.0f) / (n1 + n2);
        const float nearFactor = 1.0f - k * n1 * float(beyondNear1) - k * n2 * float(beyondNear2);
        const float farFactor = 1.0f - k * n1 * float(beyondFar1) - k * n2 * float(beyondFar2);
        w[0] *= std::clamp(nearFactor, 0.0f, 1.0f);
        w[1] *= std::clamp(farFactor, 0.0f, 1.0f);
    }

    // The run of top edges through (x, y): leftwards while the next pixel has a top edge and no crossing
    // (left) edge in the two rows stops the run between them, up to 2 steps - 1 pixels; rightwards up to
    // 2 steps (SMAA's bilinear search covers two pixels a fetch and reads these exact ends).
    void horizontalWeights(int x, int y, float* w) const {
        int l, r;
        smaaHorizontalRun(edges_, stride_, pad_, x, y, o_.searchSteps, l, r);
        const int pattern =
            smaaOrthogonalPattern(left(l, y), left(r + 1, y), left(l, y - 1), left(r + 1, y - 1));
        const auto a = smaaOrthogonalArea(pattern, x - l, r - x);
        w[0] = a[0], w[1] = a[1];
        corners(x - l, r - x, left(l, y + 1), left(r + 1, y + 1), left(l, y - 2), left(r + 1, y - 2), w);
    }

    // The same along a column of left edges (the transposed search): w = {toward left, left neighbour's}.
    void verticalWeights(int x, int y, float* w) const {
        int t, b;
        smaaVerticalRun(edges_, stride_, pad_, x, y, o_.searchSteps, t, b);
        const int pattern = smaaOrthogonalPattern(top(x, t), top(x, b + 1), top(x - 1, t), top(x - 1, b + 1));
        const auto a = smaaOrthogonalArea(pattern, y - t, b - y);
        w[0] = a[0], w[1] = a[1];
        corners(y - t, b - y, top(x + 1, t), top(x + 1, b + 1), top(x - 2, t), top(x - 2, b + 1), w);
    }

    struct DiagonalEnd {
        int steps;   // pixels of the diagonal found beyond the start
        bool ended;  // the search found where it ends (else it stopped at the step limit)
    };
    // Steps along (dx, dy) while the pixel has both boundaries of the diagonal; `second`: the "\"
    // diagonal, whose pixels have a top edge and a right one (the next pixel's left edge).
    DiagonalEnd searchDiagonal(int x, int y, int dx, int dy, bool second, bool countTopEnd) const {
        int steps = -1, both = 1, lastTop = 0;
        while (steps < o_.diagonalSteps - 1 && both) {
            x += dx, y += dy, ++steps;
            const int t = top(x, y), l = second ? left(x + 1, y) : left(x, y);
            both = t & l;
            lastTop = t;
        }
        if (countTopEnd && lastTop) ++steps;  // a final pixel with its top edge only still belongs
        return {steps, !both};
    }

    const float* areas(int c1, int c2, int d1, int d2) const {
        return smaaDiagonalAreas(diagonal_, smaaDiagonalPattern(c1, c2), std::min(d1, kSmaaDiagonalMax - 1),
                                 std::min(d2, kSmaaDiagonalMax - 1));
    }

    void diagonalWeights(int x, int y, uint8_t e, float* w) const {
        // "/": pixels with left and top edges, down-left (only if this pixel has its left edge) and up-right.
        DiagonalEnd a{0, true};
        if (e & 1) a = searchDiagonal(x, y, -1, 1, false, true);
        DiagonalEnd b = searchDiagonal(x, y, 1, -1, false, false);
        if (a.steps + b.steps > 2) {
            int c1 = 2 * top(x - a.steps - 1, y + a.steps) + left(x - a.steps, y + a.steps);
            int c2 = 2 * top(x + b.steps + 1, y - b.steps) + left(x + b.steps + 1, y - b.steps - 1);
            if (!a.ended) c1 = 0;  // the end is unknown: no crossing edge
            if (!b.ended) c2 = 0;
            const float* area = areas(c1, c2, a.steps, b.steps);
            w[0] += area[0], w[1] += area[1];
        }
        // "\": pixels with top and right edges, up-left and down-right (only with this pixel's right edge).
        a = searchDiagonal(x, y, -1, -1, true, false);
        b = {0, true};
        if (left(x + 1, y)) b = searchDiagonal(x, y, 1, 1, true, true);
        if (a.steps + b.steps > 2) {
            int c1 = 2 * top(x - a.steps - 1, y - a.steps) + left(x - a.steps, y - a.steps - 1);
            int c2 = 2 * top(x + b.steps + 1, y + b.steps) + left(x + b.steps + 1, y + b.steps);
            if (!a.ended) c1 = 0;
            if (!b.ended) c2 = 0;
            const float* area = areas(c1, c2, a.steps, b.steps);
            w[0] += area[1], w[1] += area[0];
        }
    }

    const SmaaOptions& o_;
    const uint8_t* edges_;
    size_t stride_;
    int pad_;
    const float* diagonal_;
};

}  // namespace

void Smaa::apply(const float* in, float* out, int width, int height, int channels, const float* depth) {
    if (width < 1 || height < 1 || channels < 3) throw Error("SMAA needs an image with R, G, B channels");
    if (options_.predication && !depth) throw Error("SMAA with predication needs the frame's depth");
    const size_t pixels = size_t(width) * size_t(height);
    if (pixels * size_t(channels) > size_t(INT32_MAX))
        throw Error("SMAA: image too large (" + std::to_string(width) + "x" + std::to_string(height) + ")");
    if (in == out) {  // every pass reads the original frame
        if (copy_.size() < pixels * size_t(channels)) copy_.resize(pixels * size_t(channels));
        parallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
            const size_t row = size_t(width) * size_t(channels);
            std::memcpy(copy_.data() + size_t(y0) * row, in + size_t(y0) * row,
                        size_t(y1 - y0) * row * sizeof(float));
        });
        in = copy_.data();
    }
    if (width != width_ || height != height_) {  // new planes; the edges' pads stay zero from here on
        width_ = width, height_ = height;
        edgeStride_ = size_t(width) + 2 * size_t(pad_);
        edges_.assign(edgeStride_ * (size_t(height) + 2 * size_t(pad_)), 0);
        lumaStride_ = size_t(width) + 2 * kSmaaLumaPad;
        luma_.assign(lumaStride_ * size_t(height), 0.0f);
        weights_.assign(4 * pixels, 0.0f);
        edgeCounts_.assign(size_t(height), 0);
    }
    SmaaKernelArgs args;
    args.frame = in, args.out = out, args.width = width, args.height = height, args.channels = channels;
    args.depth = options_.predication ? depth : nullptr;
    args.threshold = options_.threshold;
    args.predicationThreshold = options_.predicationThreshold;
    args.predicationScale = options_.predicationScale;
    args.predicationStrength = options_.predicationStrength;
    args.colourEdges = options_.edges == SmaaEdges::Colour;
    args.luma = luma_.data(), args.lumaStride = lumaStride_;
    args.edges = edges_.data(), args.edgeStride = edgeStride_, args.edgePad = pad_;
    args.weights = weights_.data();
    args.linear = options_.linearBlending;

    // 1. Edges (luma first: a row's edges read the luma two rows up and one down).
    if (!args.colourEdges)
        parallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
            for (int64_t y = y0; y < y1; ++y) DEJAG_SIMD_CALL(smaaLumaRow, args, int(y));
        });
    parallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
        for (int64_t y = y0; y < y1; ++y) edgeCounts_[size_t(y)] = DEJAG_SIMD_CALL(smaaEdgeRow, args, int(y));
    });
    int64_t edgePixels = 0;
    for (int64_t n : edgeCounts_) edgePixels += n;
    edgeFraction_ = double(edgePixels) / double(pixels);

    // 2. Blending weights of the pixels with an edge (the searches read edges anywhere: after pass 1).
    const WeightSearch search(options_, edges_.data(), edgeStride_, pad_);
    parallelFor(0, height, 8, [&](int64_t y0, int64_t y1) {
        for (int64_t y = y0; y < y1; ++y) {
            if (edgeCounts_[size_t(y)] == 0) continue;
            const uint8_t* e = edges_.data() + size_t(y + pad_) * edgeStride_ + size_t(pad_);
            float* w = weights_.data() + 4 * size_t(y) * size_t(width);
            for (int x = 0; x < width;
                 x += 8) {  // eight at a time past pixels without edges (the pad is zero)
                uint64_t any;
                std::memcpy(&any, e + x, 8);
                if (any == 0) continue;
                for (int k = x; k < std::min(x + 8, width); ++k)
                    if (e[k]) search.weights(k, int(y), e[k], w + 4 * k);
            }
        }
    });

    // 3. Blending (reads the weights of the row below: after pass 2).
    parallelFor(0, height, 16, [&](int64_t y0, int64_t y1) {
        for (int64_t y = y0; y < y1; ++y) DEJAG_SIMD_CALL(smaaBlendRow, args, int(y));
    });
}

namespace {

class SmaaFilter final : public Filter {
  public:
    SmaaFilter(const SmaaOptions& options, const std::string& preset) : Filter("smaa"), smaa_(options) {
        figures_.settings = {{"preset", preset}};
    }
    BufferSet needs() const override { return smaa_.options().predication ? unsigned(Buffer::Depth) : 0u; }

  private:
    void process(const Frame& frame, float* out) override {
        smaa_.apply(frame.colour, out, frame.width, frame.height, frame.channels, frame.depth);
        figures_.processedFraction = smaa_.edgeFraction();
    }
    Smaa smaa_;
};

}  // namespace

SmaaOptions smaaOptions(const MethodParameters& p) {
    const std::string preset = p.text("preset");
    SmaaOptions o;
    try {
        o = smaaPreset(preset);
    } catch (const Error& e) {
        throw Error(p.origin("preset") + ": " + e.what());
    }
    if (p.text("threshold") != "preset") o.threshold = float(p.number("threshold", 1e-6, 0.5));
    if (p.text("search-steps") != "preset") o.searchSteps = p.integer("search-steps", 1, 112);
    if (p.text("diagonal-steps") != "preset") o.diagonalSteps = p.integer("diagonal-steps", 0, 20);
    if (p.text("corner-rounding") != "preset") o.cornerRounding = p.integer("corner-rounding", 0, 100);
    const std::string edges = p.text("edges");
    if (edges == "colour" || edges == "color") {
        o.edges = SmaaEdges::Colour;
    } else if (edges != "luma") {
        throw Error(p.origin("edges") + ": SMAA edges '" + edges + "' is not luma or colour");
    }
    o.predication = p.flag("predication");
    o.linearBlending = p.flag("linear");
    return o;
}

MethodSpec smaaMethod() {
    MethodSpec spec;
    spec.name = "smaa";
    spec.summary = "SMAA 1x (Jimenez et al. 2012): edge patterns searched and revectorised, one frame";
    spec.parameters = {
        {"preset", "ultra", "low, medium, high or ultra: the published settings below"},
        {"threshold", "preset",
         "edge detection threshold, (0, 0.5] (ultra 0.05, high and medium 0.1, low 0.15)"},
        {"search-steps", "preset", "orthogonal search steps, [1, 112] (ultra 32, high 16, medium 8, low 4)"},
        {"diagonal-steps", "preset", "diagonal search steps, [0, 20], 0 off (ultra 16, high 8, else 0)"},
        {"corner-rounding", "preset", "percent of sharp corners rounded, [0, 100], 100 off (ultra, high 25)"},
        {"edges", "luma", "edge detection on luma or colour (the largest channel step)"},
        {"predication", "off", "lower the threshold where the depth steps too (needs depth)"},
        {"linear", "on", "blend in linear light, as an sRGB texture read does; off: on encoded values"},
    };
    // (No buffers by default; with predication on, the filter made needs depth.)
    spec.make = [](MethodParameters& p) -> std::unique_ptr<Filter> {
        const SmaaOptions o = smaaOptions(p);
        return std::make_unique<SmaaFilter>(o, p.text("preset"));
    };
    return spec;
}

}  // namespace dejag::infer
